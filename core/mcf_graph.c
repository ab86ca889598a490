/* SPDX-License-Identifier: MIT */
/*
 * mcf_graph.c - the uniform graph Laplacian of a mesh: the vertex
 * adjacency (weight 1 per edge, however many faces share it), umbrella
 * averages and Taubin's lambda|mu passes on it; and the faces at each
 * vertex (mcf__vertex_faces).
 *
 * The fairing filter (mcf_fairing.c) and the noise estimate (mcf_auto.c)
 * work on this graph rather than on cotan weights: the cotan weights of a
 * noisy scan are themselves noisy, the graph's are not. L = D - A with A
 * the adjacency and D the degrees; D^-1 L has its spectrum in [0, 2].
 */
#include <stdlib.h>
#include <string.h>

#include "mcf_internal.h"

void mcf__vertex_faces(const int32_t *F, int nf, int nv, int *vp, int *vf)
{
    /* counts at i + 2, their prefix sums at i + 2, then each face placed
     * by the cursor at i + 1, which ends as the start of i + 1 */
    for (size_t q = 0; q < 3 * (size_t)nf; q++)
        vp[F[q] + 2]++;
    for (int i = 0; i < nv; i++)
        vp[i + 2] += vp[i + 1];
    for (int f = 0; f < nf; f++)
        for (int k = 0; k < 3; k++)
            vf[vp[F[3 * (size_t)f + k] + 1]++] = f;
}

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

/* The 3 columns' sums in registers over one walk of the adjacency (the
 * loop below walks it once per column, its sum in memory): each column's
 * neighbours added in the same order, the same numbers bit for bit. */
static void average_3(const mcf__graph *g, const double *v, double *out)
{
    for (size_t i = 0; i < (size_t)g->n; i++) {
        int d = g->ptr[i + 1] - g->ptr[i];
        double s0 = 0.0, s1 = 0.0, s2 = 0.0;
        for (int t = g->ptr[i]; t < g->ptr[i + 1]; t++) {
            const double *vj = v + 3 * (size_t)g->adj[t];
            s0 += vj[0];
            s1 += vj[1];
            s2 += vj[2];
        }
        double *o = out + 3 * i;
        if (d > 0) {
            o[0] = s0 / d;
            o[1] = s1 / d;
            o[2] = s2 / d;
        } else {
            memcpy(o, v + 3 * i, 3 * sizeof(double));
        }
    }
}

void mcf__graph_average(const mcf__graph *g, const double *v, int ncol, double *out)
{
    if (ncol == 3) {
        average_3(g, v, out);
        return;
    }
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

/* One half of a Taubin pass from v into out: out_i = v_i + coef (avg_i -
 * v_i) on the free vertices (avg: mcf__graph_average's, v_i where vertex
 * i has no neighbour), v_i on the fixed. The same arithmetic as the
 * average into a scratch array and the update after it, in one sweep
 * over the vertices: half the memory traffic. */
typedef struct {
    const mcf__graph *g;
    const unsigned char *fixed;
    const double *v;
    double *out;
    double coef;
    int ncol;
} half_pass;

/* One vertex's update (above) for NCOL a constant of the compiler (3:
 * positions; 6, 9: with the fairing's three or six probes): the sums in
 * registers, two columns to a vector (GCC's vector extension; SSE2 on
 * x86-64), each lane the scalar code's operations in its order -- the
 * neighbours added in the adjacency's order, then / d, - v_i, * coef,
 * + v_i, no fused multiply-add -- so the same numbers bit for bit. The
 * loop over the columns as written kept its sums in memory (a store and
 * a reload per neighbour and column pair: 40 ns per vertex and half pass
 * on the 1.74M scan, perf). */
typedef double v2d __attribute__((vector_size(16)));

static inline v2d ld2(const double *p)
{
    v2d x;
    memcpy(&x, p, sizeof x);
    return x;
}

static inline void st2(double *p, v2d x)
{
    memcpy(p, &x, sizeof x);
}

static inline __attribute__((always_inline)) void row_update(const int *ptr, const int *adj,
                                                             const unsigned char *fixed, const double *v,
                                                             double *out, size_t i, double coef,
                                                             const int NCOL)
{
    const double *vi = v + (size_t)NCOL * i;
    double *o = out + (size_t)NCOL * i;
    int d = ptr[i + 1] - ptr[i];
    if ((fixed && fixed[i]) || d == 0) {
        memcpy(o, vi, sizeof(double) * (size_t)NCOL);
        return;
    }
    v2d s0 = {0.0, 0.0}, s1 = s0, s2 = s0, s3 = s0;
    double sl = 0.0; /* the last column when NCOL is odd */
    for (int t = ptr[i]; t < ptr[i + 1]; t++) {
        const double *vj = v + (size_t)NCOL * adj[t];
        s0 += ld2(vj);
        if (NCOL >= 4)
            s1 += ld2(vj + 2);
        if (NCOL >= 6)
            s2 += ld2(vj + 4);
        if (NCOL >= 8)
            s3 += ld2(vj + 6);
        if (NCOL & 1)
            sl += vj[NCOL - 1];
    }
    double dd = (double)d;
    v2d vd = {dd, dd}, vc = {coef, coef};
    st2(o, ld2(vi) + vc * (s0 / vd - ld2(vi)));
    if (NCOL >= 4)
        st2(o + 2, ld2(vi + 2) + vc * (s1 / vd - ld2(vi + 2)));
    if (NCOL >= 6)
        st2(o + 4, ld2(vi + 4) + vc * (s2 / vd - ld2(vi + 4)));
    if (NCOL >= 8)
        st2(o + 6, ld2(vi + 6) + vc * (s3 / vd - ld2(vi + 6)));
    if (NCOL & 1)
        o[NCOL - 1] = vi[NCOL - 1] + coef * (sl / dd - vi[NCOL - 1]);
}

#define HALF_PASS(NAME, NCOL)                                                                \
    static void NAME(const half_pass *h, size_t lo, size_t hi)                               \
    {                                                                                        \
        for (size_t i = lo; i < hi; i++)                                                     \
            row_update(h->g->ptr, h->g->adj, h->fixed, h->v, h->out, i, h->coef, NCOL);      \
    }

HALF_PASS(half_pass_3, 3)
HALF_PASS(half_pass_6, 6)
HALF_PASS(half_pass_9, 9)

static void half_pass_n(const half_pass *h, size_t lo, size_t hi)
{
    int n = h->ncol, *ptr = h->g->ptr;
    for (size_t i = lo; i < hi; i++) {
        const double *vi = h->v + (size_t)n * i;
        double *o = h->out + (size_t)n * i;
        int d = ptr[i + 1] - ptr[i];
        for (int c = 0; c < n; c++) {
            double s = 0.0;
            for (int t = ptr[i]; t < ptr[i + 1]; t++)
                s += h->v[(size_t)n * h->g->adj[t] + c];
            o[c] = (h->fixed && h->fixed[i]) || d == 0 ? vi[c] : vi[c] + h->coef * (s / d - vi[c]);
        }
    }
}

static void half_pass_range(void *ctx, size_t lo, size_t hi)
{
    const half_pass *h = ctx;
    if (h->ncol == 3)
        half_pass_3(h, lo, hi);
    else if (h->ncol == 6)
        half_pass_6(h, lo, hi);
    else if (h->ncol == 9)
        half_pass_9(h, lo, hi);
    else
        half_pass_n(h, lo, hi);
}

void mcf__graph_taubin(const mcf__graph *g, const unsigned char *fixed, double *X, int ncol,
                       int passes, double *tmp, int nthreads, double *cpu_s)
{
    /* lambda from X into tmp, mu from tmp back into X */
    half_pass h[2] = {{g, fixed, X, tmp, MCF_TAUBIN_LAMBDA, ncol},
                      {g, fixed, tmp, X, MCF_TAUBIN_MU, ncol}};
    for (int k = 0; k < passes; k++)
        for (int q = 0; q < 2; q++)
            mcf__par_for(nthreads, cpu_s, (size_t)g->n, half_pass_range, &h[q]);
}

