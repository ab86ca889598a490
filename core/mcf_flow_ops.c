/* SPDX-License-Identifier: MIT */
/*
 * mcf_flow_ops.c - the operators and linear solves of one MCF run, and the
 * checks a step is judged by.
 *
 * Linear systems: every implicit scheme solves (c M + s L) Y = B for three
 * right-hand-side columns, where M and L are evaluated at some
 * configuration. The sparsity pattern never changes during a job, so
 * cholmod_analyze runs once (mcf_cholesky.c); each step refills the values
 * (a scatter over the faces, no triplets, no sort), refactorizes
 * numerically and solves. Fixed vertices (fixed boundary, the user's list,
 * vertices no face uses) are Dirichlet rows: their row and column become
 * the identity and their couplings move to the right-hand side, which
 * keeps the system SPD.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_flow_ctx.h"

double *mcf__flow_alloc(flow_ctx *c, size_t n)
{
    double *v = mcf__calloc(n, sizeof(double));
    if (v)
        c->bytes += n * sizeof(double);
    return v;
}

/* Weights, areas and masses of configuration X into (w, area, mass). */
void mcf__flow_ops_at(flow_ctx *c, const double *X, double *w, double *area, double *mass)
{
    double t0 = mcf_now();
    mcf__cot_weights(X, c->F, c->nf, c->p->laplacian, c->delta, w, area);
    mcf__mass(X, c->F, c->nf, c->nv, c->p->mass, area, mass);
    c->st->time_assemble += mcf_now() - t0;
}

/* V *= -M^-1, zero on fixed vertices. */
static void scale_velocity(flow_ctx *c, const double *mass, double *V)
{
    for (int i = 0; i < c->nv; i++) {
        double s = c->fixed[i] ? 0.0 : -1.0 / mass[i];
        V[3 * i] *= s; V[3 * i + 1] *= s; V[3 * i + 2] *= s;
    }
}

/* V = -M^-1 L X (zero on fixed vertices), from weights w and mass. */
void mcf__flow_velocity(flow_ctx *c, const double *w, const double *mass, const double *X, double *V)
{
    mcf__apply_L(c->F, c->nf, c->nv, w, X, V);
    scale_velocity(c, mass, V);
}

/* Operators at X (c->mass, c->area_sum; c->w and c->area when keep_w or
 * when the mass is not barycentric) and Y = L X: with the barycentric
 * mass in one pass over the faces, which is most of an explicit step. */
void mcf__flow_LX(flow_ctx *c, const double *X, int keep_w, double *Y)
{
    if (c->p->mass != MCF_MASS_BARYCENTRIC) {
        mcf__flow_ops_at(c, X, c->w, c->area, c->mass);
        mcf__apply_L(c->F, c->nf, c->nv, c->w, X, Y);
        c->area_sum = 0.0;
        for (int f = 0; f < c->nf; f++)
            c->area_sum += c->area[f];
        return;
    }
    double t0 = mcf_now();
    c->area_sum = mcf__weights_mass_LX(X, c->F, c->nf, c->nv, c->p->laplacian, c->delta,
                                       keep_w ? c->w : NULL, keep_w ? c->area : NULL, c->mass, Y);
    c->st->time_assemble += mcf_now() - t0;
}

/* ops_LX keeping the weights, and V = -M^-1 L X. */
void mcf__flow_ops_velocity(flow_ctx *c, const double *X, double *V)
{
    mcf__flow_LX(c, X, 1, V);
    scale_velocity(c, c->mass, V);
}

/* Y = M X row-wise. */
void mcf__flow_mul_mass(int nv, const double *mass, const double *X, double *Y)
{
    for (int i = 0; i < nv; i++) {
        Y[3 * i] = mass[i] * X[3 * i];
        Y[3 * i + 1] = mass[i] * X[3 * i + 1];
        Y[3 * i + 2] = mass[i] * X[3 * i + 2];
    }
}

mcf_status mcf__flow_solver_init(flow_ctx *c, mcf_error *err)
{
    /* entries to zero for Dirichlet rows */
    c->zero_idx = mcf__malloc((size_t)c->pat.nnz, sizeof(int));
    c->zero_col = mcf__malloc((size_t)c->pat.nnz, sizeof(int));
    if (!c->zero_idx || !c->zero_col)
        return mcf__fail(err, MCF_ENOMEM, "solver: out of memory");
    for (int j = 0; j < c->nv; j++)
        for (int t = c->pat.colptr[j]; t < c->pat.colptr[j + 1]; t++) {
            int i = c->pat.rowind[t];
            if (i != j && (c->fixed[i] || c->fixed[j])) {
                c->zero_col[c->nzero] = j;
                c->zero_idx[c->nzero++] = t;
            }
        }
    c->Ax = mcf__malloc((size_t)c->pat.nnz, sizeof(double));
    if (!c->Ax)
        return mcf__fail(err, MCF_ENOMEM, "solver: out of memory");
    c->bytes += sizeof(double) * (size_t)c->pat.nnz;
    /* four columns: the automatic amount's, which borrows the solver */
    if (!(c->chol = mcf__chol_new(&c->pat, 4, err)))
        return MCF_ENOMEM;
    return MCF_OK;
}

/* A = cm * M + cl * L(w), Dirichlet rows applied; values into c->Ax. */
void mcf__flow_system_fill(flow_ctx *c, double cmass, double cl, const double *w, const double *mass)
{
    double t0 = mcf_now();
    double *a = c->Ax;
    mcf__pattern_fill_L(&c->pat, c->F, c->nf, w, a);
    if (cl != 1.0)
        for (int t = 0; t < c->pat.nnz; t++)
            a[t] *= cl;
    for (int j = 0; j < c->nv; j++)
        a[c->pat.diag[j]] = c->fixed[j] ? 1.0 : a[c->pat.diag[j]] + cmass * mass[j];
    c->st->time_assemble += mcf_now() - t0;
}

/* Numeric factorization of c->Ax (symbolic analysis on first use). The
 * couplings to fixed vertices are zeroed here; the callers' right-hand
 * sides hold fixed values only where those are zero (velocities) or add
 * the coupling first (positions: see rhs_dirichlet). */
mcf_status mcf__flow_factorize(flow_ctx *c, mcf_error *err)
{
    double *a = c->Ax;
    mcf_status rc;
    for (int k = 0; k < c->nzero; k++)
        a[c->zero_idx[k]] = 0.0;
    if (!c->analyzed) {
        double t0 = mcf_now();
        rc = mcf__chol_analyze(c->chol, err);
        c->st->time_analyze += mcf_now() - t0;
        if (rc != MCF_OK)
            return rc;
        c->analyzed = 1;
        mcf__chol_size(c->chol, &c->st->factor_nnz, &c->st->factor_flops);
    }
    double t0 = mcf_now();
    rc = mcf__chol_factorize(c->chol, a, err);
    double dt = mcf_now() - t0;
    c->st->time_factorize += dt;
    c->step_solve_s += dt;
    c->st->factorizations++;
    c->factor_valid = rc == MCF_OK;
    return rc;
}

/* Dirichlet rows of a right-hand side. For unknowns that are positions:
 * B[free i] -= sum A_ij x_j over fixed j, B[fixed] = x_fixed; this needs
 * the couplings before mcf__flow_factorize() zeroes them. Xfix NULL: the unknowns
 * are zero on fixed vertices (velocities) and nothing moves to B. */
void mcf__flow_rhs_dirichlet(flow_ctx *c, const double *Xfix, double *B)
{
    const double *a = c->Ax;
    for (int k = 0; Xfix && k < c->nzero; k++) {
        int t = c->zero_idx[k], j = c->zero_col[k], i = c->pat.rowind[t];
        if (!c->fixed[i] && c->fixed[j])
            for (int d = 0; d < 3; d++)
                B[3 * i + d] -= a[t] * Xfix[3 * j + d];
        else if (c->fixed[i] && !c->fixed[j])
            for (int d = 0; d < 3; d++)
                B[3 * j + d] -= a[t] * Xfix[3 * i + d];
    }
    for (int i = 0; i < c->nv; i++)
        if (c->fixed[i])
            for (int d = 0; d < 3; d++)
                B[3 * i + d] = Xfix ? Xfix[3 * i + d] : 0.0;
}

/* Solves A Y = B (3 columns, row-major B and Y) with the current factor.
 * Fixed rows of B must hold the Dirichlet values already. */
mcf_status mcf__flow_solve(flow_ctx *c, const double *B, double *Y, mcf_error *err)
{
    (void)err;
    double t0 = mcf_now();
    mcf__chol_solve3(c->chol, B, Y);
    double dt = mcf_now() - t0;
    c->st->time_solve += dt;
    c->step_solve_s += dt;
    c->st->solves++;
    return MCF_OK;
}

/* One semi-implicit Euler (desbrun) step of size h from X into Y with the
 * operators (w, mass) already evaluated at X. */
mcf_status mcf__flow_be_step(flow_ctx *c, const double *X, double h, const double *w,
                          const double *mass, double *Y, mcf_error *err)
{
    mcf_status rc;
    mcf__flow_system_fill(c, 1.0, h, w, mass);
    mcf__flow_mul_mass(c->nv, mass, X, c->B);
    mcf__flow_rhs_dirichlet(c, X, c->B);
    if ((rc = mcf__flow_factorize(c, err)) != MCF_OK)
        return rc;
    return mcf__flow_solve(c, c->B, Y, err);
}

/* -------------------------------------------------------- geometry */

/* Faces a step folded (mcf__folded_faces against fn_before: turned by
 * more than 90 degrees and lying backwards in the neighbourhood). The new
 * face normals go to fn_after (the next step's "before"); N (4*nv) is
 * scratch. Faces that were degenerate before (zero normal) cannot fold. */
int mcf__flow_folded_faces(const double *X, const int32_t *F, int nf, int nv,
                           const double *fn_before, double *fn_after, double *N)
{
    return mcf__folded_faces(X, F, nf, nv, fn_before, fn_after, N, NULL);
}

int mcf__flow_all_finite(const double *X, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (!isfinite(X[i]))
            return 0;
    return 1;
}

/* M-weighted RMS of D (3*nv) over sqrt(sum m): the error norm of MATH.md
 * for unit-area meshes. */
double mcf__flow_mnorm(const flow_ctx *c, const double *D, const double *mass)
{
    double s = 0.0, ms = 0.0;
    for (int i = 0; i < c->nv; i++) {
        s += mass[i] * mcf__dot3(D + 3 * i, D + 3 * i);
        ms += mass[i];
    }
    return ms > 0.0 ? sqrt(s / ms) : 0.0;
}

/* The largest vertex's length in D (3*nv). */
double mcf__flow_maxnorm(const flow_ctx *c, const double *D)
{
    double mx = 0.0;
    for (size_t i = 0; i < (size_t)c->nv; i++)
        mx = fmax(mx, mcf__dot3(D + 3 * i, D + 3 * i));
    return sqrt(mx);
}

/* The M-norm (and the vertices' max) of W^-1 (cmass M) D, for D (3*nv, zero on fixed vertices)
 * and the current factor W = cmass M + s L (mass: the M inside W): an
 * error estimate seen through the step's own resolvent (Shampine's
 * filter, as ros2 does). A mode of L with eigenvalue lambda is scaled by
 * 1 / (1 + s lambda / cmass): smooth modes (s lambda << 1), whose local
 * errors add up to the global one, pass unchanged; stiff modes (slivers,
 * the noise), which the L-stable step damps anyway, are damped too. Raw,
 * those dominate every estimate on a scan and the controller crawls
 * (dt 1e-11 after 22k steps on an 11k-vertex head). Used by the
 * step-doubling estimates (desbrun, desbrun2's first step, richardson),
 * whose first-order companion overstates the error of stiff modes;
 * desbrun2's Milne estimate goes unfiltered (mcf__flow_step says why). One more
 * back-solve (3 columns) with the factor already at hand; D is
 * overwritten. */
mcf_status mcf__flow_filtered_mnorm(flow_ctx *c, double cmass, const double *mass, double *D,
                                 step_est *out, mcf_error *err)
{
    mcf_status rc;
    for (int i = 0; i < c->nv; i++)
        for (int d = 0; d < 3; d++)
            c->B[3 * i + d] = c->fixed[i] ? 0.0 : cmass * mass[i] * D[3 * i + d];
    if ((rc = mcf__flow_solve(c, c->B, D, err)) != MCF_OK)
        return rc;
    out->rms = mcf__flow_mnorm(c, D, mass);
    out->max = mcf__flow_maxnorm(c, D);
    return MCF_OK;
}

/* Shortest edge of positive length (0 when none). */
double mcf__flow_min_edge(const double *X, const int32_t *F, int nf)
{
    double mn = INFINITY;
    for (int f = 0; f < nf; f++)
        for (int k = 0; k < 3; k++) {
            double e[3];
            mcf__sub3(X + 3 * (size_t)F[3 * f + k], X + 3 * (size_t)F[3 * f + (k + 1) % 3], e);
            double l2 = mcf__dot3(e, e);
            if (l2 > 0.0 && l2 < mn)
                mn = l2;
        }
    return isfinite(mn) ? sqrt(mn) : 0.0;
}

/* ---------------------------------------------------------- rescale */

/* The rescaled measure (area or volume) of X with its free vertices at
 * cen + s (x - cen); the positions go to Y. */
static double scaled_measure(const flow_ctx *c, const double *cen, double s, double *Y)
{
    double V, A;
    for (int i = 0; i < c->nv; i++)
        for (int d = 0; d < 3; d++)
            Y[3 * i + d] = c->fixed[i] ? c->X[3 * i + d] : cen[d] + s * (c->X[3 * i + d] - cen[d]);
    A = mcf__area_volume(Y, c->F, c->nf, NULL, &V);
    return c->p->rescale == MCF_RESCALE_AREA ? A : V;
}

/* Restores the area or volume by scaling the free vertices about the area
 * centroid. Without fixed vertices the factor is exact in closed form;
 * fixed vertices do not scale, so the closed form misses the target (a
 * holed bunny with its boundary fixed: 1.8e-4 off in area) and the factor
 * is refined by the secant method on the measure, which is smooth and
 * increasing in s near 1 (5-8 iterations to 1e-13 relative). */
void mcf__flow_rescale(flow_ctx *c, double area0, double vol0)
{
    double cen[3];
    double V, A = mcf__area_volume(c->X, c->F, c->nf, cen, &V), s = 1.0;
    int area = c->p->rescale == MCF_RESCALE_AREA, any_fixed = 0;
    double target = area ? area0 : vol0, m0 = area ? A : V;
    if (area && A > 0.0)
        s = sqrt(area0 / A);
    else if (!area && V != 0.0 && vol0 / V > 0.0)
        s = cbrt(vol0 / V);
    if (s == 1.0)
        return;
    for (int i = 0; i < c->nv && !any_fixed; i++)
        any_fixed = c->fixed[i] != 0;
    if (any_fixed) {
        double s0 = 1.0, g0 = m0 - target, s1 = s;
        double g1 = scaled_measure(c, cen, s1, c->V2) - target;
        for (int it = 0; it < 30 && fabs(g1) > 1e-13 * fabs(target) && g1 != g0; it++) {
            double s2 = s1 - g1 * (s1 - s0) / (g1 - g0);
            if (!isfinite(s2) || !(s2 > 0.0))
                break;
            s0 = s1;
            g0 = g1;
            s1 = s2;
            g1 = scaled_measure(c, cen, s1, c->V2) - target;
        }
        s = s1;
    }
    for (int i = 0; i < c->nv; i++)
        if (!c->fixed[i])
            for (int d = 0; d < 3; d++)
                c->X[3 * i + d] = cen[d] + s * (c->X[3 * i + d] - cen[d]);
}
