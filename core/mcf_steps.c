/* SPDX-License-Identifier: MIT */
/*
 * mcf_steps.c - one step of every MCF scheme, exactly as docs/MATH.md
 * ("The schemes: exact updates") writes it, with each scheme's local
 * error estimate for adaptive runs.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_flow_ctx.h"

/* ----------------------------------------------------- the schemes */

/* X+ = X + dt V + dt^2/2 ((Dh + |A|^2 h) n - h grad h): MATH.md huisken2. */
static void step_huisken2(flow_ctx *c, double h)
{
    int nv = c->nv;
    double *X = c->X, *V = c->V, *N = c->V2, *hv = c->T1, *Dh = c->T1 + nv,
           *K = c->T1 + 2 * (size_t)nv, *G = c->B;
    mcf__flow_ops_velocity(c, X, V);
    mcf__vertex_normals(X, c->F, c->nf, nv, N);
    for (int i = 0; i < nv; i++)
        hv[i] = mcf__dot3(V + 3 * i, N + 3 * i);
    /* Dh = -M^-1 L h: apply_L to the column (h, 0, 0) */
    for (int i = 0; i < nv; i++) {
        c->T2[3 * i] = hv[i];
        c->T2[3 * i + 1] = c->T2[3 * i + 2] = 0.0;
    }
    mcf__apply_L(c->F, c->nf, nv, c->w, c->T2, c->B);
    for (int i = 0; i < nv; i++)
        Dh[i] = c->fixed[i] ? 0.0 : -c->B[3 * i] / c->mass[i];
    /* K by angle deficit over the true barycentric mass (MATH.md); the
     * two nv-long sums live in T2 */
    double *asum = c->T2, *bmass = c->T2 + nv;
    memset(asum, 0, 2 * sizeof(double) * (size_t)nv);
    mcf__corner_sums(X, c->F, c->nf, asum, bmass, NULL);
    for (int i = 0; i < nv; i++)
        K[i] = c->fixed[i] || !(bmass[i] > 0.0) ? 0.0 : (2.0 * MCF_PI - asum[i]) / bmass[i];
    mcf__vertex_gradient(X, c->F, c->nf, nv, hv, G);
    for (int i = 0; i < nv; i++) {
        if (c->fixed[i])
            continue;
        double A2 = hv[i] * hv[i] - 2.0 * K[i]; /* 4H^2 - 2K with h = -2H */
        double sn = Dh[i] + A2 * hv[i];
        for (int d = 0; d < 3; d++)
            X[3 * i + d] += h * V[3 * i + d] +
                            0.5 * h * h * (sn * N[3 * i + d] - hv[i] * G[3 * i + d]);
    }
}

/* Per-vertex osculating-sphere step: MATH.md arc. */
static void step_arc(flow_ctx *c, double h)
{
    double *X = c->X, *V = c->V;
    mcf__flow_ops_velocity(c, X, V);
    for (int i = 0; i < c->nv; i++) {
        double *v = V + 3 * i, s = sqrt(mcf__dot3(v, v));
        double move;
        /* where |V|^2 h is tiny the arc and the line agree to rounding */
        if (s * s * h < 1e-12) {
            move = h;
        } else {
            double R = 2.0 / s;
            move = (R - sqrt(fmax(R * R - 4.0 * h, 0.0))) / s;
        }
        X[3 * i] += move * v[0]; X[3 * i + 1] += move * v[1]; X[3 * i + 2] += move * v[2];
    }
}

/* Taubin: X += lambda U X, X += mu U X, U = normalized umbrella -D^-1 L. */
static void step_taubin(flow_ctx *c)
{
    static const double coef[2] = {0.5, -0.53};
    for (int pass = 0; pass < 2; pass++) {
        double t0 = mcf_now();
        mcf__cot_weights(c->X, c->F, c->nf, c->p->laplacian, c->delta, c->w, c->area);
        c->st->time_assemble += mcf_now() - t0;
        mcf__apply_L(c->F, c->nf, c->nv, c->w, c->X, c->V);
        /* D = diag(L) = sum of the weights at each vertex */
        double *D = c->T1;
        memset(D, 0, sizeof(double) * (size_t)c->nv);
        for (int f = 0; f < c->nf; f++)
            for (int k = 0; k < 3; k++) {
                double wk = c->w[3 * f + k];
                D[c->F[3 * f + (k + 1) % 3]] += wk;
                D[c->F[3 * f + (k + 2) % 3]] += wk;
            }
        for (int i = 0; i < c->nv; i++) {
            if (c->fixed[i] || D[i] == 0.0)
                continue;
            double s = -coef[pass] / D[i];
            c->X[3 * i] += s * c->V[3 * i];
            c->X[3 * i + 1] += s * c->V[3 * i + 1];
            c->X[3 * i + 2] += s * c->V[3 * i + 2];
        }
    }
}

/* Picard iteration for the fully implicit Euler step. */
static mcf_status step_implicit(flow_ctx *c, double h, mcf_error *err)
{
    mcf_status rc;
    double *Xk = c->Xold, *Y = c->T1, *Ynew = c->V;
    memcpy(Xk, c->X, sizeof(double) * 3 * (size_t)c->nv);
    mcf__flow_ops_at(c, Xk, c->w, c->area, c->mass);
    if ((rc = mcf__flow_be_step(c, Xk, h, c->w, c->mass, Y, err)) != MCF_OK)
        return rc;
    for (int it = 1; it <= c->p->implicit_maxit; it++) {
        mcf__flow_ops_at(c, Y, c->w, c->area, c->mass);
        mcf__flow_system_fill(c, 1.0, h, c->w, c->mass);
        mcf__flow_mul_mass(c->nv, c->mass, Xk, c->B);
        mcf__flow_rhs_dirichlet(c, Xk, c->B);
        if ((rc = mcf__flow_factorize(c, err)) != MCF_OK || (rc = mcf__flow_solve(c, c->B, Ynew, err)) != MCF_OK)
            return rc;
        c->st->picard_iterations++;
        for (size_t i = 0; i < 3 * (size_t)c->nv; i++)
            c->V2[i] = Ynew[i] - Y[i];
        double d = mcf__flow_mnorm(c, c->V2, c->mass);
        memcpy(Y, Ynew, sizeof(double) * 3 * (size_t)c->nv);
        if (!isfinite(d))
            break;
        if (d <= c->p->implicit_tol) {
            memcpy(c->X, Y, sizeof(double) * 3 * (size_t)c->nv);
            return MCF_OK;
        }
    }
    return mcf__fail(err, MCF_ENOCONV,
                     "implicit: Picard iteration did not converge to %g in %d iterations at dt %g (use a smaller dt or desbrun2)",
                     c->p->implicit_tol, c->p->implicit_maxit, h);
}

/* A desbrun step from c->Xold into c->X. With est: step doubling, one
 * step h (T1) against two steps h/2 (kept as the result); *est is their
 * difference, filtered. */
static mcf_status desbrun_step(flow_ctx *c, double h, step_est *est, mcf_error *err)
{
    mcf_status rc;
    mcf__flow_ops_at(c, c->Xold, c->w, c->area, c->mass);
    if (!est)
        return mcf__flow_be_step(c, c->Xold, h, c->w, c->mass, c->X, err);
    if ((rc = mcf__flow_be_step(c, c->Xold, h, c->w, c->mass, c->T1, err)) != MCF_OK ||
        (rc = mcf__flow_be_step(c, c->Xold, 0.5 * h, c->w, c->mass, c->T2, err)) != MCF_OK)
        return rc;
    mcf__flow_ops_at(c, c->T2, c->w2, c->area2, c->mass2);
    if ((rc = mcf__flow_be_step(c, c->T2, 0.5 * h, c->w2, c->mass2, c->X, err)) != MCF_OK)
        return rc;
    /* the last factor is that of the second half step, at T2 */
    for (size_t i = 0; i < 3 * (size_t)c->nv; i++)
        c->V[i] = c->X[i] - c->T1[i];
    return mcf__flow_filtered_mnorm(c, 1.0, c->mass2, c->V, est, err);
}

/* euler: one pass over the faces (L X, mass, area), one over the
 * vertices (X -= h M^-1 L X, the copy to Xold): nothing else. */
static void step_euler(flow_ctx *c, double h)
{
    double *X = c->X;
    const double *Y = c->V;
    mcf__flow_LX(c, X, 0, c->V);
    for (int i = 0; i < c->nv; i++) {
        double s = c->fixed[i] ? 0.0 : -h / c->mass[i];
        for (int d = 0; d < 3; d++) {
            c->Xold[3 * i + d] = X[3 * i + d];
            X[3 * i + d] += s * Y[3 * i + d];
        }
    }
}

/* taylor2 (c2 = 1/2) and neumann2 (c2 = 1): X + h A X + c2 h^2 A^2 X. */
static void step_taylor(flow_ctx *c, double h, double c2)
{
    size_t n3 = 3 * (size_t)c->nv;
    mcf__flow_ops_velocity(c, c->X, c->V);                    /* A X */
    mcf__flow_velocity(c, c->w, c->mass, c->V, c->V2);        /* A^2 X */
    for (size_t i = 0; i < n3; i++)
        c->X[i] += h * c->V[i] + c2 * h * h * c->V2[i];
}

/* Milne's device (docs/MATH.md, "Adaptive steps"): the M-norm of c->X
 * minus the quadratic through the last three accepted states, at t + h.
 * That difference is X''' h (h+h1) (h+h1+h2) / 6 to leading order. Uses
 * c->V. */
static double milne_norm(flow_ctx *c, double h, const history *hist, const double *mass)
{
    double h1 = hist->h1, h2 = hist->h2;
    double tk = 0, tm1 = -h1, tm2 = -h1 - h2, tp = h;
    /* Lagrange weights of the quadratic through (tm2,tm1,tk) at tp */
    double l0 = (tp - tm1) * (tp - tk) / ((tm2 - tm1) * (tm2 - tk));
    double l1 = (tp - tm2) * (tp - tk) / ((tm1 - tm2) * (tm1 - tk));
    double l2 = (tp - tm2) * (tp - tm1) / ((tk - tm2) * (tk - tm1));
    for (size_t i = 0; i < 3 * (size_t)c->nv; i++)
        c->V[i] = c->X[i] - (l0 * c->Xprev2[i] + l1 * c->Xprev[i] + l2 * c->Xold[i]);
    return mcf__flow_mnorm(c, c->V, mass);
}

/* A one-step method of local error C h^3 X''' (on y' = lambda y, C from
 * the series of its stability function against exp: ros2 -1.3738 with
 * gamma = 1 + 1/sqrt 2): Milne's difference times 6 |C| h^2 /
 * ((h+h1)(h+h1+h2)). Unfiltered, per unit step, as desbrun2's
 * (docs/MATH.md). */
static double milne_onestep(flow_ctx *c, double C, double h, const history *hist)
{
    return 6.0 * fabs(C) * h * h / ((h + hist->h1) * (h + hist->h1 + hist->h2)) *
           milne_norm(c, h, hist, c->mass);
}

/* desbrun2 after its first step: variable-step BDF2, operator at the
 * linear extrapolation:
 * (c0 Me + h Le) X+ = Me ((1+w) X^k - w^2/(1+w) X^(k-1)),
 * w = h/h1, c0 = (1+2w)/(1+w); w = 1 gives MATH.md's form. */
static mcf_status step_bdf2(flow_ctx *c, double h, const history *hist, step_est *est,
                            mcf_error *err)
{
    size_t n3 = 3 * (size_t)c->nv;
    double *X = c->X;
    mcf_status rc;
    double om = h / hist->h1, c0 = (1.0 + 2.0 * om) / (1.0 + om);
    double a1 = 1.0 + om, a2 = om * om / (1.0 + om);
    for (size_t i = 0; i < n3; i++)
        c->T1[i] = c->Xold[i] + om * (c->Xold[i] - c->Xprev[i]);
    mcf__flow_ops_at(c, c->T1, c->w, c->area, c->mass);
    mcf__flow_system_fill(c, c0, h, c->w, c->mass);
    for (size_t i = 0; i < n3; i++)
        c->T2[i] = a1 * c->Xold[i] - a2 * c->Xprev[i];
    mcf__flow_mul_mass(c->nv, c->mass, c->T2, c->B);
    mcf__flow_rhs_dirichlet(c, c->Xold, c->B);
    if ((rc = mcf__flow_factorize(c, err)) != MCF_OK || (rc = mcf__flow_solve(c, c->B, X, err)) != MCF_OK)
        return rc;
    if (est && hist->nhist >= 2) {
        /* Two parts (docs/MATH.md, "Adaptive steps"), in the M-norm:
         * Milne's device: X+ minus the quadratic through the last three
         * points is DD3 * h (h+h1) (h+h1+h2); the BDF2 local error is
         * |DD3| h^2 (h+h1)^2 / (2h+h1) (docs/MATH.md). Unfiltered: a
         * mode's local error survives to T damped by about
         * exp(-lambda (T - t)), not by the step's resolvent, so
         * filtering hid the modes near h lambda ~ 1 that the last steps
         * leave in the result (tol 1e-5 on noisy spot and snowden: 1.9-2.0x
         * tol filtered, 1.0-1.2x unfiltered).
         * The defect: the operator is taken at the extrapolation, not at
         * X+, an error of order h^3 X'' dL/dX that is smooth in time, so
         * the third difference cannot see it. The residual of the fully
         * implicit equation at X+, r = Me+ (a1 X^k - a2 X^(k-1)) -
         * (c0 Me+ + h Le+) X+, through the step's factor is X+'s
         * distance to the fully implicit BDF2 result. On spot
         * (strength 0.5) it is as large as Milne's part, and without it
         * the largest vertex error at T was 57-223x tol. One more
         * assembly and back-solve, no factorization.
         * The max: the largest vertex of Milne's part seen through the
         * step's factor plus the defect (issue 30: the RMS leaves ear
         * tips and fingers, 5-10% of the mean mass, 39-128 tol off on
         * armadillo; unfiltered, a noise sliver's transient sets the
         * step). One more back-solve. */
        double h1 = hist->h1, h2 = hist->h2;
        double fac = h * (h + h1) / ((2.0 * h + h1) * (h + h1 + h2));
        double milne = fac * milne_norm(c, h, hist, c->mass);
        step_est f;
        if ((rc = mcf__flow_filtered_mnorm(c, c0, c->mass, c->V, &f, err)) != MCF_OK)
            return rc;
        mcf__flow_ops_at(c, X, c->w2, c->area2, c->mass2);
        mcf__apply_L(c->F, c->nf, c->nv, c->w2, X, c->B);
        for (int i = 0; i < c->nv; i++)
            for (int d = 0; d < 3; d++) {
                size_t j = 3 * (size_t)i + (size_t)d;
                c->B[j] = c->fixed[i] ? 0.0 : c->mass2[i] * (c->T2[j] - c0 * X[j]) - h * c->B[j];
            }
        if ((rc = mcf__flow_solve(c, c->B, c->V2, err)) != MCF_OK)
            return rc;
        est->rms = milne + mcf__flow_mnorm(c, c->V2, c->mass);
        for (size_t i = 0; i < n3; i++)
            c->V[i] = fac * c->V[i] + c->V2[i];
        est->max = mcf__flow_maxnorm(c, c->V);
    }
    return MCF_OK;
}

/* ros2's local error constant on y' = lambda y: R(z) - exp(z) =
 * -1.3738 z^3 + O(z^4) with gamma = 1 + 1/sqrt 2 (sympy series of the
 * stability function, docs/numerics.md). */
#define ROS2_C (-1.37377344785321)

/* ros2: Rosenbrock-W, gamma = 1 + 1/sqrt(2); est: Milne's device from the
 * third step on, the embedded first-order solution before; the RMS only
 * (est->max stays 0: docs/numerics.md, "What tol means", says why). */
static mcf_status step_ros2(flow_ctx *c, double h, const history *hist, step_est *est, mcf_error *err)
{
    size_t n3 = 3 * (size_t)c->nv;
    double *X = c->X;
    mcf_status rc;
    const double gamma = 1.0 + 1.0 / sqrt(2.0);
    double *K1 = c->T1, *K2 = c->T2;
    mcf__flow_ops_at(c, c->Xold, c->w, c->area, c->mass);
    mcf__flow_system_fill(c, 1.0, gamma * h, c->w, c->mass);
    mcf__apply_L(c->F, c->nf, c->nv, c->w, c->Xold, c->B);   /* L X */
    for (size_t i = 0; i < n3; i++)
        c->B[i] = -c->B[i];
    mcf__flow_rhs_dirichlet(c, NULL, c->B);
    if ((rc = mcf__flow_factorize(c, err)) != MCF_OK || (rc = mcf__flow_solve(c, c->B, K1, err)) != MCF_OK)
        return rc;
    for (size_t i = 0; i < n3; i++)
        c->V[i] = c->Xold[i] + h * K1[i];                     /* Y */
    mcf__flow_ops_at(c, c->V, c->w2, c->area2, c->mass2);
    mcf__apply_L(c->F, c->nf, c->nv, c->w2, c->V, c->B);     /* L(Y) Y */
    for (int i = 0; i < c->nv; i++) {
        double r = c->mass[i] / c->mass2[i];
        for (int d = 0; d < 3; d++)
            c->B[3 * i + d] = -r * c->B[3 * i + d] - 2.0 * c->mass[i] * K1[3 * i + d];
    }
    mcf__flow_rhs_dirichlet(c, NULL, c->B);
    if ((rc = mcf__flow_solve(c, c->B, K2, err)) != MCF_OK)
        return rc;
    for (size_t i = 0; i < n3; i++)
        X[i] = c->Xold[i] + h * (1.5 * K1[i] + 0.5 * K2[i]);
    if (est && hist->nhist >= 2) {
        est->rms = milne_onestep(c, ROS2_C, h, hist);
    } else if (est) {
        /* The first two steps: X+ - Y = h/2 (K1 + K2), a first-order
         * companion's error, filtered through W^-1 M (Shampine):
         * unfiltered, a stiff mode of Y keeps (1 - 1/gamma) of its
         * amplitude, so the raw difference is O(1) on noisy meshes
         * and the controller would crawl. One more back-solve. */
        for (int i = 0; i < c->nv; i++)
            for (int d = 0; d < 3; d++)
                c->B[3 * i + d] = c->fixed[i] ? 0.0 : 0.5 * h * c->mass[i] * (K1[3 * i + d] + K2[3 * i + d]);
        if ((rc = mcf__flow_solve(c, c->B, c->V2, err)) != MCF_OK)
            return rc;
        est->rms = mcf__flow_mnorm(c, c->V2, c->mass);
    }
    return MCF_OK;
}

/* richardson: 2 BE(h/2) o BE(h/2) - BE(h); est from their difference.
 * (Milne's device with its constant, -1/6 h^3 X''' on y' = lambda y,
 * missed the transient of a noisy sphere: 12 tol at T where the control
 * promised 0.3, tests/test_core_flow.c test_adaptive; docs/numerics.md.) */
static mcf_status step_richardson(flow_ctx *c, double h, step_est *est, mcf_error *err)
{
    size_t n3 = 3 * (size_t)c->nv;
    double *X = c->X;
    mcf_status rc = MCF_OK;
    mcf__flow_ops_at(c, c->Xold, c->w, c->area, c->mass);
    if ((rc = mcf__flow_be_step(c, c->Xold, h, c->w, c->mass, c->T1, err)) != MCF_OK ||
        (rc = mcf__flow_be_step(c, c->Xold, 0.5 * h, c->w, c->mass, c->T2, err)) != MCF_OK)
        return rc;
    mcf__flow_ops_at(c, c->T2, c->w2, c->area2, c->mass2);
    if ((rc = mcf__flow_be_step(c, c->T2, 0.5 * h, c->w2, c->mass2, c->V, err)) != MCF_OK)
        return rc;
    for (size_t i = 0; i < n3; i++) {
        c->V2[i] = c->V[i] - c->T1[i];
        X[i] = 2.0 * c->V[i] - c->T1[i];
    }
    if (est) /* the last factor: the second half step's, at T2 */
        rc = mcf__flow_filtered_mnorm(c, 1.0, c->mass2, c->V2, est, err);
    return rc;
}

/* linear: (M_0 + dt L_0) X+ = M_0 X: factor once, back-solve each step. */
static mcf_status step_linear(flow_ctx *c, double h, mcf_error *err)
{
    size_t n3 = 3 * (size_t)c->nv;
    double *X = c->X;
    mcf_status rc;
    if (!c->factor_valid) {
        mcf__flow_system_fill(c, 1.0, h, c->w2, c->mass2);
        mcf__flow_mul_mass(c->nv, c->mass2, c->Xold, c->B);
        mcf__flow_rhs_dirichlet(c, c->Xold, c->B);
        if ((rc = mcf__flow_factorize(c, err)) != MCF_OK)
            return rc;
    } else {
        mcf__flow_mul_mass(c->nv, c->mass2, c->Xold, c->B);
        for (int i = 0; i < c->nv; i++)
            if (c->fixed[i])
                for (int d = 0; d < 3; d++)
                    c->B[3 * i + d] = c->Xold[3 * i + d];
        /* the couplings to fixed vertices are constant: their effect
         * on B was recorded in T2 at the first step */
        for (size_t i = 0; i < n3; i++)
            c->B[i] += c->T2[i];
    }
    return mcf__flow_solve(c, c->B, X, err);
}

/* One step of size h from c->X (kept in c->Xold). On return c->X holds the
 * new positions and *est (if the scheme has one and est != NULL) the local
 * error estimate. */
mcf_status mcf__flow_step(flow_ctx *c, double h, const history *hist, step_est *est,
                          mcf_error *err)
{
    if (c->p->scheme != MCF_EULER) /* euler copies in its vertex pass */
        memcpy(c->Xold, c->X, 3 * (size_t)c->nv * sizeof(double));
    if (est)
        est->rms = est->max = 0.0;
    switch (c->p->scheme) {
    case MCF_EULER:
        step_euler(c, h);
        return MCF_OK;
    case MCF_TAYLOR2:
        step_taylor(c, h, 0.5);
        return MCF_OK;
    case MCF_NEUMANN2:
        step_taylor(c, h, 1.0);
        return MCF_OK;
    case MCF_DESBRUN:
        return desbrun_step(c, h, est, err);
    case MCF_DESBRUN2: /* the start, as MATH.md says: a desbrun step */
        return hist->nhist == 0 ? desbrun_step(c, h, est, err) : step_bdf2(c, h, hist, est, err);
    case MCF_ROS2:
        return step_ros2(c, h, hist, est, err);
    case MCF_RICHARDSON:
        return step_richardson(c, h, est, err);
    case MCF_IMPLICIT:
        return step_implicit(c, h, err);
    case MCF_HUISKEN2:
        step_huisken2(c, h);
        return MCF_OK;
    case MCF_ARC:
        step_arc(c, h);
        return MCF_OK;
    case MCF_CMCF:
        /* (M_k + dt L_0) X+ = M_k X: stiffness from the input (w2) */
        mcf__flow_ops_at(c, c->Xold, c->w, c->area, c->mass);
        return mcf__flow_be_step(c, c->Xold, h, c->w2, c->mass, c->X, err);
    case MCF_LINEAR:
        return step_linear(c, h, err);
    case MCF_TAUBIN:
        step_taubin(c);
        return MCF_OK;
    case MCF_FAIRING:
    case MCF_FAIRING_FEATURE:
    case MCF_FAIRING_EXPLICIT: /* filters: run_fairing, never a step here */
    case MCF_NSCHEMES:
        break;
    }
    return mcf__fail(err, MCF_EINVAL, "scheme out of range");
}
