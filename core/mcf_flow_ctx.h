/* SPDX-License-Identifier: MIT */
/*
 * mcf_flow_ctx.h - private to the files of one MCF run (mcf_flow.c, the
 * driver; mcf_flow_ops.c, its operators, linear solves and step checks;
 * mcf_steps.c, the schemes' steps; mcf_schemes.c, the scheme table and
 * parameter checks): the run's state and what those files call across.
 * Never included outside core/; the public contract is mcf.h.
 */
#ifndef MCF_FLOW_CTX_H
#define MCF_FLOW_CTX_H

#include "mcf_internal.h"

/* The state of one mcf_flow_run call: the mesh in working units, the
 * operators, the solver and the work vectors. */
typedef struct {
    const mcf_flow_params *p;
    const mcf_scheme_info *si;
    int nv, nf;
    const int32_t *F;
    double *X;              /* the mesh's positions, normalized in place */
    double delta;           /* mollification margin, fixed per job */
    unsigned char *fixed;   /* nv: Dirichlet vertex */
    size_t bytes;           /* our own allocations, for peak_bytes */

    /* operators at the configuration last passed to ops_at() */
    double *w, *area, *mass;
    double area_sum;        /* total area at the last ops_LX() */
    /* a second set (ros2's Y, desbrun2's frozen copy, cmcf/linear L_0, M_0) */
    double *w2, *area2, *mass2;

    /* work vectors, 3*nv each */
    double *V, *V2, *B, *T1, *T2, *Xold, *Xprev;
    double *Xprev2;         /* desbrun2 adaptive history */
    double *fn, *fn2;       /* 3*nf face normals before / after a step */

    /* solver */
    mcf__pattern pat;
    int *zero_idx, *zero_col, nzero; /* off-diagonal entries touching a fixed vertex, their columns */
    int analyzed, factor_valid;
    mcf__chol *chol;        /* the factorization (mcf_cholesky.c) */
    double *Ax;             /* the system's values on pat (upper triangle) */

    mcf_flow_stats *st;
    double step_solve_s;
} flow_ctx;

/* Everything one attempted step needs to know about history. */
typedef struct {
    int nhist;            /* accepted steps so far (for desbrun2) */
    double h1, h2;        /* the two previous step sizes */
} history;

/* An attempted step's local error estimate (adaptive runs), in working
 * units (relative to the unit-area size, as tol): rms, the M-weighted
 * RMS the control's tol bounds; max, the largest vertex's, seen through
 * the step's resolvent (mcf__flow_filtered_mnorm): the ear tips and
 * fingers whose error the M-weighting makes small (docs/numerics.md,
 * "What tol means"). */
typedef struct {
    double rms, max;
} step_est;

/* mcf_schemes.c */
int mcf__is_fairing(mcf_scheme s);

/* mcf_flow_ops.c: the operators at a configuration, the linear systems
 * (c M + s L) Y = B on one CHOLMOD factor per step, and the checks a step
 * is judged by (finite, folded faces, the error norms). */
void mcf__flow_LX(flow_ctx *c, const double *X, int keep_w, double *Y);
int mcf__flow_all_finite(const double *X, size_t n);
double *mcf__flow_alloc(flow_ctx *c, size_t n);
mcf_status mcf__flow_be_step(flow_ctx *c, const double *X, double h, const double *w,
                          const double *mass, double *Y, mcf_error *err);
mcf_status mcf__flow_factorize(flow_ctx *c, mcf_error *err);
mcf_status mcf__flow_filtered_mnorm(flow_ctx *c, double cmass, const double *mass, double *D,
                                 step_est *out, mcf_error *err);
double mcf__flow_maxnorm(const flow_ctx *c, const double *D);
int mcf__flow_folded_faces(const double *X, const int32_t *F, int nf, int nv,
                           const double *fn_before, double *fn_after, double *N);
double mcf__flow_min_edge(const double *X, const int32_t *F, int nf);
double mcf__flow_mnorm(const flow_ctx *c, const double *D, const double *mass);
void mcf__flow_mul_mass(int nv, const double *mass, const double *X, double *Y);
void mcf__flow_ops_at(flow_ctx *c, const double *X, double *w, double *area, double *mass);
void mcf__flow_ops_velocity(flow_ctx *c, const double *X, double *V);
void mcf__flow_rhs_dirichlet(flow_ctx *c, const double *Xfix, double *B);
mcf_status mcf__flow_solve(flow_ctx *c, const double *B, double *Y, mcf_error *err);
mcf_status mcf__flow_solver_init(flow_ctx *c, mcf_error *err);
/* Restores the area (rescale=area) or the volume by scaling the free
 * vertices about the area centroid. */
void mcf__flow_rescale(flow_ctx *c, double area0, double vol0);
void mcf__flow_system_fill(flow_ctx *c, double cmass, double cl, const double *w, const double *mass);
void mcf__flow_velocity(flow_ctx *c, const double *w, const double *mass, const double *X, double *V);

/* mcf_steps.c: one step of size h of the run's scheme from c->X (kept in
 * c->Xold): c->X holds the new positions and *est (when the scheme has an
 * estimate and est != NULL) its local error, in the M-norm and the
 * vertices' max. */
mcf_status mcf__flow_step(flow_ctx *c, double h, const history *hist, step_est *est,
                          mcf_error *err);

#endif /* MCF_FLOW_CTX_H */
