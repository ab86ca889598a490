/* SPDX-License-Identifier: MIT */
/*
 * mcf_fairing_implicit.c - the fairing's implicit engine (mcf_fairing_ctx.h):
 * A = I + N N', N = D_F^-1/2 L_FF D_F^-1/2, assembled on the free 2-rings
 * and factored once per run (mcf_cholesky.c); each step one solve of the
 * three coordinates in y = D_F^1/2 x (SURE's probes: mcf_fairing_trace.c).
 * mcf_fairing.c has the notation and drives the run.
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_fairing_ctx.h"

/* The entries of column k of N = D^-1/2 L_FF D^-1/2 (symmetric): the
 * free neighbours of vert[k] and k itself, ascending, into row/val;
 * returns their count. */
static int n_column(const fair_ctx *c, int k, int *row, double *val)
{
    int i = c->vert[k], q = 0, placed = 0;
    for (int t = c->g.ptr[i]; t <= c->g.ptr[i + 1]; t++) {
        int j = t < c->g.ptr[i + 1] ? c->g.adj[t] : -1;
        if (!placed && (j < 0 || j > i)) {
            row[q] = k;
            val[q++] = 1.0;
            placed = 1;
        }
        if (j >= 0 && c->fid[j] >= 0) {
            row[q] = c->fid[j];
            val[q++] = -1.0 / (c->sq[k] * c->sq[c->fid[j]]);
        }
    }
    return q;
}

/* A = I + N N' = I + N^2, its upper triangle by columns (rows ascending,
 * the diagonal last) into c->apat and c->ax: column j gathers N_ik N_kj
 * over the entries k of N's column j and i <= j of N's column k (the free
 * 2-ring of j). N by columns first (np, nr, nx), then two passes: the
 * counts, then the entries. */
static mcf_status assemble(fair_ctx *c, mcf_error *err)
{
    int n = c->nfree;
    size_t nnz_n = (size_t)n;
    for (int k = 0; k < n; k++)
        nnz_n += (size_t)(c->g.ptr[c->vert[k] + 1] - c->g.ptr[c->vert[k]]);
    int *mark = mcf__malloc((size_t)n, sizeof(int)), *list = mcf__malloc((size_t)n, sizeof(int));
    int *np = mcf__malloc((size_t)n + 1, sizeof(int)), *nr = mcf__malloc(nnz_n, sizeof(int));
    double *acc = mcf__malloc((size_t)n, sizeof(double)), *nx = mcf__malloc(nnz_n, sizeof(double));
    int *cp = c->apat.colptr = mcf__malloc((size_t)n + 1, sizeof(int));
    mcf_status rc = MCF_OK;
    if (!mark || !list || !np || !nr || !acc || !nx || !cp) {
        rc = mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d free vertices)", n);
        goto done;
    }
    np[0] = 0;
    for (int k = 0; k < n; k++)
        np[k + 1] = np[k] + n_column(c, k, nr + np[k], nx + np[k]);
    c->apat.n = n;
    for (int pass = 0; pass < 2; pass++) {
        for (int i = 0; i < n; i++)
            mark[i] = -1;
        size_t q = 0;
        for (int j = 0; j < n; j++) {
            int m = 0;
            cp[j] = (int)q;
            for (int a = np[j]; a < np[j + 1]; a++) {
                int k = nr[a];
                for (int b = np[k]; b < np[k + 1] && nr[b] <= j; b++) {
                    int i = nr[b];
                    if (mark[i] != j) {
                        mark[i] = j;
                        acc[i] = 0.0;
                        list[m++] = i;
                    }
                    acc[i] += nx[b] * nx[a];
                }
            }
            if (pass == 1) {
                for (int a = 1; a < m; a++) /* insertion sort: a 2-ring */
                    for (int b = a; b > 0 && list[b - 1] > list[b]; b--) {
                        int t = list[b];
                        list[b] = list[b - 1];
                        list[b - 1] = t;
                    }
                for (int a = 0; a < m; a++) {
                    c->apat.rowind[q + (size_t)a] = list[a];
                    c->ax[q + (size_t)a] = acc[list[a]] + (list[a] == j ? 1.0 : 0.0);
                }
            }
            q += (size_t)m;
        }
        cp[n] = (int)q;
        if (pass == 0) {
            if (q > (size_t)INT32_MAX) {
                rc = mcf__fail(err, MCF_ELIMIT, "fairing: the system of %d free vertices is too large", n);
                goto done;
            }
            c->apat.nnz = (int)q;
            c->apat.rowind = mcf__malloc(q ? q : 1, sizeof(int));
            c->ax = mcf__fair_alloc(c, q);
            c->bytes += sizeof(int) * (q + (size_t)n + 1);
            if (!c->apat.rowind || !c->ax) {
                rc = mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d free vertices)", n);
                goto done;
            }
        }
    }
done:
    free(mark);
    free(list);
    free(np);
    free(nr);
    free(acc);
    free(nx);
    return rc;
}

mcf_status mcf__fair_implicit_init(fair_ctx *c, mcf_error *err)
{
    int n = c->nfree;
    mcf_status rc;
    c->Yc = mcf__fair_alloc(c, (size_t)c->ncol * (size_t)n);
    c->b = mcf__fair_alloc(c, 3 * (size_t)n);
    if (!c->Yc || !c->b)
        return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d free vertices)", n);
    if ((rc = assemble(c, err)) != MCF_OK || !(c->chol = mcf__chol_new(&c->apat, c->ncol, err)))
        return rc != MCF_OK ? rc : MCF_ENOMEM;
    double t0 = mcf_now();
    rc = mcf__chol_analyze(c->chol, err);
    c->st->time_analyze += mcf_now() - t0;
    if (rc != MCF_OK)
        return rc;
    t0 = mcf_now();
    rc = mcf__chol_factorize(c->chol, c->ax, err);
    c->st->time_factorize += mcf_now() - t0;
    c->st->factorizations++;
    if (rc != MCF_OK)
        return rc;
    /* b = N u, u_k = -D_k^-1/2 sum of the fixed neighbours' positions */
    double *u = c->b, *y = c->Yc;
    for (int k = 0; k < n; k++) {
        int i = c->vert[k];
        double s[3] = {0, 0, 0};
        for (int t = c->g.ptr[i]; t < c->g.ptr[i + 1]; t++)
            if (c->fid[c->g.adj[t]] < 0)
                for (int d = 0; d < 3; d++)
                    s[d] += c->X0[3 * (size_t)c->g.adj[t] + d];
        for (int d = 0; d < 3; d++)
            y[(size_t)d * n + k] = -s[d] / c->sq[k]; /* u, in Yc for now */
    }
    for (int k = 0; k < n; k++) {
        int i = c->vert[k];
        for (int d = 0; d < 3; d++) {
            double s = y[(size_t)d * n + k];
            for (int t = c->g.ptr[i]; t < c->g.ptr[i + 1]; t++) {
                int l = c->fid[c->g.adj[t]];
                if (l >= 0)
                    s -= y[(size_t)d * n + l] / (c->sq[k] * c->sq[l]);
            }
            u[(size_t)d * n + k] = s;
        }
    }
    /* y0 = D^1/2 x0 */
    for (int k = 0; k < n; k++)
        for (int d = 0; d < 3; d++)
            y[(size_t)d * n + k] = c->sq[k] * c->X0[3 * (size_t)c->vert[k] + d];
    return MCF_OK;
}

mcf_status mcf__fair_implicit_step(fair_ctx *c, mcf_error *err)
{
    int n = c->nfree;
    double t0 = mcf_now();
    double *y = c->Yc;
    for (size_t q = 0; q < 3 * (size_t)n; q++)
        y[q] -= c->b[q];
    mcf_status rc = mcf__chol_solve(c->chol, c->ncol, y, 1, (size_t)n, y, err);
    if (rc != MCF_OK)
        return rc;
    c->st->time_solve += mcf_now() - t0;
    c->st->solves += c->ncol / 3;
    return MCF_OK;
}

