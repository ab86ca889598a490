/* SPDX-License-Identifier: MIT */
/*
 * mcf_fairing_sure.c - Stein's unbiased risk estimate for the fairing
 * filter (docs/fairing.md, "The amount"): the probes' traces, SURE of a
 * step and its gain's standard error, the combination of the kept
 * iterates, and the default's pick between the implicit steps and the
 * explicit passes. The run's state: mcf_fairing_ctx.h.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_fairing_ctx.h"

/* SURE is unbiased for fixed weights; weights fitted to it on the same
 * data see it low by about 2 s^2 per weight (in sum w units, as for a
 * least-squares fit of COMB_J parameters): charged before the comparison
 * with the best single step, a few percent of the risk on a 300-vertex
 * mesh, nothing on a scan */
#define COMB_PENALTY 2.0
/* The combination's gain 1 + sum_j c_j (g(k)^kj - 1) on the spectrum
 * k in [0, 2] stays within [COMB_GAIN_MIN, COMB_GAIN_MAX]: a denoiser
 * does not amplify, nor turn a frequency over by more than half. The
 * combinations SURE chose on the shared scans (numpy, noise 0.1 and
 * 0.25) stay within -0.22 .. 1.015; a clean sphere told noise 0.5
 * (strength 0.5: SURE's model wrong, the iterates nearly equal) got
 * weights of +-250,000, a gain of -32,575 .. 6,893, and vertices moved by
 * 0.16 of its radius (0.01 at K*) */
#define COMB_GAIN_MIN (-0.5)
#define COMB_GAIN_MAX 1.1
/* The explicit passes replace the implicit steps (pick_explicit) when
 * SURE's gain over them is at least PICK_MIN_GAIN of its standard error:
 * both results already passed SURE_MIN_GAIN against the input, so a
 * wrong pick trades one denoised result for another rather than harming
 * the mesh; one standard error (one-sided, 84%) bounds the pick's
 * selection bias (a minimum of two estimates reads low by at most 0.4 of
 * the difference's standard error) to what the gain shows. The error is
 * mostly the noise level's (s2_rel: 0.21 on 250 vertices); the even
 * coarse torus of test_coarse_torus_taubin at noise 0.25, seed 1, gains
 * 1.37 standard errors: 2 kept the implicit steps, 1.24x the uniform
 * Taubin oracle. */
#define PICK_MIN_GAIN 1.0
/* The run with no creases held replaces the one that held them
 * (mcf__fair_pick_uncreased) when SURE's gain is at least
 * UNCREASE_MIN_GAIN of its standard error: as above a choice between two
 * denoised results, and half an error still covers the minimum's
 * selection bias (0.4 of an error at most). Measured (make quality's
 * noise, seed 1): bunny_npm_closed.obj's false creases gain 0.76-0.98
 * standard errors at 0.1-0.5 h, which one error kept (1.04-1.09x the
 * error without them); the box of test_creases_kept loses 1.9-8
 * standard errors at 0.1-0.5 (seed 2). */
#define UNCREASE_MIN_GAIN 0.5
/* The default request runs the feature-aware stage before the run with no
 * creases held and makes that run only when the stage was not taken
 * (mcf_fairing.c): against the result with its creases held, the stage
 * must gain FEATURE_HELD_GAIN standard errors, PICK_MIN_GAIN plus the
 * most its z fell from that opponent to the run with none held, where
 * both were measured (make quality's noise, seed 1, 2026-11-29, the
 * CAD parts the stage's gate opens on: 4.0 on blade.obj normal 0.25,
 * 1.31 -> -2.67; 0.5-3.4 on seven others; it rose on two). Taken at
 * 1.31 and 1.87 (blade.obj normal 0.25, 0.5 h), the stage returned 0.225
 * and 0.296 of the input's error where the run with none held gives
 * 0.150 and 0.213; of the cases the stage took after that run, the
 * least z against the held result was 5.72 (couplingdown_sub2.obj normal
 * 0.25 h; docs/fairing.md, "Creases"). */
#define FEATURE_HELD_GAIN 5.0

/* The mean of the nprobe probes' estimates est, and the variance of that
 * mean (*var). */
double mcf__fair_mean_trace(const double *est, int nprobe, double *var)
{
    double tr = 0.0, v = 0.0;
    for (int q = 0; q < nprobe; q++)
        tr += est[q] / nprobe;
    for (int q = 0; q < nprobe; q++)
        v += (est[q] - tr) * (est[q] - tr);
    *var = v / ((nprobe - 1) * nprobe);
    return tr;
}

/* A step's figures for SURE in one sweep over the free vertices (each
 * sum in the vertices' order, as separate sweeps would add them):
 * est[q], probe q's estimate of sum_i w_i (T^K)_ii; and the moments of
 * the displacement Y - X0, r along n0 and t its part in the tangent
 * planes of n0: m[0] = sum_F w r^2, m[1] = sum w^2 r^2, m[2] = sum w^2
 * r^4, and m[3..5] the same of |t|. The explicit engine's positions
 * are read off Z and written into Y's free rows in the same sweep (its
 * fixed rows are X0's already: run_init); the implicit engine's are in Y
 * (positions()). The sums live in locals, NP (the
 * probes) a constant of the compiler: written through est and m, each
 * addition waited for a store and a reload (perf: 14.5% of the 435k
 * dragon's default request); the same additions in the same order, the
 * same numbers bit for bit. */
static inline __attribute__((always_inline)) void step_moments(const fair_ctx *c, double *Y,
                                                               double est[NPROBE], double m[6], const int NP)
{
    double e[NPROBE] = {0}, m0 = 0.0, m1 = 0.0, m2 = 0.0, m3 = 0.0, m4 = 0.0, m5 = 0.0;
    const double *probe = c->probe, *w = c->w, *X0 = c->X0, *n0 = c->n0;
    const double *Z = c->Z, *Yc = c->Yc;
    const int *vert = c->vert;
    size_t nfree = (size_t)c->nfree, nc = (size_t)c->ncol;
    int is_explicit = c->is_explicit;
    for (size_t k = 0; k < nfree; k++) {
        size_t i = (size_t)vert[k];
        double wi = w[i];
        for (int q = 0; q < NP; q++) {
            double z = probe[(size_t)q * nfree + k];
            double y = is_explicit ? Z[nc * i + 3 + (size_t)q] : Yc[(size_t)(3 + q) * nfree + k];
            e[q] += wi * z * y;
        }
        if (is_explicit)
            memcpy(Y + 3 * i, Z + nc * i, 3 * sizeof(double));
        double d[3];
        mcf__sub3(Y + 3 * i, X0 + 3 * i, d);
        double r = mcf__dot3(n0 + 3 * i, d), r2 = r * r, t2 = mcf__dot3(d, d) - r2;
        t2 = t2 > 0.0 ? t2 : 0.0; /* fmax(0, t2): the same for every t2, NaN included */
        m0 += wi * r2;
        m1 += wi * wi * r2;
        m2 += wi * wi * r2 * r2;
        m3 += wi * t2;
        m4 += wi * wi * t2;
        m5 += wi * wi * t2 * t2;
    }
    for (int q = 0; q < NPROBE; q++)
        est[q] = e[q];
    m[0] = m0;
    m[1] = m1;
    m[2] = m2;
    m[3] = m3;
    m[4] = m4;
    m[5] = m5;
}

/* c->nprobe is NPROBE_FEW or NPROBE (mcf_fairing.c, run_init); the
 * implicit engine's probes, and the explicit one's after the implicit run,
 * are not columns (mcf__fair_lz_trace) */
void mcf__fair_step_moments(const fair_ctx *c, double *Y, double est[NPROBE], double m[6])
{
    if (c->ncol == 3)
        step_moments(c, Y, est, m, 0);
    else if (c->nprobe == NPROBE_FEW)
        step_moments(c, Y, est, m, NPROBE_FEW);
    else
        step_moments(c, Y, est, m, NPROBE);
}

/* The variance of a SURE gain (over the input, or of one result over
 * another: the same input, weights and probes) with v the noise variance
 * it is scaled by: the gain is a sum over the n free vertices of terms
 * with sum sd and sum of squares sd2, whose spread is taken as that of n
 * independent terms; the traces' difference dtr enters with 2 v (the
 * probes' variance vtr); and the gain grows with v as 2 dtr, v being
 * estimated with a relative standard error c->s2_rel. */
static double gain_var(const fair_ctx *c, double v, int n, double sd, double sd2, double dtr,
                       double vtr)
{
    double ds = 2.0 * dtr * v * c->s2_rel;
    double spread = n > 1 ? fmax(0.0, sd2 - sd * sd / n) * n / (n - 1.0) : 0.0;
    return spread + (4.0 * v * v * vtr + ds * ds);
}

/* SURE(K) for dim directions of noise level sig (1 along the normals, 2
 * in the tangent planes) from the moments mo (sum w rho^2, sum w^2 rho^2,
 * sum w^2 rho^4) and the trace tr (its probe variance vtr). *z gets the
 * gain over SURE(0) = dim sig^2 sum w in its standard errors (gain_var):
 * the gain is a sum over the free vertices of d_i = w_i (2 dim sig^2 (1 -
 * tr / sum w) - rho_i^2), and the traces' difference is sum w - tr. */
double mcf__fair_sure_of(const fair_ctx *c, int dim, double sig, const double *mo, double tr, double vtr,
                      double *z)
{
    double sw = (double)c->nfree, v = dim * sig * sig;
    double risk = mo[0] - v * sw + 2.0 * v * tr, gain = v * sw - risk;
    double cc = 2.0 * v * (1.0 - tr / sw);
    double sd2 = cc * cc * c->sumw2 - 2.0 * cc * mo[1] + mo[2]; /* sum d_i^2 */
    double var = gain_var(c, v, c->nfree, gain, sd2, sw - tr, vtr);
    *z = var > 0.0 ? gain / sqrt(var) : (gain > 0.0 ? INFINITY : 0.0);
    return risk;
}

/* Keeps Y - X0 on the free vertices after k steps, with the probes'
 * traces est, as the newest of the last COMB_J iterates (the oldest's
 * buffer reused). */
void mcf__fair_keep_iterate(fair_ctx *c, int k, const double *Y, const double est[NPROBE])
{
    if (c->nk == COMB_J) {
        float *d = c->dk[0];
        memmove(c->dk, c->dk + 1, (COMB_J - 1) * sizeof c->dk[0]);
        memmove(c->kk, c->kk + 1, (COMB_J - 1) * sizeof c->kk[0]);
        memmove(c->trq, c->trq + 1, (COMB_J - 1) * sizeof c->trq[0]);
        c->dk[--c->nk] = d;
    }
    float *d = c->dk[c->nk];
    for (int q = 0; q < c->nfree; q++)
        for (int e = 0; e < 3; e++) {
            size_t i = 3 * (size_t)c->vert[q] + (size_t)e;
            d[3 * (size_t)q + (size_t)e] = (float)(Y[i] - c->X0[i]);
        }
    c->kk[c->nk] = k;
    memcpy(c->trq[c->nk], est, sizeof c->trq[0]);
    c->nk++;
}

/* r_j = n0 . (Y_kj - X0) at free vertex q for the kept iterates. */
static void kept_r(const fair_ctx *c, int q, double *r)
{
    const double *n = c->n0 + 3 * (size_t)c->vert[q];
    for (int j = 0; j < c->nk; j++) {
        const float *d = c->dk[j] + 3 * (size_t)q;
        r[j] = n[0] * d[0] + n[1] * d[1] + n[2] * d[2];
    }
}

/* Solves A x = y for the SPD J x J matrix A (row-major) by Cholesky, A
 * and y overwritten, x into y; 0 when A is not positive definite. */
static int small_spd_solve(double *A, double *y, int J)
{
    for (int j = 0; j < J; j++) {
        for (int k = 0; k < j; k++)
            A[j * J + j] -= A[j * J + k] * A[j * J + k];
        if (!(A[j * J + j] > 0.0))
            return 0;
        A[j * J + j] = sqrt(A[j * J + j]);
        for (int i = j + 1; i < J; i++) {
            for (int k = 0; k < j; k++)
                A[i * J + j] -= A[i * J + k] * A[j * J + k];
            A[i * J + j] /= A[j * J + j];
        }
    }
    for (int i = 0; i < J; i++) {
        for (int k = 0; k < i; k++)
            y[i] -= A[i * J + k] * y[k];
        y[i] /= A[i * J + i];
    }
    for (int i = J - 1; i >= 0; i--) {
        for (int k = i + 1; k < J; k++)
            y[i] -= A[k * J + i] * y[k];
        y[i] /= A[i * J + i];
    }
    return 1;
}

/* Whether the gain of the combination with weights cw stays within
 * [COMB_GAIN_MIN, COMB_GAIN_MAX] on k in [0, 2] (a grid of steps 0.01),
 * g(k) the gain of one step: 1 / (1 + k^2), or Taubin's pair's
 * (1 - 0.5 k)(1 + 0.53 k). */
static int comb_gain_ok(const fair_ctx *c, const double *cw)
{
    for (int t = 0; t <= 200; t++) {
        double k = 0.01 * t, g = c->is_explicit ? (1.0 - 0.5 * k) * (1.0 + 0.53 * k) : 1.0 / (1.0 + k * k);
        double gain = 1.0;
        for (int j = 0; j < c->nk; j++)
            gain += cw[j] * (pow(g, c->kk[j]) - 1.0);
        if (!(gain >= COMB_GAIN_MIN && gain <= COMB_GAIN_MAX))
            return 0;
    }
    return 1;
}

/* SURE's best combination of the kept iterates: with r_j = n0 . (Y_kj -
 * X0) and b_j = tr_j - sum w (the trace of T^kj - I), the displacement
 * sum_j c_j r_j has SURE(c) = sum w (sum_j c_j r_j)^2 - s^2 sum w + 2 s^2
 * (sum w + sum_j c_j b_j), least at G c = -s^2 b, G_jl = sum w r_j r_l
 * (a ridge of 1e-9 of G's mean diagonal keeps iterates that coincide
 * solvable). It replaces c->Ybest when its gain stays within bounds
 * (comb_gain_ok), its SURE plus COMB_PENALTY s^2 per weight is below the
 * best single step's and its gain over the input
 * passes SURE_MIN_GAIN (sure_of, the probes' spread of sum_j c_j tr_j
 * included); st->ncomb reports it taken, st->comb_* the weights found. */
void mcf__fair_combine(fair_ctx *c)
{
    int J = c->nk, n = c->nfree;
    double G[COMB_J * COMB_J] = {0}, cw[COMB_J], est[NPROBE] = {0}, r[COMB_J], mo[3] = {0, 0, 0};
    double s2 = c->s * c->s, sw = (double)n, gd = 0.0, vtr, z;
    /* combinations between the kept iterates only: a run the cap
     * stopped may have its best step past the last (the box of
     * test_creases_kept at noise 0.1: K* = 200, kept 16-128, error 0.296
     * -> 0.348 of the input's with a combination of them) */
    if (J < 2 || c->kbest == 0 || c->kk[J - 1] < c->kbest)
        return;
    for (int q = 0; q < n; q++) {
        double w = c->w[c->vert[q]];
        kept_r(c, q, r);
        for (int a = 0; a < J; a++)
            for (int b = 0; b < J; b++)
                G[a * J + b] += w * r[a] * r[b];
    }
    for (int j = 0; j < J; j++) {
        gd += G[j * J + j] / J;
        cw[j] = -s2 * (mcf__fair_mean_trace(c->trq[j], c->nprobe, &vtr) - sw);
    }
    for (int j = 0; j < J; j++)
        G[j * J + j] += 1e-9 * gd;
    if (!(gd > 0.0) || !small_spd_solve(G, cw, J))
        return;
    for (int j = 0; j < J; j++) { /* the weights found, taken or not */
        c->st->comb_steps[j] = c->kk[j];
        c->st->comb_weight[j] = cw[j];
    }
    if (!comb_gain_ok(c, cw))
        return;
    for (int q = 0; q < c->nprobe; q++) {
        est[q] = sw; /* the identity's: sum w z^2 = sum w */
        for (int j = 0; j < J; j++)
            est[q] += cw[j] * (c->trq[j][q] - sw);
    }
    /* the gain over the best single step, sum of the free vertices'
     * w (r*^2 - rho^2) and 2 s^2 (tr* - tr): moments of the first (dd),
     * the probes' estimates of the second (est) */
    double dd[2] = {0.0, 0.0};
    for (int q = 0; q < n; q++) {
        size_t i = (size_t)c->vert[q];
        double w = c->w[i], rho = 0.0, d[3];
        kept_r(c, q, r);
        for (int j = 0; j < J; j++)
            rho += cw[j] * r[j];
        mcf__sub3(c->Ybest + 3 * i, c->X0 + 3 * i, d);
        double rs = mcf__dot3(c->n0 + 3 * i, d), t = w * (rs * rs - rho * rho);
        dd[0] += t;
        dd[1] += t * t;
        mo[0] += w * rho * rho;
        mo[1] += w * w * rho * rho;
        mo[2] += w * w * rho * rho * rho * rho;
    }
    double tr = mcf__fair_mean_trace(est, c->nprobe, &vtr), risk = mcf__fair_sure_of(c, 1, c->s, mo, tr, vtr, &z), tr_comb[NPROBE];
    memcpy(tr_comb, est, sizeof est);
    for (int q = 0; q < c->nprobe; q++)
        est[q] = c->trbest[q] - est[q];
    double dtr = mcf__fair_mean_trace(est, c->nprobe, &vtr), gain = c->risk - risk - COMB_PENALTY * J * s2;
    double var = gain_var(c, s2, n, dd[0], dd[1], dtr, vtr);
    if (!(gain > 0.0) || gain * gain < SURE_MIN_GAIN * SURE_MIN_GAIN * var || !(z >= SURE_MIN_GAIN))
        return;
    memcpy(c->Ybest, c->X0, 3 * sizeof(double) * (size_t)c->nv);
    for (int q = 0; q < n; q++)
        for (int j = 0; j < J; j++)
            for (int e = 0; e < 3; e++)
                c->Ybest[3 * (size_t)c->vert[q] + (size_t)e] += cw[j] * c->dk[j][3 * (size_t)q + (size_t)e];
    c->st->ncomb = J;
    /* the result's SURE (its penalty charged) and traces, for the
     * choice between the filters (pick_explicit) */
    c->risk = risk + COMB_PENALTY * J * s2;
    memcpy(c->trbest, tr_comb, sizeof tr_comb);
}

/* Whether the explicit run e replaces the implicit run i (same input,
 * noise level, weights and probes): SURE's gain of e over i must pass
 * PICK_MIN_GAIN of its standard error, from the sum over the free
 * vertices of w (r_i^2 - r_e^2) (spread of n independent terms), 2 s^2
 * (tr_i - tr_e) (the probes' spread of the difference) and the noise
 * level's uncertainty. */
int mcf__fair_pick_explicit(const fair_ctx *i, const fair_ctx *e)
{
    if (e->kbest == 0 || i->nfree != e->nfree || i->nprobe != e->nprobe)
        return 0;
    if (i->kbest == 0)
        return 1; /* the implicit filter found nothing to remove */
    double s2 = i->s * i->s, dd[2] = {0.0, 0.0}, est[NPROBE], vtr;
    int n = i->nfree;
    for (int q = 0; q < n; q++) {
        size_t v = (size_t)i->vert[q];
        double a[3], b[3];
        mcf__sub3(i->Ybest + 3 * v, i->X0 + 3 * v, a);
        mcf__sub3(e->Ybest + 3 * v, e->X0 + 3 * v, b);
        double ra = mcf__dot3(i->n0 + 3 * v, a), rb = mcf__dot3(e->n0 + 3 * v, b);
        double t = i->w[v] * (ra * ra - rb * rb);
        dd[0] += t;
        dd[1] += t * t;
    }
    for (int q = 0; q < i->nprobe; q++)
        est[q] = i->trbest[q] - e->trbest[q];
    double dtr = mcf__fair_mean_trace(est, i->nprobe, &vtr), gain = i->risk - e->risk;
    double var = gain_var(i, s2, n, dd[0], dd[1], dtr, vtr);
    return gain > 0.0 && gain * gain >= PICK_MIN_GAIN * PICK_MIN_GAIN * var;
}

int mcf__fair_pick_uncreased(const fair_ctx *c, const fair_ctx *n, const double kdiv[NPROBE], double *z)
{
    if (z)
        *z = NAN;
    if (n->kbest == 0 || n->nprobe != c->nprobe || !(c->s > 0.0) || c->nfree == 0)
        return 0;
    /* c's weights are the areas over their mean on its own free vertices,
     * n's over n's: one factor apart (ratio), on every vertex c moves */
    double s2 = c->s * c->s, ratio = 0.0, dd[2] = {0.0, 0.0}, vk;
    double kept = 2.0 * s2 * mcf__fair_mean_trace(kdiv, c->nprobe, &vk); /* the crease vertices' 2 s^2 div */
    for (int q = 0; q < c->nfree; q++)
        ratio += n->w[c->vert[q]];
    ratio /= c->nfree;
    for (int q = 0; q < n->nfree; q++) {
        size_t v = (size_t)n->vert[q];
        double a[3], b[3], w = n->w[v];
        /* both displacements from the same input, along its normals */
        mcf__sub3(c->Ybest + 3 * v, n->X0 + 3 * v, a);
        mcf__sub3(n->Ybest + 3 * v, n->X0 + 3 * v, b);
        double ra = mcf__dot3(n->n0 + 3 * v, a), rb = mcf__dot3(n->n0 + 3 * v, b);
        double t = w * (ra * ra - rb * rb);
        if (c->fid[v] < 0) { /* a crease vertex of c: r^2 - s^2 (+ 2 s^2 div, below) */
            t -= w * s2;
            kept += w * (ra * ra - s2);
        }
        dd[0] += t;
        dd[1] += t * t;
    }
    /* the traces' difference per probe (the probes agree on the vertices
     * both runs move, and n's on c's crease vertices are kdiv's) */
    double est[NPROBE], vtr;
    for (int q = 0; q < c->nprobe; q++)
        est[q] = c->trbest[q] * ratio + kdiv[q] - n->trbest[q];
    double dtr = mcf__fair_mean_trace(est, c->nprobe, &vtr), gain = c->risk * ratio + kept - n->risk;
    double var = gain_var(n, s2, n->nfree, dd[0], dd[1], dtr, vtr);
    if (z && var > 0.0)
        *z = gain / sqrt(var);
    return gain > 0.0 && gain * gain >= UNCREASE_MIN_GAIN * UNCREASE_MIN_GAIN * var;
}

mcf_status mcf__fair_feature(fair_ctx *c, int vs, const unsigned char *fixed, double *X, int *taken, mcf_error *err)
{
    mcf_flow_stats *st = c->st;
    mcf__feature_frame fr;
    mcf__feature_pick pk;
    double h2 = c->hbar * c->hbar, s2 = c->s * c->s;
    double *Yf = mcf__malloc(3 * (size_t)c->nv + 1, sizeof(double));
    *taken = 0;
    if (!Yf)
        return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d vertices)", c->nv);
    memset(&fr, 0, sizeof fr);
    fr.nfree = c->nfree;
    fr.vert = c->vert;
    fr.w = c->w;
    fr.probe = c->probe;
    fr.nprobe = c->nprobe;
    fr.s = c->s;
    fr.s2_rel = c->s2_rel;
    fr.s_known = c->grid[0] > 0.0;
    fr.min_z = SURE_MIN_GAIN;
    if (vs != FEAT_VS_INPUT && c->kbest > 0) {
        fr.Ylin = c->Ybest;
        fr.X0 = c->X0;
        fr.trlin = c->trbest;
        fr.lin_penalty = st->ncomb > 0 ? COMB_PENALTY * st->ncomb * s2 : 0.0;
        fr.min_z = vs == FEAT_VS_HELD ? FEATURE_HELD_GAIN : PICK_MIN_GAIN;
    }
    mcf_status rc = mcf__feature(c->Xin, c->F, c->nf, c->nv, fixed, &fr, Yf, &pk, err);
    if (rc == MCF_OK) {
        c->bytes += pk.bytes + 3 * sizeof(double) * (size_t)c->nv;
        st->feature_ran = 1;
        st->feature_sigma_r = pk.sigma_r;
        st->feature_normal_iters = pk.normal_iters;
        st->feature_vertex_iters = pk.vertex_iters;
        st->feature_sure = h2 > 0.0 ? pk.risk / h2 : 0.0;
        st->feature_sure_against = h2 > 0.0 ? pk.risk_lin / h2 : 0.0;
        st->feature_z = isfinite(pk.z) ? pk.z : 1e300;
        st->feature_noise = c->hbar > 0.0 ? pk.s / c->hbar : 0.0;
        if (pk.won) {
            *taken = st->feature = 1;
            rc = mcf__fair_feature_output(c, Yf, fixed, pk.s, X, err);
        }
    }
    free(Yf);
    return rc;
}
