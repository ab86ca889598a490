/* SPDX-License-Identifier: MIT */
/*
 * mcf_fairing_trace.c - the implicit engine's probe traces (mcf_fairing_ctx.h)
 * by Lanczos quadrature, so that its steps solve the three coordinates
 * only. SURE after K steps needs, per Rademacher probe z, the estimate
 * z' W R^K z of tr(W T^K) (mcf_fairing.c): R = (I + N^2)^-1, N = D_F^-1/2
 * L_FF D_F^-1/2 symmetric, W the area weights. With a = W z this is the
 * bilinear form a' f_K(N) z, f_K(l) = (1 + l^2)^-K; m steps of Lanczos on
 * N from z give T_m (tridiagonal), the basis Q_m and c = Q_m' a, and
 *     a' f_K(N) z ~ |z| c' f_K(T_m) e1 = |z| c' (I + T_m^2)^-K e1,
 * K banded solves of size m (I + T_m^2 is pentadiagonal). The error is that
 * of the best polynomial of degree m - 1 to f_K on N's spectrum, within
 * [0, 2] whatever the mesh: m grows with K, not with the mesh. Measured
 * (numpy, blade.obj's 7,991 free vertices, six probes, the exact values from
 * 200 solves; lab/results/quality/issue31-cpu2): m = 20 reads K <= 8 to
 * 2e-10 n, m = 40 K <= 64 to 6e-12 n and K = 200 to 5e-9 n, m = 80 every K
 * <= 200 to 4e-15 n, where carrying the probes cost two thirds of each
 * step's solve (9 columns for 3). The steps are made as the run needs them
 * (mcf__fair_lz_trace): from LZ_FIRST on, LZ_GROW more at a time, until the
 * estimates up to the step asked agree with the previous m's to LZ_TOL n.
 *
 * Pure C11; no globals.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_fairing_ctx.h"

/* the first Lanczos steps, and at least this many more when the estimates
 * asked for have not settled */
#define LZ_FIRST 16
#define LZ_GROW 16
/* settled: two successive m's estimates within LZ_TOL n (SURE's terms are
 * s^2 n; the summation of the steps' own estimates rounds at about 1e-16 n
 * per step) */
#define LZ_TOL 1e-12
/* a Lanczos vector this small against the start's norm: the Krylov space is
 * invariant, the quadrature exact from there on */
#define LZ_BREAK 1e-13

struct mcf__fair_lz {
    int n, nprobe, cap;
    int *rp, *ci;                  /* N's off-diagonal on the free vertices (CSR) */
    double *isq;                   /* n: 1 / sqrt(D) */
    double *q, *qprev, *p, *v;     /* n x nprobe, the probes interleaved */
    double *alpha, *beta, *cz;     /* nprobe x mmax */
    int m[NPROBE], done[NPROBE];   /* steps made; invariant space reached */
    double bprev[NPROBE], znorm[NPROBE];
    double *est, *old;             /* nprobe x (cap + 1): at m, at mprev */
    int steps, mprev;              /* the steps made (every probe not done), at the last comparison */
    int kgood;                     /* est settled for K <= kgood */
    int mmax;                      /* allocated steps */
    double *band, *x;              /* 3 x mmax (the banded factor), mmax */
};

void mcf__fair_lz_free(mcf__fair_lz *lz)
{
    if (!lz)
        return;
    free(lz->rp);
    free(lz->ci);
    free(lz->isq);
    free(lz->q);
    free(lz->qprev);
    free(lz->p);
    free(lz->v);
    free(lz->alpha);
    free(lz->beta);
    free(lz->cz);
    free(lz->est);
    free(lz->old);
    free(lz->band);
    free(lz->x);
    free(lz);
}

/* c_j = (W z) . q_j of each probe into a, and P = D^-1/2 q_j, from q_j
 * in Q (its row k). */
static void start_row(const fair_ctx *c, const mcf__fair_lz *lz, int k, double *a)
{
    int n = lz->n, np = lz->nprobe;
    double wk = c->w[c->vert[k]];
    for (int q = 0; q < np; q++) {
        size_t t = (size_t)k * np + q;
        a[q] += wk * c->probe[(size_t)q * n + k] * lz->q[t];
        lz->p[t] = lz->q[t] * lz->isq[k];
    }
}

/* Every probe's Lanczos run carried to m steps (at most n), the probes
 * side by side: one sweep over N per step. v = N q on the free vertices:
 * q_k - (1/sq_k) sum over free neighbours j of q_j / sq_j. Three passes
 * over the vertices a step (the step's c_j and P with the last one's
 * shift of the basis, then v with alpha, then the next vector with
 * beta), each value and sum made as by one pass per quantity, in the
 * same order: the same bits, where six passes took 12% of the default
 * request on couplingdown_sub2.obj (iso 0.25 h, perf 2026-11-29). */
static void extend(const fair_ctx *c, mcf__fair_lz *lz, int m)
{
    int n = lz->n, np = lz->nprobe;
    double *Q = lz->q, *Qp = lz->qprev, *V = lz->v;
    double a[NPROBE] = {0};
    if (m > n)
        m = n;
    if (lz->steps < m)
        for (int k = 0; k < n; k++)
            start_row(c, lz, k, a);
    for (int j = lz->steps; j < m; j++) {
        double al[NPROBE] = {0}, b[NPROBE] = {0};
        for (int k = 0; k < n; k++) {
            double s[NPROBE] = {0};
            for (int t = lz->rp[k]; t < lz->rp[k + 1]; t++)
                for (int q = 0; q < np; q++)
                    s[q] += lz->p[(size_t)lz->ci[t] * np + q];
            for (int q = 0; q < np; q++) {
                size_t t = (size_t)k * np + q;
                V[t] = Q[t] - lz->isq[k] * s[q];
                al[q] += Q[t] * V[t];
            }
        }
        /* Qp <- N q_j - beta_{j-1} q_{j-1} - alpha_j q_j, the next vector */
        for (int k = 0; k < n; k++)
            for (int q = 0; q < np; q++) {
                size_t t = (size_t)k * np + q;
                Qp[t] = V[t] - lz->bprev[q] * Qp[t] - al[q] * Q[t];
                b[q] += Qp[t] * Qp[t];
            }
        for (int q = 0; q < np; q++) {
            if (lz->done[q])
                continue;
            b[q] = sqrt(b[q]);
            size_t o = (size_t)q * lz->mmax + (size_t)j;
            lz->cz[o] = a[q];
            lz->alpha[o] = al[q];
            lz->beta[o] = b[q];
            lz->m[q] = j + 1;
            lz->done[q] = !(b[q] > LZ_BREAK); /* unit start: relative to 1 */
            lz->bprev[q] = b[q];
        }
        /* (q_{j-1}, q_j) <- (q_j, q_{j+1}), and the next step's start */
        int more = j + 1 < m;
        memset(a, 0, sizeof a);
        for (int k = 0; k < n; k++) {
            for (int q = 0; q < np; q++) {
                size_t t = (size_t)k * np + q;
                double u = Q[t];
                Q[t] = lz->done[q] ? u : Qp[t] / lz->bprev[q];
                Qp[t] = lz->done[q] ? Qp[t] : u;
            }
            if (more)
                start_row(c, lz, k, a);
        }
        lz->steps = j + 1;
    }
}

/* est[K] = |z| c' (I + T^2)^-K e1 for K = 0..kmax, T = T_m of probe q
 * (m at most the steps it made). */
static void quadrature(mcf__fair_lz *lz, int q, int m, int kmax, double *est)
{
    if (m > lz->m[q])
        m = lz->m[q];
    const double *al = lz->alpha + (size_t)q * lz->mmax, *be = lz->beta + (size_t)q * lz->mmax,
                 *cz = lz->cz + (size_t)q * lz->mmax;
    double *d0 = lz->band, *d1 = d0 + lz->mmax, *d2 = d1 + lz->mmax, *x = lz->x;
    /* M = I + T^2 (rows i: diagonal, first and second subdiagonal), then
     * its banded Cholesky factor in place: M = L L', L's rows (d2, d1, d0) */
    for (int i = 0; i < m; i++) {
        double bl = i > 0 ? be[i - 1] : 0.0, br = i + 1 < m ? be[i] : 0.0;
        d0[i] = 1.0 + al[i] * al[i] + bl * bl + br * br;
        d1[i] = i > 0 ? bl * (al[i - 1] + al[i]) : 0.0;
        d2[i] = i > 1 ? be[i - 2] * be[i - 1] : 0.0;
    }
    for (int i = 0; i < m; i++) {
        double l2 = i > 1 ? d2[i] / d0[i - 2] : 0.0;
        double l1 = i > 0 ? (d1[i] - (i > 1 ? l2 * d1[i - 1] : 0.0)) / d0[i - 1] : 0.0;
        d0[i] = sqrt(d0[i] - l1 * l1 - l2 * l2);
        d1[i] = l1;
        d2[i] = l2;
    }
    if (m > 0) {
        memset(x, 0, sizeof(double) * (size_t)m);
        x[0] = 1.0;
    }
    for (int K = 0; K <= kmax; K++) {
        if (K > 0) {
            for (int i = 0; i < m; i++) /* L y = x */
                x[i] = (x[i] - (i > 0 ? d1[i] * x[i - 1] : 0.0) - (i > 1 ? d2[i] * x[i - 2] : 0.0)) / d0[i];
            for (int i = m - 1; i >= 0; i--) /* L' x = y */
                x[i] = (x[i] - (i + 1 < m ? d1[i + 1] * x[i + 1] : 0.0) - (i + 2 < m ? d2[i + 2] * x[i + 2] : 0.0)) /
                       d0[i];
        }
        double s = 0.0;
        for (int i = 0; i < m; i++)
            s += cz[i] * x[i];
        est[K] = lz->znorm[q] * s;
    }
}

mcf_status mcf__fair_lz_new(fair_ctx *c, mcf_error *err)
{
    int n = c->nfree, np = c->nprobe, mmax = n < 64 ? n : 64;
    size_t nnz = 0;
    mcf__fair_lz *lz = c->lz = mcf__calloc(1, sizeof *lz);
    if (!lz)
        return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d free vertices)", n);
    for (int k = 0; k < n; k++)
        nnz += (size_t)(c->g.ptr[c->vert[k] + 1] - c->g.ptr[c->vert[k]]);
    lz->n = n;
    lz->nprobe = np;
    lz->cap = c->cap;
    lz->mmax = mmax;
    lz->rp = mcf__malloc((size_t)n + 1, sizeof(int));
    lz->ci = mcf__malloc(nnz + 1, sizeof(int));
    lz->isq = mcf__malloc((size_t)n + 1, sizeof(double));
    lz->q = mcf__calloc((size_t)np * n + 1, sizeof(double));
    lz->qprev = mcf__calloc((size_t)np * n + 1, sizeof(double));
    lz->p = mcf__malloc((size_t)np * n + 1, sizeof(double));
    lz->v = mcf__malloc((size_t)np * n + 1, sizeof(double));
    lz->alpha = mcf__malloc((size_t)np * mmax + 1, sizeof(double));
    lz->beta = mcf__malloc((size_t)np * mmax + 1, sizeof(double));
    lz->cz = mcf__malloc((size_t)np * mmax + 1, sizeof(double));
    lz->est = mcf__malloc((size_t)np * (c->cap + 1), sizeof(double));
    lz->old = mcf__malloc((size_t)np * (c->cap + 1), sizeof(double));
    lz->band = mcf__malloc(3 * (size_t)mmax + 1, sizeof(double));
    lz->x = mcf__malloc((size_t)mmax + 1, sizeof(double));
    if (!lz->rp || !lz->ci || !lz->isq || !lz->q || !lz->qprev || !lz->p || !lz->v || !lz->alpha || !lz->beta ||
        !lz->cz || !lz->est || !lz->old || !lz->band || !lz->x)
        return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d free vertices)", n);
    c->bytes += sizeof(int) * ((size_t)n + 1 + nnz) +
                sizeof(double) * ((1 + 4 * (size_t)np) * n + 2 * (size_t)np * (c->cap + 1) + (3 * np + 4) * (size_t)mmax);
    /* the free neighbours of each free vertex, in the graph's order */
    size_t t = 0;
    for (int k = 0; k < n; k++) {
        int i = c->vert[k];
        lz->rp[k] = (int)t;
        for (int e = c->g.ptr[i]; e < c->g.ptr[i + 1]; e++)
            if (c->fid[c->g.adj[e]] >= 0)
                lz->ci[t++] = c->fid[c->g.adj[e]];
        lz->isq[k] = 1.0 / c->sq[k];
    }
    lz->rp[n] = (int)t;
    for (int q = 0; q < np; q++) { /* q_1 = z / |z| */
        const double *z = c->probe + (size_t)q * n;
        double s = 0.0;
        for (int k = 0; k < n; k++)
            s += z[k] * z[k];
        lz->znorm[q] = sqrt(s);
        for (int k = 0; s > 0.0 && k < n; k++)
            lz->q[(size_t)k * np + q] = z[k] / lz->znorm[q];
        lz->done[q] = !(s > 0.0);
    }
    lz->kgood = -1;
    return MCF_OK;
}

/* Room for m steps per probe (the arrays kept by probe). */
static int grow(mcf__fair_lz *lz, int m)
{
    if (m <= lz->mmax)
        return 1;
    int mm = m > 2 * lz->mmax ? m : 2 * lz->mmax;
    if (mm > lz->n)
        mm = lz->n;
    /* everything allocated before anything is replaced: a failure leaves
     * lz as it was, for mcf__fair_lz_free */
    double *r[3], *band = mcf__malloc(3 * (size_t)mm, sizeof(double)), *x = mcf__malloc((size_t)mm, sizeof(double));
    int ok = band && x;
    for (int t = 0; t < 3; t++)
        ok &= (r[t] = mcf__malloc((size_t)lz->nprobe * mm, sizeof(double))) != NULL;
    if (!ok) {
        for (int t = 0; t < 3; t++)
            free(r[t]);
        free(band);
        free(x);
        return 0;
    }
    double **a[3] = {&lz->alpha, &lz->beta, &lz->cz};
    for (int t = 0; t < 3; t++) {
        for (int q = 0; q < lz->nprobe; q++)
            memcpy(r[t] + (size_t)q * mm, *a[t] + (size_t)q * lz->mmax, sizeof(double) * (size_t)lz->m[q]);
        free(*a[t]);
        *a[t] = r[t];
    }
    free(lz->band);
    free(lz->x);
    lz->band = band;
    lz->x = x;
    lz->mmax = mm;
    return 1;
}

mcf_status mcf__fair_lz_trace(fair_ctx *c, int k, double est[NPROBE], mcf_error *err)
{
    mcf__fair_lz *lz = c->lz;
    int np = lz->nprobe, ncap = lz->cap + 1;
    while (lz->kgood < k) {
        /* the estimates up to twice the step asked for (at least LZ_FIRST) */
        int kmax = 2 * k > LZ_FIRST ? 2 * k : LZ_FIRST, exact = 1;
        if (kmax > lz->cap)
            kmax = lz->cap;
        for (int q = 0; q < np; q++)
            exact &= lz->done[q];
        exact = exact || lz->steps >= lz->n;
        if (lz->steps == 0 && !exact) {
            if (!grow(lz, LZ_FIRST < lz->n ? LZ_FIRST : lz->n))
                return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d free vertices)", lz->n);
            extend(c, lz, LZ_FIRST);
            continue;
        }
        for (int q = 0; q < np; q++)
            quadrature(lz, q, lz->steps, kmax, lz->est + (size_t)q * ncap);
        if (exact) { /* the Krylov space is invariant: nothing to compare */
            lz->kgood = kmax;
            break;
        }
        /* settled up to the first K where some probe moved more than
         * LZ_TOL n from the last comparison's m */
        int K = 0;
        if (lz->mprev > 0) {
            for (int q = 0; q < np; q++)
                quadrature(lz, q, lz->mprev, kmax, lz->old + (size_t)q * ncap);
            for (; K <= kmax; K++) {
                int ok = 1;
                for (int q = 0; q < np && ok; q++)
                    ok = fabs(lz->est[(size_t)q * ncap + K] - lz->old[(size_t)q * ncap + K]) <= LZ_TOL * lz->n;
                if (!ok)
                    break;
            }
        }
        lz->kgood = K - 1;
        if (lz->kgood >= k)
            break;
        int m = lz->steps + (lz->steps / 2 > LZ_GROW ? lz->steps / 2 : LZ_GROW);
        if (m > lz->n)
            m = lz->n;
        if (!grow(lz, m))
            return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d free vertices)", lz->n);
        lz->mprev = lz->steps;
        extend(c, lz, m);
    }
    for (int q = 0; q < np; q++)
        est[q] = lz->est[(size_t)q * ncap + k];
    return MCF_OK;
}
