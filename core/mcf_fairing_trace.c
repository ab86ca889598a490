/* SPDX-License-Identifier: MIT */
/*
 * mcf_fairing_trace.c - the probe traces of the fairing's implicit engine,
 * and of the default request's explicit passes after it (mcf_fairing_ctx.h),
 * by Lanczos quadrature, so that the steps solve and those passes move the
 * three coordinates only. SURE
 * after K steps needs, per Rademacher probe z, an unbiased estimate of
 * tr(W T^K) (mcf_fairing.c), T one step on the free vertices, W the area
 * weights. Both steps are functions of one symmetric matrix, N = D_F^-1/2
 * L_FF D_F^-1/2 (the fixed vertices, creases included, enter only the
 * coordinates' affine part, not T): the implicit step T = D^-1/2 R D^1/2,
 * R = (I + N^2)^-1; the explicit pass (Taubin's lambda|mu pair of graph
 * averages, avg - x = -D^-1/2 N D^1/2 x) T = D^-1/2 P(N) D^1/2, P(l) =
 * (1 - mu l)(1 - lambda l). So tr(W T^K) = tr(W f_K(N)), f_K(l) = (1 +
 * l^2)^-K or P(l)^K, estimated by z' W f_K(N) z, the bilinear form a'
 * f_K(N) z with a = W z; m steps of Lanczos on N from z give T_m
 * (tridiagonal), the basis Q_m and c = Q_m' a, and
 *     a' f_K(N) z ~ |z| c' f_K(T_m) e1,
 * K banded solves of size m (I + T_m^2 is pentadiagonal) or 2K products
 * with T_m. The error is that of the best polynomial of degree m - 1 to
 * f_K on N's spectrum, within [0, 2] whatever the mesh: m grows with K, not
 * with the mesh (P^K is itself a polynomial of degree 2K: exact from m =
 * 2K + 1, and close long before: its shape is about exp(-0.265 K l^2)).
 * The explicit passes alone carry their probes as columns, whose estimate
 * z' W T^K z has the same mean (the trace) and a spread 1-3% lower (numpy,
 * 60 probes on armadillo.obj: lab/results/quality/issue27-pick); the
 * default request's explicit run takes its implicit run's Lanczos runs
 * (mcf_fairing.c, run_init), the same N and probes, and only extends them:
 * its probes then cost next to nothing. A Lanczos run of their own cost
 * the passes more than their columns (a step sweeps the probes three
 * times, and settling P^64 took 48 steps on the 435k dragon). Measured (numpy,
 * blade.obj's 7,991 free vertices, six probes, the implicit estimates from
 * 200 solves; lab/results/quality/issue31-cpu2): m = 20 reads K <= 8 to
 * 2e-10 n, m = 40 K <= 64 to 6e-12 n and K = 200 to 5e-9 n, m = 80 every K
 * <= 200 to 4e-15 n; the explicit ones: lab/results/quality/issue27-pick.
 * The steps are made as the run needs them (mcf__fair_lz_trace): from
 * LZ_FIRST on, LZ_GROW more at a time, until the estimates up to the step
 * asked agree with the previous m's to LZ_TOL n.
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
    int n, nprobe;
    int *rp, *ci;                  /* N's off-diagonal on the free vertices (CSR) */
    double *isq;                   /* n: 1 / sqrt(D) */
    double *q, *qprev, *p;         /* n x nprobe, the probes interleaved */
    double *alpha, *beta, *cz;     /* nprobe x mmax */
    int m[NPROBE], done[NPROBE];   /* steps made; invariant space reached */
    double bprev[NPROBE], znorm[NPROBE];
    double *est, *old;             /* nprobe x (cap + 1): at m, at mprev */
    int cap;                       /* the K est and old have room for */
    int expl;                      /* est, old and kgood are of P^K (explicit), else of R^K */
    int steps, mprev;              /* the steps made (every probe not done), at the last comparison */
    int turn;                      /* q, qprev hold q_{j-1}, beta_j q_{j+1}: extend's first sweep moves them */
    int kgood;                     /* est settled for K <= kgood */
    int mmax;                      /* allocated steps */
    double *band, *x, *y;          /* 3 x mmax (the banded factor), mmax, mmax */
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
    free(lz->alpha);
    free(lz->beta);
    free(lz->cz);
    free(lz->est);
    free(lz->old);
    free(lz->band);
    free(lz->x);
    free(lz->y);
    free(lz);
}

/* Every probe's Lanczos run carried to m steps (at most n), the probes
 * side by side: three sweeps a step. The first moves the last step's
 * next vector into place (lz->turn: q_j = r / beta, and q_{j-1} kept) and
 * reads c_j = (W z) . q_j and q_j / sq; the second v = N q_j on the free
 * vertices, q_k - (1/sq_k) sum over free neighbours j of q_j / sq_j, and
 * alpha_j, writing v - beta_{j-1} q_{j-1} over q_{j-1} (each entry read
 * once, at its own place); the third r = that - alpha_j q_j and its norm.
 * The same operations in the same order as five separate sweeps (one
 * per quantity: six passes took 12% of the default request on
 * couplingdown_sub2.obj iso 0.25 h, perf 2026-11-29), without the array
 * v = N q_j those kept. NP, the
 * probes, a constant of the compiler (extend): with the count a variable
 * the gather's loop over the probes took most of the 435k dragon's
 * Lanczos time in its own counter and branch (perf). */
static inline __attribute__((always_inline)) void extend_np(const fair_ctx *c, mcf__fair_lz *lz, int m,
                                                            const int NP)
{
    int n = lz->n, np = NP;
    double *Q = lz->q, *Qp = lz->qprev, *P = lz->p;
    if (m > n)
        m = n;
    for (int j = lz->steps; j < m; j++) {
        double a[NPROBE] = {0}, al[NPROBE] = {0}, b[NPROBE] = {0};
        for (int k = 0; k < n; k++) {
            double wk = c->w[c->vert[k]];
            for (int q = 0; q < np; q++) {
                size_t t = (size_t)k * np + q;
                if (lz->turn && !lz->done[q]) { /* (q_{j-1}, q_j) <- (q_j, q_{j+1}) */
                    double u = Q[t];
                    Q[t] = Qp[t] / lz->bprev[q];
                    Qp[t] = u;
                }
                a[q] += wk * c->probe[(size_t)q * n + k] * Q[t];
                P[t] = Q[t] * lz->isq[k];
            }
        }
        lz->turn = 0;
        for (int k = 0; k < n; k++) {
            double s[NPROBE] = {0};
            for (int t = lz->rp[k]; t < lz->rp[k + 1]; t++)
                for (int q = 0; q < np; q++)
                    s[q] += P[(size_t)lz->ci[t] * np + q];
            for (int q = 0; q < np; q++) {
                size_t t = (size_t)k * np + q;
                double v = Q[t] - lz->isq[k] * s[q];
                al[q] += Q[t] * v;
                Qp[t] = v - lz->bprev[q] * Qp[t];
            }
        }
        /* Qp <- N q_j - beta_{j-1} q_{j-1} - alpha_j q_j, the next vector
         * times beta_j */
        for (int k = 0; k < n; k++)
            for (int q = 0; q < np; q++) {
                size_t t = (size_t)k * np + q;
                Qp[t] = Qp[t] - al[q] * Q[t];
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
        lz->turn = 1;
        lz->steps = j + 1;
    }
}

static void extend(const fair_ctx *c, mcf__fair_lz *lz, int m)
{
    if (lz->nprobe == NPROBE)
        extend_np(c, lz, m, NPROBE);
    else if (lz->nprobe == NPROBE_FEW)
        extend_np(c, lz, m, NPROBE_FEW);
    else
        extend_np(c, lz, m, lz->nprobe);
}

/* y = x - t T x for the tridiagonal T (al, be) of size m */
static void tri_step(const double *al, const double *be, int m, double t, const double *x, double *y)
{
    for (int i = 0; i < m; i++) {
        double tx = al[i] * x[i] + (i > 0 ? be[i - 1] * x[i - 1] : 0.0) + (i + 1 < m ? be[i] * x[i + 1] : 0.0);
        y[i] = x[i] - t * tx;
    }
}

/* est[K] = |z| c' f_K(T) e1 for K = 0..kmax, T = T_m of probe q (m at most
 * the steps it made): f_K = P^K (lz->expl, two products with T a pass),
 * else (I + T^2)^-K (a banded solve a step). */
static void quadrature(mcf__fair_lz *lz, int q, int m, int kmax, double *est)
{
    if (m > lz->m[q])
        m = lz->m[q];
    const double *al = lz->alpha + (size_t)q * lz->mmax, *be = lz->beta + (size_t)q * lz->mmax,
                 *cz = lz->cz + (size_t)q * lz->mmax;
    double *d0 = lz->band, *d1 = d0 + lz->mmax, *d2 = d1 + lz->mmax, *x = lz->x;
    /* M = I + T^2 (rows i: diagonal, first and second subdiagonal), then
     * its banded Cholesky factor in place: M = L L', L's rows (d2, d1, d0) */
    for (int i = 0; !lz->expl && i < m; i++) {
        double bl = i > 0 ? be[i - 1] : 0.0, br = i + 1 < m ? be[i] : 0.0;
        d0[i] = 1.0 + al[i] * al[i] + bl * bl + br * br;
        d1[i] = i > 0 ? bl * (al[i - 1] + al[i]) : 0.0;
        d2[i] = i > 1 ? be[i - 2] * be[i - 1] : 0.0;
    }
    for (int i = 0; !lz->expl && i < m; i++) {
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
        if (K > 0 && lz->expl) { /* x <- (I - mu T)(I - lambda T) x */
            tri_step(al, be, m, MCF_TAUBIN_LAMBDA, x, lz->y);
            tri_step(al, be, m, MCF_TAUBIN_MU, lz->y, x);
        } else if (K > 0) {
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
    lz->mmax = mmax;
    lz->expl = c->is_explicit;
    lz->rp = mcf__malloc((size_t)n + 1, sizeof(int));
    lz->ci = mcf__malloc(nnz + 1, sizeof(int));
    lz->isq = mcf__malloc((size_t)n + 1, sizeof(double));
    lz->q = mcf__calloc((size_t)np * n + 1, sizeof(double));
    lz->qprev = mcf__calloc((size_t)np * n + 1, sizeof(double));
    lz->p = mcf__malloc((size_t)np * n + 1, sizeof(double));
    lz->alpha = mcf__malloc((size_t)np * mmax + 1, sizeof(double));
    lz->beta = mcf__malloc((size_t)np * mmax + 1, sizeof(double));
    lz->cz = mcf__malloc((size_t)np * mmax + 1, sizeof(double));
    lz->band = mcf__malloc(3 * (size_t)mmax + 1, sizeof(double));
    lz->x = mcf__malloc((size_t)mmax + 1, sizeof(double));
    lz->y = mcf__malloc((size_t)mmax + 1, sizeof(double));
    if (!lz->rp || !lz->ci || !lz->isq || !lz->q || !lz->qprev || !lz->p || !lz->alpha || !lz->beta || !lz->cz ||
        !lz->band || !lz->x || !lz->y)
        return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d free vertices)", n);
    c->bytes += sizeof(int) * ((size_t)n + 1 + nnz) +
                sizeof(double) * ((1 + 3 * (size_t)np) * n + (3 * np + 5) * (size_t)mmax);
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

int mcf__fair_lz_fits(const fair_ctx *c, const fair_ctx *from)
{
    size_t n = (size_t)c->nfree, nv = (size_t)c->nv;
    return from->lz && c->nfree == from->nfree && c->nv == from->nv && c->nprobe == from->nprobe &&
           c->g.ptr == from->g.ptr && !memcmp(c->vert, from->vert, n * sizeof(int)) &&
           !memcmp(c->sq, from->sq, n * sizeof(double)) && !memcmp(c->w, from->w, nv * sizeof(double)) &&
           !memcmp(c->probe, from->probe, (size_t)c->nprobe * n * sizeof(double));
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
    double *y = mcf__malloc((size_t)mm, sizeof(double));
    int ok = band && x && y;
    for (int t = 0; t < 3; t++)
        ok &= (r[t] = mcf__malloc((size_t)lz->nprobe * mm, sizeof(double))) != NULL;
    if (!ok) {
        for (int t = 0; t < 3; t++)
            free(r[t]);
        free(band);
        free(x);
        free(y);
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
    free(lz->y);
    lz->band = band;
    lz->x = x;
    lz->y = y;
    lz->mmax = mm;
    return 1;
}

/* Room in est and old for K <= cap, counted in c->bytes. */
static int reserve(fair_ctx *c, mcf__fair_lz *lz, int cap)
{
    if (cap <= lz->cap && lz->est)
        return 1;
    double *e = mcf__malloc((size_t)lz->nprobe * ((size_t)cap + 1), sizeof(double));
    double *o = mcf__malloc((size_t)lz->nprobe * ((size_t)cap + 1), sizeof(double));
    if (!e || !o) {
        free(e);
        free(o);
        return 0;
    }
    free(lz->est);
    free(lz->old);
    lz->est = e;
    lz->old = o;
    lz->cap = cap;
    lz->kgood = -1; /* est's layout changed */
    c->bytes += 2 * sizeof(double) * (size_t)lz->nprobe * ((size_t)cap + 1);
    return 1;
}

mcf_status mcf__fair_lz_trace(fair_ctx *c, int k, double est[NPROBE], mcf_error *err)
{
    mcf__fair_lz *lz = c->lz;
    int np = lz->nprobe;
    if (lz->expl != c->is_explicit) { /* the other filter's: its Lanczos
                                          steps kept, the quadrature anew */
        lz->expl = c->is_explicit;
        lz->kgood = -1;
    }
    if (!reserve(c, lz, c->cap > k ? c->cap : k))
        return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d free vertices)", lz->n);
    int ncap = lz->cap + 1;
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
        /* P^K has degree 2K: m Lanczos steps give it exactly for 2K < m
         * (from the three-term recurrence alone, which rounding keeps
         * whether or not the basis stays orthogonal) */
        if (lz->expl && (lz->steps - 1) / 2 > lz->kgood)
            lz->kgood = (lz->steps - 1) / 2 < kmax ? (lz->steps - 1) / 2 : kmax;
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
