/* SPDX-License-Identifier: MIT */
/*
 * mcf_graph.c - the uniform graph Laplacian of a mesh: the vertex
 * adjacency (weight 1 per edge, however many faces share it), umbrella
 * averages and Taubin's lambda|mu passes on it.
 *
 * The fairing filter (mcf_fairing.c) and the noise estimate (mcf_auto.c)
 * work on this graph rather than on cotan weights: the cotan weights of a
 * noisy scan are themselves noisy, the graph's are not. L = D - A with A
 * the adjacency and D the degrees; D^-1 L has its spectrum in [0, 2].
 */
#include <stdlib.h>
#include <string.h>

#include "mcf_internal.h"

mcf_status mcf__graph_build(const int32_t *F, int nf, int nv, mcf__graph *g, mcf_error *err)
{
    mcf__pattern p;
    mcf_status rc;
    memset(g, 0, sizeof *g);
    if ((rc = mcf__pattern_build(F, nf, nv, 0, &p, err)) != MCF_OK)
        return rc;
    size_t nadj = 2 * ((size_t)p.nnz - (size_t)nv);
    g->n = nv;
    g->ptr = mcf__calloc((size_t)nv + 1, sizeof *g->ptr);
    g->adj = mcf__malloc(nadj ? nadj : 1, sizeof *g->adj);
    if (!g->ptr || !g->adj) {
        mcf__pattern_free(&p);
        mcf__graph_free(g);
        return mcf__fail(err, MCF_ENOMEM, "graph: out of memory (%d vertices)", nv);
    }
    /* the pattern's upper triangle, both directions; columns in order
     * keep every row sorted */
    for (int j = 0; j < nv; j++)
        for (int t = p.colptr[j]; t < p.colptr[j + 1]; t++)
            if (p.rowind[t] != j) {
                g->ptr[p.rowind[t] + 1]++;
                g->ptr[j + 1]++;
            }
    for (int i = 0; i < nv; i++)
        g->ptr[i + 1] += g->ptr[i];
    int *fill = mcf__malloc((size_t)nv, sizeof *fill);
    if (!fill) {
        mcf__pattern_free(&p);
        mcf__graph_free(g);
        return mcf__fail(err, MCF_ENOMEM, "graph: out of memory (%d vertices)", nv);
    }
    memcpy(fill, g->ptr, sizeof(int) * (size_t)nv);
    for (int j = 0; j < nv; j++)
        for (int t = p.colptr[j]; t < p.colptr[j + 1]; t++) {
            int i = p.rowind[t];
            if (i != j) {
                g->adj[fill[i]++] = j;
                g->adj[fill[j]++] = i;
            }
        }
    free(fill);
    mcf__pattern_free(&p);
    return MCF_OK;
}

void mcf__graph_free(mcf__graph *g)
{
    if (!g)
        return;
    free(g->ptr);
    free(g->adj);
    memset(g, 0, sizeof *g);
}

void mcf__graph_average(const mcf__graph *g, const double *v, int ncol, double *out)
{
    for (int i = 0; i < g->n; i++) {
        int d = g->ptr[i + 1] - g->ptr[i];
        for (int c = 0; c < ncol; c++) {
            double s = 0.0;
            for (int t = g->ptr[i]; t < g->ptr[i + 1]; t++)
                s += v[(size_t)ncol * g->adj[t] + c];
            out[(size_t)ncol * i + c] = d > 0 ? s / d : v[(size_t)ncol * i + c];
        }
    }
}

void mcf__graph_taubin(const mcf__graph *g, const unsigned char *fixed, double *X, int ncol,
                       int passes, double *tmp)
{
    static const double coef[2] = {MCF_TAUBIN_LAMBDA, MCF_TAUBIN_MU};
    for (int k = 0; k < passes; k++)
        for (int h = 0; h < 2; h++) {
            mcf__graph_average(g, X, ncol, tmp);
            for (int i = 0; i < g->n; i++)
                if (!fixed || !fixed[i])
                    for (size_t q = (size_t)ncol * i; q < (size_t)ncol * (i + 1); q++)
                        X[q] += coef[h] * (tmp[q] - X[q]);
        }
}
