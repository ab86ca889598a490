/* SPDX-License-Identifier: MIT */
/*
 * mcf_auto.c - the automatic amount of smoothing: the noise level of the
 * mesh itself, then the amount (an MCF time, or Taubin's pass count) that
 * minimizes Stein's unbiased risk estimate (SURE) of the result.
 *
 * Model: the input is a clean surface plus i.i.d. Gaussian noise of
 * standard deviation s along the vertex normals. The smoother S is the
 * run's own linearization, its operator frozen at the input and its fixed
 * vertices (boundary, the caller's list, unreferenced) held. For the
 * normal component of the displacement r_i = n_i . (S Y - Y)_i over the
 * n_F free vertices,
 *     SURE(S) = sum_F r^2 - n_F s^2 + 2 s^2 tr(S)
 * is an unbiased estimate of the squared error against the clean surface
 * (Stein 1981), so its minimizer over the amount estimates the best
 * amount. (Weighted by the vertex areas, as the metrics weigh the error,
 * it chose 10-30% longer times and errors up to 4% worse on armadillo,
 * snowden, spot and fertility at noise 0.25: unweighted.) The trace
 * comes from Hutchinson's estimator with one Rademacher probe carried as
 * a fourth column of the same solves (three probes, a third fewer
 * columns' worth of cost, changed the error of the result by under 0.3%
 * on the sphere, the coarse bunny and spot at noise 0.1-0.5, 3 seeds:
 * the probe's error is nearly the same at every amount, and the minimum
 * moves little).
 *
 * The noise level s is the hard part: the residual after a small
 * smoothing underestimates it 1.5-2.3x (the smoothing removes part of the
 * noise, the surface's own detail adds to it). Here s is measured by a
 * second-order high-pass that cancels a smooth surface to second order,
 * e_i = d_i - avg_j d_j with d_i = n_i . (Y_i - avg_j Y_j) over the
 * 1-ring (the uniform graph Laplacian, mcf_graph.c), whose response to
 * noise depends on the valences and shapes around each vertex; it is
 * calibrated on the same mesh by the response to unit Gaussian noise along
 * the normals (s = MAD(e_Y) / MAD(e_noise)), and the median absolute
 * deviation ignores the features (creases, ears) where the surface itself
 * does not cancel. The normals n are those of 10 uniform Taubin passes of
 * Y, not Y's own: a noisy normal tilts with the noise and the projection
 * then misses part of it (0.36-0.39 read for 0.5). Both medians run over
 * the free vertices of degree >= 3 only: fixed and boundary vertices
 * carry no noise, and counting them read 0.5 as 0.23 on a scan with many
 * holes.
 *
 * MCF (mcf__auto_time): the run does K steps of size T/K; its smoother is
 * modelled by K frozen implicit Euler steps, ((M + T/K L)^-1 M)^K. One
 * factorization serves every candidate: M + h0 L with h0 = t0 / K' (K' =
 * min(K, 6)), t0 the time a prior from the noise level expects (strength
 * 0.8 rho + 0.25 mean edges, the fit of the oracle's best times in `make
 * quality`), and candidate k is k steps of h0, one more four-column solve
 * each; the search stops 3 steps past the minimum (cap 4 K'). k steps of
 * h0 and K steps of T/K are different rational filters; candidate k is
 * mapped to the run's time whose filter halves the same frequency (the
 * gains (1 + h lambda)^-k = 1/2 at h lambda = 2^(1/k) - 1), 4% apart at
 * k = 5 and K = 10 (K' = 10 instead of 6: the same errors, 4 more
 * solves). The frozen model runs slower than the run: the noise
 * inflates the area, the mass M follows it (L's weights are scale-free),
 * and the run's diffusion M^-1 L speeds up as the noise goes, most of it
 * early. So the time is scaled by the area of the frozen result at the
 * minimum over the input's (0.97 / 0.88 / 0.70 at noise 0.1 / 0.25 /
 * 0.5); given the true noise level, desbrun2 then came within 1% of the
 * best time's error on spot, armadillo and the coarse bunny at noise 0.5
 * (1.15x, 1.07x, 1.25x without it). moving_mass 0 (the `linear` scheme,
 * whose operators are the frozen ones) skips it. Cost: one analysis, one
 * factorization and k* + 3 solves (about 10), against the run's K
 * factorizations: 1.2-1.45x the fixed amount's run in all, the noise
 * estimate included.
 *
 * Taubin (mcf__auto_passes): the passes x += lambda U x, x += mu U x with
 * U = -D^-1 L frozen at the input, on the positions and the probes; SURE
 * after every pass, stopping at 2 k* + 10 passes (cap MCF_AUTO_MAX_PASSES).
 *
 * Pure C11, no globals; the factorization and the solves by mcf_cholesky.c:
 * the run's solver when it lends it (an implicit scheme: its pattern and
 * symbolic analysis, which the run's own factorizations then reuse), else
 * one of its own.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_internal.h"

enum { NPROBE = 1, NCOL = 3 + NPROBE };
/* the uneven reading (mcf__noise_shape) leaves out the high-pass values
 * above NOISE_TRIM robust deviations: creases and spikes, not noise */
#define NOISE_TRIM 4.0

typedef struct {
    int nv, nf;
    const int32_t *F;
    mcf__pattern own_pat; /* built here unless the run lends its own */
    const mcf__pattern *pat;
    double *N;          /* 3*nv unit vertex normals of X */
    unsigned char *fix; /* nv: held by the run (or massless) */
    int nfree;          /* vertices not held */
    double *probe;      /* NPROBE*nv Rademacher probes, 0 on fixed */
    double *yn;         /* nv: n_i . X_i */
    double *mass;       /* nv: the lumped mass at X */
    double *lval;       /* pattern nnz: L's upper values at X */
    mcf__chol *own_ch;  /* the solver, unless the run lends its own */
    double *ax;         /* pattern nnz: M + h0 L */
    double *B;          /* nv x NCOL, column-major: the state */
} auto_ctx;

static void auto_free(auto_ctx *a)
{
    free(a->N);
    free(a->fix);
    free(a->probe);
    free(a->yn);
    free(a->mass);
    free(a->lval);
    free(a->ax);
    free(a->B);
    mcf__chol_free(a->own_ch);
    mcf__pattern_free(&a->own_pat);
}

/* The second-order high-pass along the unit normals N (3*nv) of positions
 * P (3*nv) into e (nv): d_i = n_i . (P_i - avg_j P_j) over the 1-ring,
 * e_i = d_i - avg_j d_j. d (nv) and tmp (3*nv) are scratch. */
static void high_pass(const mcf__graph *g, const double *N, const double *P, double *e,
                      double *d, double *tmp)
{
    mcf__graph_average(g, P, 3, tmp);
    for (int i = 0; i < g->n; i++) {
        double r[3];
        mcf__sub3(P + 3 * (size_t)i, tmp + 3 * (size_t)i, r);
        d[i] = mcf__dot3(N + 3 * (size_t)i, r);
    }
    mcf__graph_average(g, d, 1, tmp);
    for (int i = 0; i < g->n; i++)
        e[i] = d[i] - tmp[i];
}

/* Median of |v_i| over the free vertices with a 1-ring of at least 3 (the
 * others, on slivers and boundaries' tips, say little; fixed vertices
 * carry no noise); work (nv) is scratch. */
static double mad(const mcf__graph *g, const unsigned char *fixed, const double *v,
                  double *work)
{
    size_t k = 0;
    for (int i = 0; i < g->n; i++)
        if (g->ptr[i + 1] - g->ptr[i] >= 3 && !(fixed && fixed[i]))
            work[k++] = fabs(v[i]);
    return mcf__median(work, k);
}

/* The RMS of v over the vertices mad() counts, those with |v| above
 * trim robust deviations (1.4826 mad) left out (creases, spikes). */
static double trimmed_rms(const mcf__graph *g, const unsigned char *fixed, const double *v, double mad_v,
                          double trim)
{
    double s = 0.0, lim = trim * 1.4826 * mad_v;
    size_t k = 0;
    for (int i = 0; i < g->n; i++)
        if (g->ptr[i + 1] - g->ptr[i] >= 3 && !(fixed && fixed[i]) && fabs(v[i]) <= lim) {
            s += v[i] * v[i];
            k++;
        }
    return k ? sqrt(s / (double)k) : 0.0;
}

/* The correlation of v with its 1-ring average, sum v_i (Avg v)_i / sum
 * v_i^2, over the vertices mad() counts with |v_i| within trim robust
 * deviations; avg (nv) scratch. */
static double ring_correlation(const mcf__graph *g, const unsigned char *fixed, const double *v, double mad_v,
                               double trim, double *avg)
{
    double num = 0.0, den = 0.0, lim = trim * 1.4826 * mad_v;
    mcf__graph_average(g, v, 1, avg);
    for (int i = 0; i < g->n; i++)
        if (g->ptr[i + 1] - g->ptr[i] >= 3 && !(fixed && fixed[i]) && fabs(v[i]) <= lim) {
            num += v[i] * avg[i];
            den += v[i] * v[i];
        }
    return den > 0.0 ? num / den : 0.0;
}

/* The largest eigenvalue of the symmetric 3 x 3 M (row-major) in closed
 * form (the trigonometric solution of its characteristic cubic: Smith,
 * CACM 4(4) 168, 1961) and a unit eigenvector of it into v (the longest
 * cross product of two rows of M - lambda I; any unit vector when lambda
 * is a double eigenvalue). */
static double largest_eigen(const double *M, double *v)
{
    double q = (M[0] + M[4] + M[8]) / 3.0, p1 = M[1] * M[1] + M[2] * M[2] + M[5] * M[5];
    double p2 = (M[0] - q) * (M[0] - q) + (M[4] - q) * (M[4] - q) + (M[8] - q) * (M[8] - q) + 2.0 * p1;
    double p = sqrt(p2 / 6.0), lam = q;
    v[0] = 1.0;
    v[1] = v[2] = 0.0;
    if (!(p > 0.0))
        return lam;
    double B[9];
    for (int a = 0; a < 9; a++)
        B[a] = (M[a] - (a % 4 == 0 ? q : 0.0)) / p;
    double r = 0.5 * (B[0] * (B[4] * B[8] - B[5] * B[7]) - B[1] * (B[3] * B[8] - B[5] * B[6]) +
                      B[2] * (B[3] * B[7] - B[4] * B[6]));
    lam = q + 2.0 * p * cos(acos(fmax(-1.0, fmin(1.0, r))) / 3.0);
    double R[9], c[3][3], best = 0.0;
    for (int a = 0; a < 9; a++)
        R[a] = M[a] - (a % 4 == 0 ? lam : 0.0);
    mcf__cross3(R, R + 3, c[0]);
    mcf__cross3(R, R + 6, c[1]);
    mcf__cross3(R + 3, R + 6, c[2]);
    for (int k = 0; k < 3; k++) {
        double l = mcf__dot3(c[k], c[k]);
        if (l > best) {
            best = l;
            for (int a = 0; a < 3; a++)
                v[a] = c[k][a];
        }
    }
    if (best > 0.0)
        for (int a = 0; a < 3; a++)
            v[a] /= sqrt(best);
    return lam;
}

/* The share of the largest eigenvalue of the 3 x 3 sum of E_i E_i' over
 * the vertices mad() counts whose |E_i| is at most trim times the median,
 * E (3*nv) the second-order high-pass vectors (I - Avg)^2 X, and its unit
 * eigenvector into dir; len (nv) and work (nv) scratch. 1/3 for
 * directions spread evenly, 1 for one direction. */
static double direction_share(const mcf__graph *g, const unsigned char *fixed, const double *E, double trim,
                              double *len, double *work, double *dir)
{
    double M[9] = {0};
    for (int i = 0; i < g->n; i++)
        len[i] = sqrt(mcf__dot3(E + 3 * (size_t)i, E + 3 * (size_t)i));
    double lim = trim * mad(g, fixed, len, work);
    for (int i = 0; i < g->n; i++)
        if (g->ptr[i + 1] - g->ptr[i] >= 3 && !(fixed && fixed[i]) && len[i] <= lim)
            for (int a = 0; a < 3; a++)
                for (int b = 0; b < 3; b++)
                    M[3 * a + b] += E[3 * (size_t)i + a] * E[3 * (size_t)i + b];
    double trace = M[0] + M[4] + M[8];
    if (!(trace > 0.0))
        return 0.0;
    return largest_eigen(M, dir) / trace;
}

/* The variance of the second-order high-pass ((I - Avg)^2 z)_i of unit
 * i.i.d. values z on the free vertices (0 on the fixed) into c (nv): the
 * squared norm of row i of (I - Avg)^2 over the free columns, accumulated
 * over the 2-ring; acc (nv) scratch, zero on entry and exit, and touched
 * (nv) scratch. */
static void high_pass_variance(const mcf__graph *g, const unsigned char *fixed, double *c, double *acc,
                               int *touched)
{
    for (int i = 0; i < g->n; i++) {
        int nt = 0, di = g->ptr[i + 1] - g->ptr[i];
        /* row i of I - Avg: 1 at i, -1/d_i at its neighbours (none: 0) */
#define ADD(k, x)                   \
    do {                            \
        if (acc[k] == 0.0)          \
            touched[nt++] = (k);    \
        acc[k] += (x);              \
        if (acc[k] == 0.0)          \
            acc[k] = 1e-300;        \
    } while (0)
        for (int t = -1; t < di; t++) {
            int j = t < 0 ? i : g->adj[g->ptr[i] + t];
            double a = di == 0 ? 0.0 : t < 0 ? 1.0 : -1.0 / di;
            int dj = g->ptr[j + 1] - g->ptr[j];
            if (a == 0.0 || dj == 0)
                continue;
            /* times row j of I - Avg */
            ADD(j, a);
            for (int s = g->ptr[j]; s < g->ptr[j + 1]; s++)
                ADD(g->adj[s], -a / dj);
        }
#undef ADD
        double v = 0.0;
        for (int q = 0; q < nt; q++) {
            int k = touched[q];
            if (!(fixed && fixed[k]))
                v += acc[k] * acc[k];
            acc[k] = 0.0;
        }
        c[i] = v;
    }
}

/* The tangential second-order high-pass of P (3*nv) into e (nv): the
 * length of the tangential part (normals N) of (I - Avg)^2 P; tmp and t2
 * are 3*nv scratch. */
static void tangential_high_pass(const mcf__graph *g, const double *N, const double *P, double *e,
                                 double *tmp, double *t2)
{
    size_t n3 = 3 * (size_t)g->n;
    mcf__graph_average(g, P, 3, tmp);
    for (size_t q = 0; q < n3; q++)
        tmp[q] = P[q] - tmp[q];
    mcf__graph_average(g, tmp, 3, t2);
    for (int i = 0; i < g->n; i++) {
        double r[3];
        const double *n = N + 3 * (size_t)i;
        mcf__sub3(tmp + 3 * (size_t)i, t2 + 3 * (size_t)i, r);
        double a = mcf__dot3(n, r);
        for (int c = 0; c < 3; c++)
            r[c] -= a * n[c];
        e[i] = sqrt(mcf__dot3(r, r));
    }
}

mcf_status mcf__noise_level(const double *X, const int32_t *F, int nf, int nv,
                            const unsigned char *fixed, double *sigma, mcf_error *err)
{
    return mcf__noise_levels(NULL, X, F, nf, nv, fixed, sigma, NULL, NULL, NULL, err);
}

/* The noise reading's stages' shares of its time (tick), measured on the
 * 435k dragon (clean, 2026-11-28, 2 loaded cores: 1.07 s, 0.31 s, 0.58 s,
 * 0.39 s): the smoothed normals (10 Taubin passes), the level along
 * them, the shape; the tangential reading the rest. */
#define NOISE_TICK_NORMALS 0.45
#define NOISE_TICK_LEVEL 0.6
#define NOISE_TICK_SHAPE 0.85
mcf_status mcf__noise_levels(const mcf__graph *given, const double *X, const int32_t *F, int nf, int nv,
                             const unsigned char *fixed, double *sigma, double *sigma_t,
                             mcf__noise_shape *shape, const mcf__tick *tick, mcf_error *err)
{
    mcf__graph g;
    mcf_status rc = MCF_OK;
    if (given)
        g = *given; /* borrowed: not freed below */
    else if ((rc = mcf__graph_build(F, nf, nv, &g, err)) != MCF_OK)
        return rc;
    double *N = mcf__malloc(3 * (size_t)nv, sizeof(double));
    double *P = mcf__malloc(3 * (size_t)nv, sizeof(double));
    double *tmp = mcf__malloc(3 * (size_t)nv, sizeof(double));
    double *e = mcf__malloc((size_t)nv, sizeof(double));
    double *d = mcf__malloc((size_t)nv, sizeof(double));
    if (!N || !P || !tmp || !e || !d) {
        rc = mcf__fail(err, MCF_ENOMEM, "noise estimate: out of memory (%d vertices)", nv);
        goto done;
    }
    /* the normals of the surface without its noise: those of the noisy
     * mesh itself tilt with the noise, and the high-pass along them then
     * misses a part of it (0.36-0.39 read for 0.5 mean edges) */
    memcpy(P, X, 3 * sizeof(double) * (size_t)nv);
    mcf__graph_taubin(&g, fixed, P, 3, 10, tmp, 1, NULL);
    mcf__vertex_normals(P, F, nf, nv, N);
    mcf__ticked(tick, "noise", NOISE_TICK_NORMALS);
    high_pass(&g, N, X, e, d, tmp);
    double mad_y = mad(&g, fixed, e, P), rms_y = shape ? trimmed_rms(&g, fixed, e, mad_y, NOISE_TRIM) : 0.0;
    double corr_y = shape ? ring_correlation(&g, fixed, e, mad_y, NOISE_TRIM, tmp) : 0.0;
    /* the response to unit Gaussian noise along the same normals on the
     * free vertices (mcf_mesh_add_noise's generator: reproducible) */
    mcf__gauss_fill(0x5eed5eedULL, d, (size_t)nv);
    for (int i = 0; i < nv; i++)
        for (int c = 0; c < 3; c++)
            P[3 * (size_t)i + c] = fixed && fixed[i] ? 0.0 : d[i] * N[3 * (size_t)i + c];
    high_pass(&g, N, P, e, d, tmp);
    double mad_n = mad(&g, fixed, e, P);
    *sigma = mad_n > 0.0 ? mad_y / mad_n : 0.0;
    mcf__ticked(tick, "noise", NOISE_TICK_LEVEL);
    if (shape) {
        double rms_n = trimmed_rms(&g, fixed, e, mad_n, NOISE_TRIM);
        shape->corr = corr_y;
        shape->corr_noise = ring_correlation(&g, fixed, e, mad_n, NOISE_TRIM, tmp);
        shape->sigma_rms = rms_n > 0.0 ? rms_y / rms_n : 0.0;
        /* the high-pass vectors (I - Avg)^2 X into P, their directions */
        mcf__graph_average(&g, X, 3, tmp);
        for (size_t q = 0; q < 3 * (size_t)nv; q++)
            tmp[q] = X[q] - tmp[q];
        mcf__graph_average(&g, tmp, 3, P);
        for (size_t q = 0; q < 3 * (size_t)nv; q++)
            P[q] = tmp[q] - P[q];
        double u[3] = {0.0, 0.0, 0.0};
        shape->direction_share = direction_share(&g, fixed, P, NOISE_TRIM, e, d, u);
        /* the noise along u: (I - Avg)^2 of s g u is s u (I - Avg)^2 g,
         * so the high-pass vectors' component along u has the variance
         * s^2 c_i (high_pass_variance); over the vertices within
         * NOISE_TRIM robust deviations of it, s^2 = sum (E_i . u)^2 /
         * sum c_i */
        double un2 = 0.0, num = 0.0, den = 0.0;
        size_t k = 0;
        for (int i = 0; i < nv; i++)
            e[i] = mcf__dot3(P + 3 * (size_t)i, u);
        double lim = NOISE_TRIM * 1.4826 * mad(&g, fixed, e, d);
        int *touched = mcf__malloc((size_t)nv, sizeof(int));
        if (!touched) {
            rc = mcf__fail(err, MCF_ENOMEM, "noise estimate: out of memory (%d vertices)", nv);
            goto done;
        }
        memset(tmp, 0, sizeof(double) * (size_t)nv);
        high_pass_variance(&g, fixed, d, tmp, touched);
        free(touched);
        for (int i = 0; i < nv; i++)
            if (g.ptr[i + 1] - g.ptr[i] >= 3 && !(fixed && fixed[i])) {
                double a = mcf__dot3(u, N + 3 * (size_t)i);
                un2 += a * a;
                k++;
                if (fabs(e[i]) <= lim) {
                    num += e[i] * e[i];
                    den += d[i];
                }
            }
        double s3 = den > 0.0 ? sqrt(num / den) : 0.0;
        un2 = k ? un2 / (double)k : 0.0;
        shape->sigma_dir = s3;
        memcpy(shape->direction, u, sizeof u);
        shape->sigma_view = s3 * sqrt(un2);
        shape->sigma_view_t = s3 * sqrt(0.5 * (1.0 - un2));
        mcf__ticked(tick, "noise", NOISE_TICK_SHAPE);
    }
    if (sigma_t) {
        /* the same for the tangential part, calibrated by unit Gaussian
         * noise in the tangent planes (two independent components) */
        double *t2 = mcf__malloc(3 * (size_t)nv, sizeof(double));
        if (!t2) {
            rc = mcf__fail(err, MCF_ENOMEM, "noise estimate: out of memory (%d vertices)", nv);
            goto done;
        }
        tangential_high_pass(&g, N, X, e, tmp, t2);
        double mt_y = mad(&g, fixed, e, d);
        mcf__gauss_fill(0x7a5eed5eULL, P, 3 * (size_t)nv);
        for (int i = 0; i < nv; i++) {
            double *z = P + 3 * (size_t)i, a = mcf__dot3(z, N + 3 * (size_t)i);
            for (int c = 0; c < 3; c++)
                z[c] = fixed && fixed[i] ? 0.0 : z[c] - a * N[3 * (size_t)i + c];
        }
        tangential_high_pass(&g, N, P, e, tmp, t2);
        double mt_n = mad(&g, fixed, e, d);
        *sigma_t = mt_n > 0.0 ? mt_y / mt_n : 0.0;
        free(t2);
    }
done:
    free(N);
    free(P);
    free(tmp);
    free(e);
    free(d);
    if (!given)
        mcf__graph_free(&g);
    return rc;
}

/* What both amounts need: the pattern, the operators at X (the run's
 * Laplacian lap and mass mk), the normals and valences, the noise level,
 * the fixed set (fixed, or massless) and the probes. */
static mcf_status auto_setup(auto_ctx *a, const double *X, const int32_t *F, int nf, int nv,
                             const unsigned char *fixed, mcf_laplacian lap, mcf_mass mk,
                             double hbar, const mcf__pattern *lent, double *s, mcf_error *err)
{
    mcf_status rc;
    memset(a, 0, sizeof *a);
    a->nv = nv;
    a->nf = nf;
    a->F = F;
    a->pat = lent;
    if (!lent && (rc = mcf__pattern_build(F, nf, nv, 1, &a->own_pat, err)) != MCF_OK)
        return rc;
    if (!lent)
        a->pat = &a->own_pat;
    a->N = mcf__malloc(3 * (size_t)nv, sizeof(double));
    a->fix = mcf__calloc((size_t)nv, 1);
    a->probe = mcf__malloc(NPROBE * (size_t)nv, sizeof(double));
    a->yn = mcf__malloc((size_t)nv, sizeof(double));
    a->mass = mcf__malloc((size_t)nv, sizeof(double));
    a->lval = mcf__malloc((size_t)a->pat->nnz, sizeof(double));
    double *w = mcf__malloc(3 * (size_t)nf, sizeof(double)), *area = mcf__malloc((size_t)nf, sizeof(double));
    if (!a->N || !a->fix || !a->probe || !a->yn || !a->mass || !a->lval || !w || !area) {
        free(w);
        free(area);
        return mcf__fail(err, MCF_ENOMEM, "automatic amount: out of memory (%d vertices)", nv);
    }
    mcf__cot_weights(X, F, nf, lap, MCF_MOLLIFY * hbar, w, area);
    mcf__mass(X, F, nf, nv, mk, area, a->mass);
    mcf__pattern_fill_L(a->pat, F, nf, w, a->lval);
    free(w);
    free(area);
    mcf__vertex_normals(X, F, nf, nv, a->N);
    for (int i = 0; i < nv; i++) {
        a->fix[i] = (fixed && fixed[i]) || !(a->mass[i] > 0.0);
        a->nfree += !a->fix[i];
        a->yn[i] = mcf__dot3(a->N + 3 * (size_t)i, X + 3 * (size_t)i);
    }
    if ((rc = mcf__noise_level(X, F, nf, nv, a->fix, s, err)) != MCF_OK)
        return rc;
    /* Rademacher probes, deterministic, on the free vertices */
    for (size_t i = 0; i < NPROBE * (size_t)nv; i++)
        a->probe[i] = a->fix[i % (size_t)nv] ? 0.0
                      : (mcf__mix64(i + 0x9e3779b97f4a7c15ULL) >> 63) ? 1.0 : -1.0;
    return MCF_OK;
}

/* SURE of a smoothed state: P holds the positions (column-major nv x 3
 * at stride ld, columns 0-2) and S applied to the probes (columns 3..). */
static double sure(const auto_ctx *a, const double *P, size_t ld, double s)
{
    double r2 = 0.0, tr = 0.0;
    for (int i = 0; i < a->nv; i++) {
        if (a->fix[i])
            continue;
        double ri = -a->yn[i];
        for (int c = 0; c < 3; c++)
            ri += a->N[3 * (size_t)i + c] * P[(size_t)c * ld + i];
        r2 += ri * ri;
        for (int q = 0; q < NPROBE; q++)
            tr += a->probe[(size_t)q * a->nv + i] * P[(size_t)(3 + q) * ld + i];
    }
    return r2 - s * s * a->nfree + 2.0 * s * s * tr / NPROBE;
}

/* The minimum of risk[0..n) and its position refined by the parabola
 * through it and its neighbours (x = index). */
static double argmin_refined(const double *risk, int n)
{
    int kb = 0;
    for (int k = 1; k < n; k++)
        if (risk[k] < risk[kb])
            kb = k;
    if (kb == 0 || kb == n - 1)
        return kb;
    double y0 = risk[kb - 1], y1 = risk[kb], y2 = risk[kb + 1];
    double curv = y0 - 2.0 * y1 + y2;
    if (!(curv > 0.0))
        return kb;
    double x = kb + 0.5 * (y0 - y2) / curv;
    return x > kb - 1 && x < kb + 1 ? x : kb;
}

/* h lambda where k implicit Euler steps of h halve a mode (x > 0 steps,
 * real-valued for the refined minimum): x (2^(1/x) - 1). */
static double half_gain(double x)
{
    return x * expm1(log(2.0) / x);
}

#define MAX_CANDIDATES 24 /* 4 x 6 */
/* The area of the faces F over positions P held column-major (nv x 3). */
static double positions_area(const double *P, int nv, const int32_t *F, int nf)
{
    double A = 0.0;
    for (int f = 0; f < nf; f++) {
        double p[3][3], e1[3], e2[3], c[3];
        for (int q = 0; q < 3; q++)
            for (int d = 0; d < 3; d++)
                p[q][d] = P[(size_t)d * nv + F[3 * f + q]];
        mcf__sub3(p[1], p[0], e1);
        mcf__sub3(p[2], p[0], e2);
        mcf__cross3(e1, e2, c);
        A += 0.5 * sqrt(mcf__dot3(c, c));
    }
    return A;
}

mcf_status mcf__auto_time(const double *X, const int32_t *F, int nf, int nv, const unsigned char *fixed,
                          mcf_laplacian lap, mcf_mass mk, int moving_mass, double hbar, int K,
                          mcf__chol *lend, double *t_best, double *sigma, mcf_error *err)
{
    auto_ctx a;
    mcf_status rc = MCF_OK;
    double risk[MAX_CANDIDATES + 1], aratio[MAX_CANDIDATES + 1]; /* area over the input's */
    double *cpl = NULL, s;
    if ((rc = auto_setup(&a, X, F, nf, nv, fixed, lap, mk, hbar, lend ? mcf__chol_pattern(lend) : NULL, &s, err)) != MCF_OK)
        goto done;
    *sigma = s;
    const double *mass = a.mass, *lval = a.lval;
    if (!(cpl = mcf__calloc(3 * (size_t)nv, sizeof(double)))) {
        rc = mcf__fail(err, MCF_ENOMEM, "automatic amount: out of memory (%d vertices)", nv);
        goto done;
    }

    /* the prior: strength 0.8 rho + 0.25 mean edges, in Kc steps */
    int Kc = K < 6 ? K : 6;
    double str0 = 0.8 * s / hbar + 0.25, h0 = str0 * str0 * hbar * hbar / Kc;

    /* the run's solver when it lends it (its pattern is this one: one
     * symbolic analysis serves both), else our own */
    mcf__chol *ch = lend ? lend : (a.own_ch = mcf__chol_new(a.pat, NCOL, err));
    a.ax = mcf__malloc((size_t)a.pat->nnz, sizeof(double));
    a.B = mcf__malloc(NCOL * (size_t)nv, sizeof(double));
    if (!ch || !a.ax || !a.B) {
        rc = mcf__fail(err, MCF_ENOMEM, "automatic amount: out of memory (%d vertices)", nv);
        goto done;
    }
    /* M + h0 L; a fixed vertex's row and column become the identity and
     * its couplings -h0 L_ij x_j move to the free rows' right-hand side
     * (cpl), as the run's Dirichlet rows do */
    double *ax = a.ax;
    for (int j = 0; j < nv; j++)
        for (int t = a.pat->colptr[j]; t < a.pat->colptr[j + 1]; t++) {
            int i = a.pat->rowind[t];
            ax[t] = h0 * lval[t];
            if (i == j) {
                ax[t] = a.fix[j] ? 1.0 : ax[t] + mass[j];
            } else if (a.fix[i] || a.fix[j]) {
                int fr = a.fix[i] ? j : i, fx = a.fix[i] ? i : j;
                if (!a.fix[fr])
                    for (int c = 0; c < 3; c++)
                        cpl[3 * (size_t)fr + c] -= ax[t] * X[3 * (size_t)fx + c];
                ax[t] = 0.0;
            }
        }
    if ((rc = mcf__chol_analyze(ch, err)) != MCF_OK || (rc = mcf__chol_factorize(ch, ax, err)) != MCF_OK)
        goto done;
    /* the state: positions (0-2) and probes (3..), column-major */
    double *b = a.B;
    for (int i = 0; i < nv; i++) {
        for (int c = 0; c < 3; c++)
            b[(size_t)c * nv + i] = X[3 * (size_t)i + c];
        for (int q = 0; q < NPROBE; q++)
            b[(size_t)(3 + q) * nv + i] = a.probe[(size_t)q * nv + i];
    }
    risk[0] = sure(&a, b, (size_t)nv, s); /* k = 0: S = I */
    double A0 = positions_area(b, nv, F, nf);
    aratio[0] = 1.0;
    int n = 1, kb = 0;
    int kmax = 4 * Kc;
    for (int k = 1; k <= kmax; k++) {
        for (int i = 0; i < nv; i++) {
            if (a.fix[i])
                continue; /* positions keep X, probes 0 */
            for (int c = 0; c < NCOL; c++)
                b[(size_t)c * nv + i] *= mass[i];
            for (int c = 0; c < 3; c++)
                b[(size_t)c * nv + i] += cpl[3 * (size_t)i + c];
        }
        mcf__chol_solve(ch, NCOL, b, 1, (size_t)nv, b, NULL); /* 4 columns: no failure */
        risk[n++] = sure(&a, b, (size_t)nv, s);
        aratio[k] = positions_area(b, nv, F, nf) / A0;
        if (risk[k] < risk[kb])
            kb = k;
        if (k >= kb + 3)
            break;
    }
    /* candidate x (steps of h0) as the run's time: the K-step filter that
     * halves the same frequency */
    double x = argmin_refined(risk, n);
    *t_best = x > 0.0 ? x * h0 * half_gain(K) / half_gain(x) : 0.0;
    /* the run's mass follows the area (see above): its time is the frozen
     * model's over the area ratio of the frozen result at x */
    if (moving_mass) {
        int k0 = (int)x;
        double fr = x - k0, ar = k0 + 1 < n ? (1.0 - fr) * aratio[k0] + fr * aratio[k0 + 1] : aratio[k0];
        *t_best *= ar;
    }
done:
    free(cpl);
    auto_free(&a);
    return rc;
}

/* One frozen Taubin half pass on the NCOL columns of P (column-major nv x
 * NCOL): P_i += coef / D_i sum_j w_ij (P_j - P_i) on the free vertices;
 * U (nv x NCOL) is scratch. val: L's upper values, D its diagonal. */
static void taubin_half(const auto_ctx *a, const double *val, const double *D, double coef,
                        double *P, double *U)
{
    const mcf__pattern *p = a->pat;
    int nv = a->nv;
    memset(U, 0, sizeof(double) * NCOL * (size_t)nv);
    for (int j = 0; j < nv; j++)
        for (int t = p->colptr[j]; t < p->colptr[j + 1]; t++) {
            int i = p->rowind[t];
            if (i == j)
                continue;
            double wij = -val[t]; /* L_ij = -w_ij */
            for (int c = 0; c < NCOL; c++) {
                double d = P[(size_t)c * nv + j] - P[(size_t)c * nv + i];
                U[(size_t)c * nv + i] += wij * d;
                U[(size_t)c * nv + j] -= wij * d;
            }
        }
    for (int i = 0; i < nv; i++)
        if (!a->fix[i] && D[i] != 0.0)
            for (int c = 0; c < NCOL; c++)
                P[(size_t)c * nv + i] += coef / D[i] * U[(size_t)c * nv + i];
}

mcf_status mcf__auto_passes(const double *X, const int32_t *F, int nf, int nv, const unsigned char *fixed,
                            mcf_laplacian lap, double hbar, int *passes, double *sigma, mcf_error *err)
{
    static const double coef[2] = {0.5, -0.53}; /* step_taubin's */
    auto_ctx a;
    mcf_status rc = MCF_OK;
    double *risk = mcf__malloc(MCF_AUTO_MAX_PASSES + 1, sizeof(double)), *D = NULL, s;
    double *P = mcf__malloc(NCOL * (size_t)nv, sizeof(double)), *U = mcf__malloc(NCOL * (size_t)nv, sizeof(double));
    memset(&a, 0, sizeof a);
    if (!risk || !P || !U || !(D = mcf__calloc((size_t)nv, sizeof(double)))) {
        rc = mcf__fail(err, MCF_ENOMEM, "automatic passes: out of memory (%d vertices)", nv);
        goto done;
    }
    if ((rc = auto_setup(&a, X, F, nf, nv, fixed, lap, MCF_MASS_BARYCENTRIC, hbar, NULL, &s, err)) != MCF_OK)
        goto done;
    *sigma = s;
    const double *val = a.lval;
    for (int j = 0; j < nv; j++)
        D[j] = val[a.pat->diag[j]];
    for (int i = 0; i < nv; i++) {
        for (int c = 0; c < 3; c++)
            P[(size_t)c * nv + i] = X[3 * (size_t)i + c];
        for (int q = 0; q < NPROBE; q++)
            P[(size_t)(3 + q) * nv + i] = a.probe[(size_t)q * nv + i];
    }
    risk[0] = sure(&a, P, (size_t)nv, s);
    int kb = 0, n = 1;
    for (int k = 1; k <= MCF_AUTO_MAX_PASSES; k++) {
        taubin_half(&a, val, D, coef[0], P, U);
        taubin_half(&a, val, D, coef[1], P, U);
        risk[n++] = sure(&a, P, (size_t)nv, s);
        if (risk[k] < risk[kb])
            kb = k;
        if (k >= 2 * kb + 10)
            break;
    }
    *passes = kb;
done:
    free(risk);
    free(D);
    free(P);
    free(U);
    auto_free(&a);
    return rc;
}
