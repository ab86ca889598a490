/*
 * mcf_flow.c - every time integrator of mean curvature flow, fixed-step and
 * adaptive, on one CHOLMOD solver per job.
 *
 * The updates are exactly those of ../shared/MATH.md ("Schemes"). All
 * schemes work on positions normalized to unit area about the area
 * centroid (unless normalize is off), so dt and time are dimensionless;
 * the result is mapped back to input units at the end.
 *
 * Linear systems: every implicit scheme solves (c M + s L) Y = B for three
 * right-hand-side columns, where M and L are evaluated at some
 * configuration. The sparsity pattern never changes during a job, so
 * cholmod_analyze runs once; each step refills the values (a scatter over
 * the faces, no triplets, no sort), refactorizes numerically and solves.
 * Fixed vertices (fixed boundary, the user's list, vertices no face uses)
 * are Dirichlet rows: their row and column become the identity and their
 * couplings move to the right-hand side, which keeps the system SPD.
 *
 * Workload: meshes up to a few million vertices, tens to thousands of
 * steps; per step the cost is one pass over the faces plus the
 * factorization. No I/O, no globals; one flow_ctx per call.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_internal.h"

/* ------------------------------------------------------- scheme table */

static const mcf_scheme_info SCHEMES[MCF_NSCHEMES] = {
    [MCF_EULER] = {"euler", "explicit (forward) Euler", 1, 1, 2.0, 0, 0, 0, "",
                   "cheap steps on small meshes; the explicit baseline"},
    [MCF_TAYLOR2] = {"taylor2", "explicit Taylor, operator frozen (article: 2nd-order explicit)", 1, 1, 2.0, 0, 0, 0, "",
                     "reproducing the article; first order on MCF because L and M move"},
    [MCF_DESBRUN] = {"desbrun", "semi-implicit Euler (Desbrun 1999 / Dziuk 1990)", 1, 0, 0.0, 1, 1, 1,
                     "step doubling",
                     "robust first-order smoothing at any step"},
    [MCF_NEUMANN2] = {"neumann2", "truncated Neumann series I + dtA + dt^2A^2 (article eq. ***)", 1, 1, 1.0, 0, 0, 0, "",
                      "reproducing the article's erratum: first order, half Euler's stability"},
    [MCF_DESBRUN2] = {"desbrun2", "linearly implicit BDF2 on the extrapolated operator", 2, 0, 0.0, 1, 1, 1,
                      "Milne device (new step vs quadratic extrapolation)",
                      "default: second order, A/L-stable, one factorization per step"},
    [MCF_ROS2] = {"ros2", "Rosenbrock-W, gamma = 1 + 1/sqrt(2)", 2, 0, 0.0, 2, 1, 1,
                  "embedded first-order solution, filtered by W^-1 M",
                  "second order with a free error estimate; small steps"},
    [MCF_RICHARDSON] = {"richardson", "Richardson extrapolation of desbrun steps", 2, 0, 0.0, 3, 3, 1,
                        "difference of the two desbrun solutions",
                        "second order from a first-order solver; 3 factorizations"},
    [MCF_IMPLICIT] = {"implicit", "fully implicit Euler by Picard iteration", 1, 0, 0.0, 0, 0, 0, "",
                      "reference for the nonlinear backward Euler; costly"},
    [MCF_HUISKEN2] = {"huisken2", "Taylor step from Huisken's evolution equations (corrected)", 1, 1, 2.0, 0, 0, 0, "",
                      "experiments; exact to 2nd order on spheres"},
    [MCF_ARC] = {"arc", "osculating-sphere arc step", 1, 1, 2.0, 0, 0, 0, "",
                 "explicit, exact radius law on spheres, never overshoots"},
    [MCF_CMCF] = {"cmcf", "conformalized MCF (Kazhdan 2012), L from the input", 1, 0, 0.0, 1, 1, 0, "",
                  "large-time smoothing without neck pinches (libigl/pmp/CGAL)"},
    [MCF_LINEAR] = {"linear", "heat flow: L and M frozen, factor once", 1, 0, 0.0, 1, 0, 0, "",
                    "fastest implicit smoothing; not geometric MCF"},
    [MCF_TAUBIN] = {"taubin", "Taubin lambda/mu filter, lambda 0.5, mu -0.53", 0, 1, 0.0, 0, 0, 0, "",
                    "volume-preserving-ish denoising baseline (MeshLab/Open3D)"},
    [MCF_FAIRING] = {"fairing", "implicit bi-Laplacian fairing along the normals, amount by SURE", 0, 0, 0.0, 3, 0, 0, "",
                     "default: denoising scans; one factorization per run"},
    [MCF_FAIRING_EXPLICIT] = {"fairing_explicit", "Taubin passes along the normals, amount by SURE", 0, 1, 0.0, 0, 0, 0, "",
                              "denoising meshes too large to factor; no linear solve"},
};

static int is_fairing(mcf_scheme s)
{
    return s == MCF_FAIRING || s == MCF_FAIRING_EXPLICIT;
}

const mcf_scheme_info *mcf_scheme_get(mcf_scheme s)
{
    return (int)s >= 0 && s < MCF_NSCHEMES ? &SCHEMES[s] : NULL;
}

mcf_status mcf_scheme_from_name(const char *name, mcf_scheme *out)
{
    for (int s = 0; name && s < MCF_NSCHEMES; s++)
        if (strcmp(name, SCHEMES[s].name) == 0) {
            *out = (mcf_scheme)s;
            return MCF_OK;
        }
    return MCF_EINVAL;
}

/* ------------------------------------------------------------ params */

void mcf_flow_params_init(mcf_flow_params *p)
{
    memset(p, 0, sizeof *p);
    p->scheme = MCF_DESBRUN2;
    p->dt = 0.0;        /* derived from the amount */
    p->iterations = 0;  /* MCF_DEFAULT_STEPS */
    p->strength = MCF_DEFAULT_STRENGTH;
    p->boundary = MCF_BOUNDARY_FIXED;
    p->rescale = MCF_RESCALE_NONE;
    p->normalize = 1;
    p->laplacian = MCF_LAPLACIAN_COTAN;
    p->mass = MCF_MASS_BARYCENTRIC;
    p->tol = 1e-4;
    p->max_steps = 10000;
    p->implicit_tol = 1e-10;
    p->implicit_maxit = 200;
}

mcf_status mcf_flow_params_check(const mcf_flow_params *p, int nv, mcf_error *err)
{
    const mcf_scheme_info *si = mcf_scheme_get(p->scheme);
    if (!si)
        return mcf__fail(err, MCF_EINVAL, "scheme: unknown scheme %d", (int)p->scheme);
    if (p->dt_auto && !si->is_explicit)
        return mcf__fail(err, MCF_EINVAL, "dt: \"auto\" applies to explicit schemes only, not '%s'", si->name);
    if (!p->dt_auto && !(isfinite(p->dt) && p->dt >= 0.0))
        return mcf__fail(err, MCF_EINVAL, "dt: must be a finite number > 0 (or 0: derived), got %g", p->dt);
    if (!isfinite(p->time) || p->time < 0.0)
        return mcf__fail(err, MCF_EINVAL, "time: must be a finite number >= 0, got %g", p->time);
    if (p->iterations < 0)
        return mcf__fail(err, MCF_EINVAL, "iterations: must be >= 1 (or 0: the default), got %d", p->iterations);
    if (!(isfinite(p->strength) && p->strength > 0.0))
        return mcf__fail(err, MCF_EINVAL, "strength: must be a finite number > 0, got %g", p->strength);
    if (p->scheme == MCF_TAUBIN && (p->time > 0.0 || p->adaptive || p->dt_auto))
        return mcf__fail(err, MCF_EINVAL, "taubin is a filter: it takes iterations (passes), not time, dt=auto or adaptive");
    if (is_fairing(p->scheme) && (p->time > 0.0 || p->adaptive || p->dt_auto || p->dt > 0.0))
        return mcf__fail(err, MCF_EINVAL, "%s is a filter: it takes iterations (steps) or the noise level, not time, dt or adaptive",
                         si->name);
    if (!(isfinite(p->noise_sigma) && p->noise_sigma >= 0.0))
        return mcf__fail(err, MCF_EINVAL, "noise_sigma: must be a finite number >= 0, got %g", p->noise_sigma);
    if (p->adaptive && !si->has_estimate)
        return mcf__fail(err, MCF_EINVAL, "adaptive: scheme '%s' has no error estimate (use desbrun2, ros2, richardson or desbrun)", si->name);
    if (p->adaptive && !(p->tol > 0.0 && p->tol <= 1.0))
        return mcf__fail(err, MCF_EINVAL, "tol: must be in (0, 1], got %g", p->tol);
    if (p->max_steps < 1)
        return mcf__fail(err, MCF_EINVAL, "max_steps: must be >= 1, got %d", p->max_steps);
    if ((unsigned)p->boundary > MCF_BOUNDARY_FREE)
        return mcf__fail(err, MCF_EINVAL, "boundary: must be fixed or free");
    if ((unsigned)p->rescale > MCF_RESCALE_AREA)
        return mcf__fail(err, MCF_EINVAL, "rescale: must be none, volume or area");
    if ((unsigned)p->laplacian > MCF_LAPLACIAN_UNIFORM)
        return mcf__fail(err, MCF_EINVAL, "laplacian: must be cotan or uniform");
    if ((unsigned)p->mass > MCF_MASS_VORONOI)
        return mcf__fail(err, MCF_EINVAL, "mass: must be barycentric or voronoi");
    if (p->scheme == MCF_IMPLICIT && (!(p->implicit_tol > 0.0) || p->implicit_maxit < 1))
        return mcf__fail(err, MCF_EINVAL, "implicit: needs implicit_tol > 0 and implicit_maxit >= 1");
    if (p->nfixed < 0 || (p->nfixed > 0 && !p->fixed))
        return mcf__fail(err, MCF_EINVAL, "fixed_vertices: %d indices but no array", p->nfixed);
    for (int i = 0; i < p->nfixed; i++)
        if (p->fixed[i] < 0 || p->fixed[i] >= nv)
            return mcf__fail(err, MCF_EINVAL, "fixed_vertices: index %d out of range 0..%d", (int)p->fixed[i], nv - 1);
    return MCF_OK;
}

/* --------------------------------------------------------- job state */

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

static double *ctx_alloc(flow_ctx *c, size_t n)
{
    double *v = mcf__calloc(n, sizeof(double));
    if (v)
        c->bytes += n * sizeof(double);
    return v;
}

/* Weights, areas and masses of configuration X into (w, area, mass). */
static void ops_at(flow_ctx *c, const double *X, double *w, double *area, double *mass)
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
static void velocity(flow_ctx *c, const double *w, const double *mass, const double *X, double *V)
{
    mcf__apply_L(c->F, c->nf, c->nv, w, X, V);
    scale_velocity(c, mass, V);
}

/* Operators at X (c->mass, c->area_sum; c->w and c->area when keep_w or
 * when the mass is not barycentric) and Y = L X: with the barycentric
 * mass in one pass over the faces, which is most of an explicit step. */
static void ops_LX(flow_ctx *c, const double *X, int keep_w, double *Y)
{
    if (c->p->mass != MCF_MASS_BARYCENTRIC) {
        ops_at(c, X, c->w, c->area, c->mass);
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
static void ops_velocity(flow_ctx *c, const double *X, double *V)
{
    ops_LX(c, X, 1, V);
    scale_velocity(c, c->mass, V);
}

/* Y = M X row-wise. */
static void mul_mass(int nv, const double *mass, const double *X, double *Y)
{
    for (int i = 0; i < nv; i++) {
        Y[3 * i] = mass[i] * X[3 * i];
        Y[3 * i + 1] = mass[i] * X[3 * i + 1];
        Y[3 * i + 2] = mass[i] * X[3 * i + 2];
    }
}

static mcf_status solver_init(flow_ctx *c, mcf_error *err)
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
    if (!(c->chol = mcf__chol_new(&c->pat, err)))
        return MCF_ENOMEM;
    return MCF_OK;
}

/* A = cm * M + cl * L(w), Dirichlet rows applied; values into c->Ax. */
static void system_fill(flow_ctx *c, double cmass, double cl, const double *w, const double *mass)
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
static mcf_status factorize(flow_ctx *c, mcf_error *err)
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
 * the couplings before factorize() zeroes them. Xfix NULL: the unknowns
 * are zero on fixed vertices (velocities) and nothing moves to B. */
static void rhs_dirichlet(flow_ctx *c, const double *Xfix, double *B)
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
static mcf_status solve(flow_ctx *c, const double *B, double *Y, mcf_error *err)
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
static mcf_status be_step(flow_ctx *c, const double *X, double h, const double *w,
                          const double *mass, double *Y, mcf_error *err)
{
    mcf_status rc;
    system_fill(c, 1.0, h, w, mass);
    mul_mass(c->nv, mass, X, c->B);
    rhs_dirichlet(c, X, c->B);
    if ((rc = factorize(c, err)) != MCF_OK)
        return rc;
    return solve(c, c->B, Y, err);
}

/* -------------------------------------------------------- geometry */

/* Faces a step folded (mcf__folded_faces against fn_before: turned by
 * more than 90 degrees and lying backwards in the neighbourhood). The new
 * face normals go to fn_after (the next step's "before"); N (3*nv) is
 * scratch. Faces that were degenerate before (zero normal) cannot fold. */
static int folded_faces(const double *X, const int32_t *F, int nf, int nv,
                        const double *fn_before, double *fn_after, double *N)
{
    return mcf__folded_faces(X, F, nf, nv, fn_before, fn_after, N, NULL);
}

static int all_finite(const double *X, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (!isfinite(X[i]))
            return 0;
    return 1;
}

/* M-weighted RMS of D (3*nv) over sqrt(sum m): the error norm of MATH.md
 * for unit-area meshes. */
static double mnorm(const flow_ctx *c, const double *D, const double *mass)
{
    double s = 0.0, ms = 0.0;
    for (int i = 0; i < c->nv; i++) {
        s += mass[i] * mcf__dot3(D + 3 * i, D + 3 * i);
        ms += mass[i];
    }
    return ms > 0.0 ? sqrt(s / ms) : 0.0;
}

/* The M-norm of W^-1 (cmass M) D, for D (3*nv, zero on fixed vertices)
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
 * desbrun2's Milne estimate goes unfiltered (do_step says why). One more
 * back-solve (3 columns) with the factor already at hand; D is
 * overwritten. */
static mcf_status filtered_mnorm(flow_ctx *c, double cmass, const double *mass, double *D,
                                 double *out, mcf_error *err)
{
    mcf_status rc;
    for (int i = 0; i < c->nv; i++)
        for (int d = 0; d < 3; d++)
            c->B[3 * i + d] = c->fixed[i] ? 0.0 : cmass * mass[i] * D[3 * i + d];
    if ((rc = solve(c, c->B, D, err)) != MCF_OK)
        return rc;
    *out = mnorm(c, D, mass);
    return MCF_OK;
}

/* ----------------------------------------------------- the schemes */

/* X+ = X + dt V + dt^2/2 ((Dh + |A|^2 h) n - h grad h): MATH.md huisken2. */
static void step_huisken2(flow_ctx *c, double h)
{
    int nv = c->nv;
    double *X = c->X, *V = c->V, *N = c->V2, *hv = c->T1, *Dh = c->T1 + nv,
           *K = c->T1 + 2 * (size_t)nv, *G = c->B;
    ops_velocity(c, X, V);
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
    ops_velocity(c, X, V);
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
    ops_at(c, Xk, c->w, c->area, c->mass);
    if ((rc = be_step(c, Xk, h, c->w, c->mass, Y, err)) != MCF_OK)
        return rc;
    for (int it = 1; it <= c->p->implicit_maxit; it++) {
        ops_at(c, Y, c->w, c->area, c->mass);
        system_fill(c, 1.0, h, c->w, c->mass);
        mul_mass(c->nv, c->mass, Xk, c->B);
        rhs_dirichlet(c, Xk, c->B);
        if ((rc = factorize(c, err)) != MCF_OK || (rc = solve(c, c->B, Ynew, err)) != MCF_OK)
            return rc;
        c->st->picard_iterations++;
        for (size_t i = 0; i < 3 * (size_t)c->nv; i++)
            c->V2[i] = Ynew[i] - Y[i];
        double d = mnorm(c, c->V2, c->mass);
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
 * step h (T1) against two steps h/2 (kept as the result); *est is the
 * M-norm of their difference. */
static mcf_status desbrun_step(flow_ctx *c, double h, double *est, mcf_error *err)
{
    mcf_status rc;
    ops_at(c, c->Xold, c->w, c->area, c->mass);
    if (!est)
        return be_step(c, c->Xold, h, c->w, c->mass, c->X, err);
    if ((rc = be_step(c, c->Xold, h, c->w, c->mass, c->T1, err)) != MCF_OK ||
        (rc = be_step(c, c->Xold, 0.5 * h, c->w, c->mass, c->T2, err)) != MCF_OK)
        return rc;
    ops_at(c, c->T2, c->w2, c->area2, c->mass2);
    if ((rc = be_step(c, c->T2, 0.5 * h, c->w2, c->mass2, c->X, err)) != MCF_OK)
        return rc;
    /* the last factor is that of the second half step, at T2 */
    for (size_t i = 0; i < 3 * (size_t)c->nv; i++)
        c->V[i] = c->X[i] - c->T1[i];
    return filtered_mnorm(c, 1.0, c->mass2, c->V, est, err);
}

/* Everything one attempted step needs to know about history. */
typedef struct {
    int nhist;            /* accepted steps so far (for desbrun2) */
    double h1, h2;        /* the two previous step sizes */
} history;

/* One step of size h from c->X (kept in c->Xold). On return c->X holds the
 * new positions and *est (if the scheme has one and est != NULL) the local
 * error estimate in the M-norm. */
static mcf_status do_step(flow_ctx *c, double h, const history *hist, double *est,
                          mcf_error *err)
{
    mcf_status rc = MCF_OK;
    size_t n3 = 3 * (size_t)c->nv;
    double *X = c->X;
    if (c->p->scheme != MCF_EULER) /* euler copies in its vertex pass */
        memcpy(c->Xold, X, n3 * sizeof(double));
    if (est)
        *est = 0.0;
    switch (c->p->scheme) {
    case MCF_EULER: {
        /* one pass over the faces (L X, mass, area), one over the
         * vertices (X -= h M^-1 L X, the copy to Xold): nothing else */
        const double *Y = c->V;
        ops_LX(c, X, 0, c->V);
        for (int i = 0; i < c->nv; i++) {
            double s = c->fixed[i] ? 0.0 : -h / c->mass[i];
            for (int d = 0; d < 3; d++) {
                c->Xold[3 * i + d] = X[3 * i + d];
                X[3 * i + d] += s * Y[3 * i + d];
            }
        }
        break;
    }
    case MCF_TAYLOR2:
    case MCF_NEUMANN2: {
        double c2 = c->p->scheme == MCF_TAYLOR2 ? 0.5 : 1.0;
        ops_velocity(c, X, c->V);                   /* A X */
        velocity(c, c->w, c->mass, c->V, c->V2);    /* A^2 X */
        for (size_t i = 0; i < n3; i++)
            X[i] += h * c->V[i] + c2 * h * h * c->V2[i];
        break;
    }
    case MCF_DESBRUN:
        rc = desbrun_step(c, h, est, err);
        break;
    case MCF_DESBRUN2:
        if (hist->nhist == 0) {
            rc = desbrun_step(c, h, est, err); /* the start, as MATH.md says */
        } else {
            /* variable-step BDF2, operator at the linear extrapolation:
             * (c0 Me + h Le) X+ = Me ((1+w) X^k - w^2/(1+w) X^(k-1)),
             * w = h/h1, c0 = (1+2w)/(1+w); w = 1 gives MATH.md's form. */
            double om = h / hist->h1, c0 = (1.0 + 2.0 * om) / (1.0 + om);
            double a1 = 1.0 + om, a2 = om * om / (1.0 + om);
            for (size_t i = 0; i < n3; i++)
                c->T1[i] = c->Xold[i] + om * (c->Xold[i] - c->Xprev[i]);
            ops_at(c, c->T1, c->w, c->area, c->mass);
            system_fill(c, c0, h, c->w, c->mass);
            for (size_t i = 0; i < n3; i++)
                c->T2[i] = a1 * c->Xold[i] - a2 * c->Xprev[i];
            mul_mass(c->nv, c->mass, c->T2, c->B);
            rhs_dirichlet(c, c->Xold, c->B);
            if ((rc = factorize(c, err)) != MCF_OK || (rc = solve(c, c->B, X, err)) != MCF_OK)
                break;
            if (est && hist->nhist >= 2) {
                /* Milne device: X+ minus the quadratic through the last
                 * three points is DD3 * h (h+h1) (h+h1+h2); the BDF2 local
                 * error is |DD3| h^2 (h+h1)^2 / (2h+h1) (see README).
                 * Unfiltered: a mode's local error survives to T damped by
                 * about exp(-lambda (T - t)), not by the step's resolvent
                 * 1 / (1 + h lambda / c0), so filtering (as the start and
                 * the first-order companions do) hid the modes near
                 * h lambda ~ 1 that the last steps leave in the result:
                 * filtered, tol 1e-5 ended 1.9-2.0x tol from a converged
                 * run on spot and snowden at noise 0.25 (25-34 steps),
                 * unfiltered 1.0-1.2x (37-65 steps), and the error now
                 * falls with tol (tol 1e-6: 0.7-1.1x). */
                double h1 = hist->h1, h2 = hist->h2;
                double tk = 0, tm1 = -h1, tm2 = -h1 - h2, tp = h;
                /* Lagrange weights of the quadratic through (tm2,tm1,tk) at tp */
                double l0 = (tp - tm1) * (tp - tk) / ((tm2 - tm1) * (tm2 - tk));
                double l1 = (tp - tm2) * (tp - tk) / ((tm1 - tm2) * (tm1 - tk));
                double l2 = (tp - tm2) * (tp - tm1) / ((tk - tm2) * (tk - tm1));
                for (size_t i = 0; i < n3; i++)
                    c->V[i] = X[i] - (l0 * c->Xprev2[i] + l1 * c->Xprev[i] + l2 * c->Xold[i]);
                double fac = h * (h + h1) / ((2.0 * h + h1) * (h + h1 + h2));
                *est = fac * mnorm(c, c->V, c->mass);
            }
        }
        break;
    case MCF_ROS2: {
        const double gamma = 1.0 + 1.0 / sqrt(2.0);
        double *K1 = c->T1, *K2 = c->T2;
        ops_at(c, c->Xold, c->w, c->area, c->mass);
        system_fill(c, 1.0, gamma * h, c->w, c->mass);
        mcf__apply_L(c->F, c->nf, c->nv, c->w, c->Xold, c->B);   /* L X */
        for (size_t i = 0; i < n3; i++)
            c->B[i] = -c->B[i];
        rhs_dirichlet(c, NULL, c->B);
        if ((rc = factorize(c, err)) != MCF_OK || (rc = solve(c, c->B, K1, err)) != MCF_OK)
            break;
        for (size_t i = 0; i < n3; i++)
            c->V[i] = c->Xold[i] + h * K1[i];                     /* Y */
        ops_at(c, c->V, c->w2, c->area2, c->mass2);
        mcf__apply_L(c->F, c->nf, c->nv, c->w2, c->V, c->B);     /* L(Y) Y */
        for (int i = 0; i < c->nv; i++) {
            double r = c->mass[i] / c->mass2[i];
            for (int d = 0; d < 3; d++)
                c->B[3 * i + d] = -r * c->B[3 * i + d] - 2.0 * c->mass[i] * K1[3 * i + d];
        }
        rhs_dirichlet(c, NULL, c->B);
        if ((rc = solve(c, c->B, K2, err)) != MCF_OK)
            break;
        for (size_t i = 0; i < n3; i++)
            X[i] = c->Xold[i] + h * (1.5 * K1[i] + 0.5 * K2[i]);
        if (est) {
            /* X+ - Y = h/2 (K1 + K2), filtered through W^-1 M (Shampine):
             * unfiltered, a stiff mode of Y keeps (1 - 1/gamma) of its
             * amplitude, so the raw difference is O(1) on noisy meshes
             * and the controller would crawl. One more back-solve. */
            for (int i = 0; i < c->nv; i++)
                for (int d = 0; d < 3; d++)
                    c->B[3 * i + d] = c->fixed[i] ? 0.0 : 0.5 * h * c->mass[i] * (K1[3 * i + d] + K2[3 * i + d]);
            if ((rc = solve(c, c->B, c->V2, err)) != MCF_OK)
                break;
            *est = mnorm(c, c->V2, c->mass);
        }
        break;
    }
    case MCF_RICHARDSON:
        ops_at(c, c->Xold, c->w, c->area, c->mass);
        if ((rc = be_step(c, c->Xold, h, c->w, c->mass, c->T1, err)) != MCF_OK ||
            (rc = be_step(c, c->Xold, 0.5 * h, c->w, c->mass, c->T2, err)) != MCF_OK)
            break;
        ops_at(c, c->T2, c->w2, c->area2, c->mass2);
        if ((rc = be_step(c, c->T2, 0.5 * h, c->w2, c->mass2, c->V, err)) != MCF_OK)
            break;
        for (size_t i = 0; i < n3; i++) {
            c->V2[i] = c->V[i] - c->T1[i];
            X[i] = 2.0 * c->V[i] - c->T1[i];
        }
        if (est) /* the last factor: the second half step's, at T2 */
            rc = filtered_mnorm(c, 1.0, c->mass2, c->V2, est, err);
        break;
    case MCF_IMPLICIT:
        rc = step_implicit(c, h, err);
        break;
    case MCF_HUISKEN2:
        step_huisken2(c, h);
        break;
    case MCF_ARC:
        step_arc(c, h);
        break;
    case MCF_CMCF:
        /* (M_k + dt L_0) X+ = M_k X: stiffness from the input (w2) */
        ops_at(c, c->Xold, c->w, c->area, c->mass);
        rc = be_step(c, c->Xold, h, c->w2, c->mass, X, err);
        break;
    case MCF_LINEAR:
        /* (M_0 + dt L_0) X+ = M_0 X: factor once, back-solve each step */
        if (!c->factor_valid) {
            system_fill(c, 1.0, h, c->w2, c->mass2);
            mul_mass(c->nv, c->mass2, c->Xold, c->B);
            rhs_dirichlet(c, c->Xold, c->B);
            if ((rc = factorize(c, err)) != MCF_OK)
                break;
        } else {
            mul_mass(c->nv, c->mass2, c->Xold, c->B);
            for (int i = 0; i < c->nv; i++)
                if (c->fixed[i])
                    for (int d = 0; d < 3; d++)
                        c->B[3 * i + d] = c->Xold[3 * i + d];
            /* the couplings to fixed vertices are constant: their effect
             * on B was recorded in T2 at the first step */
            for (size_t i = 0; i < n3; i++)
                c->B[i] += c->T2[i];
        }
        rc = solve(c, c->B, X, err);
        break;
    case MCF_TAUBIN:
        step_taubin(c);
        break;
    case MCF_FAIRING:
    case MCF_FAIRING_EXPLICIT: /* filters: run_fairing, never a step here */
    case MCF_NSCHEMES:
        rc = mcf__fail(err, MCF_EINVAL, "scheme out of range");
        break;
    }
    return rc;
}

/* ---------------------------------------------------------- driver */

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
static void rescale(flow_ctx *c, double area0, double vol0)
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

static void ctx_free(flow_ctx *c)
{
    free(c->fixed); free(c->w); free(c->area); free(c->mass);
    free(c->w2); free(c->area2); free(c->mass2);
    free(c->V); free(c->V2); free(c->B); free(c->T1); free(c->T2);
    free(c->Xold); free(c->Xprev); free(c->Xprev2); free(c->fn); free(c->fn2);
    free(c->zero_idx);
    free(c->zero_col);
    mcf__pattern_free(&c->pat);
    free(c->Ax);
    mcf__chol_free(c->chol);
}

/* 1 when some edge may lie on an odd number of faces (a boundary edge
 * lies on one), 0 when none does, -1 when out of memory: every vertex
 * XORs a bijective 64-bit mix of each neighbour once per face side they
 * share, so even multiplicities cancel. A manifold boundary vertex keeps
 * two distinct mixed values, whose XOR is never zero; only three or more
 * odd edges at every odd vertex could cancel, by a 2^-64 chance. Lets
 * explicit schemes skip the pattern on closed meshes. */
static int odd_edges(const flow_ctx *c)
{
    uint64_t *acc = mcf__calloc((size_t)c->nv, sizeof *acc);
    if (!acc)
        return -1;
    for (size_t k = 0; k < 3 * (size_t)c->nf; k += 3)
        for (int e = 0; e < 3; e++) {
            uint64_t a = (uint64_t)c->F[k + e], b = (uint64_t)c->F[k + (e + 1) % 3];
            if (a != b) {
                acc[a] ^= mcf__mix64(b);
                acc[b] ^= mcf__mix64(a);
            }
        }
    int odd = 0;
    for (int i = 0; i < c->nv && !odd; i++)
        odd = acc[i] != 0;
    free(acc);
    return odd;
}

/* Boundary vertices: endpoints of edges used by exactly one face. */
static void mark_boundary(const mcf__pattern *p, unsigned char *fixed)
{
    for (int j = 0; j < p->n; j++)
        for (int t = p->colptr[j]; t < p->colptr[j + 1]; t++)
            if (p->mult[t] == 1)
                fixed[j] = fixed[p->rowind[t]] = 1;
}

/* Adds the vertices no face uses to fixed[] (nv, 0/1 entries). */
static void mark_unreferenced(const int32_t *F, int nf, int nv, unsigned char *fixed)
{
    for (size_t k = 0; k < 3 * (size_t)nf; k++)
        fixed[F[k]] |= 2; /* referenced */
    for (int i = 0; i < nv; i++)
        fixed[i] = fixed[i] != 2; /* fixed already, or unreferenced */
}

/* Marks in fixed[] (nv, zeroed by the caller) what a run with p holds in
 * place: p's list, the boundary vertices with boundary=fixed and the
 * vertices no face uses. ENOMEM only. */
static mcf_status fixed_set(const mcf_mesh *m, const mcf_flow_params *p, unsigned char *fixed,
                            mcf_error *err)
{
    for (int i = 0; i < p->nfixed; i++)
        fixed[p->fixed[i]] = 1;
    if (p->boundary == MCF_BOUNDARY_FIXED) {
        mcf__pattern pat;
        mcf_status rc = mcf__pattern_build(m->F, m->nf, m->nv, 0, &pat, err);
        if (rc != MCF_OK)
            return rc;
        mark_boundary(&pat, fixed);
        mcf__pattern_free(&pat);
    }
    mark_unreferenced(m->F, m->nf, m->nv, fixed);
    return MCF_OK;
}

mcf_status mcf_flow_add_noise(mcf_mesh *m, const mcf_flow_params *p, double rho, uint64_t seed,
                              mcf_error *err)
{
    mcf_status rc;
    if (!m || !p)
        return mcf__fail(err, MCF_EINVAL, "mcf_flow_add_noise: NULL argument");
    if ((rc = mcf_flow_params_check(p, m->nv, err)) != MCF_OK)
        return rc;
    unsigned char *fixed = mcf__calloc((size_t)m->nv, 1);
    double *keep = mcf__malloc(3 * (size_t)m->nv, sizeof(double));
    if (!fixed || !keep) {
        rc = mcf__fail(err, MCF_ENOMEM, "noise: out of memory (%d vertices)", m->nv);
        goto done;
    }
    if ((rc = fixed_set(m, p, fixed, err)) != MCF_OK)
        goto done;
    memcpy(keep, m->X, 3 * sizeof(double) * (size_t)m->nv);
    if ((rc = mcf_mesh_add_noise(m, rho, seed, err)) != MCF_OK)
        goto done;
    for (int i = 0; i < m->nv; i++)
        if (fixed[i])
            memcpy(m->X + 3 * (size_t)i, keep + 3 * (size_t)i, 3 * sizeof(double));
done:
    free(fixed);
    free(keep);
    return rc;
}

mcf_status mcf_noise_estimate(const mcf_mesh *m, const mcf_flow_params *p, double *sigma,
                              mcf_error *err)
{
    mcf_status rc;
    if (!m || !p || !sigma)
        return mcf__fail(err, MCF_EINVAL, "mcf_noise_estimate: NULL argument");
    if ((rc = mcf_flow_params_check(p, m->nv, err)) != MCF_OK)
        return rc;
    unsigned char *fixed = mcf__calloc((size_t)m->nv, 1);
    if (!fixed)
        return mcf__fail(err, MCF_ENOMEM, "noise estimate: out of memory (%d vertices)", m->nv);
    double s = 0.0;
    if ((rc = fixed_set(m, p, fixed, err)) == MCF_OK &&
        (rc = mcf__noise_level(m->X, m->F, m->nf, m->nv, fixed, &s, err)) == MCF_OK)
        *sigma = s;
    free(fixed);
    return rc;
}

/* The log's area and volume are in input units, and the volume is
 * volume0/volume1's (mcf_mesh_volume's): about the input's origin, from
 * the positions mapped back as the run's end maps them. (The working
 * positions are centred on the input's area centroid, and on an open
 * mesh the signed volume depends on that choice.) */
static void log_step(flow_ctx *c, const double *X, int k, double t, double h, int rejected,
                     double scale, const double cen[3], double maxdisp)
{
    mcf_flow_stats *st = c->st;
    if (!c->p->log_steps || !st->log)
        return;
    mcf_step_log *L = &st->log[k];
    L->t = t;
    L->dt = h;
    double A = 0.0, V = 0.0;
    for (int f = 0; f < c->nf; f++) {
        double p[3][3], e1[3], e2[3], n[3], bd[3];
        for (int q = 0; q < 3; q++)
            for (int d = 0; d < 3; d++)
                p[q][d] = X[3 * (size_t)c->F[3 * f + q] + d] / scale + cen[d];
        mcf__sub3(p[1], p[0], e1);
        mcf__sub3(p[2], p[0], e2);
        mcf__cross3(e1, e2, n);
        A += 0.5 * sqrt(mcf__dot3(n, n));
        mcf__cross3(p[1], p[2], bd);
        V += mcf__dot3(p[0], bd);
    }
    L->area = A;
    L->volume = V / 6.0;
    L->max_disp = maxdisp / scale;
    L->solve_s = c->step_solve_s;
    L->rejected = rejected;
    st->nlog = k + 1;
}

/* The failure of a fixed-step run whose step `step` (1-based) left
 * non-finite positions (grown == 0) or an area grown by `grown`. */
static mcf_status unstable(const flow_ctx *c, mcf_error *err, int step, double h, double grown)
{
    char why[64];
    if (grown > 0.0)
        snprintf(why, sizeof why, "an area %.3g times the initial one", grown);
    else
        snprintf(why, sizeof why, "non-finite positions");
    return mcf__fail(err, MCF_ENUMERIC, "step %d of '%s' at dt %g produced %s%s", step, c->si->name, h, why,
                     c->si->is_explicit ? " (explicit scheme beyond its stability limit: try dt=auto)" : "");
}

/* Shortest edge of positive length (0 when none). */
static double min_edge(const double *X, const int32_t *F, int nf)
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

/* The warnings of a finished run (result X, input X_in, both in input
 * units). Thresholds, measured on the shared scans with 0.1-0.5 mean
 * edges of injected noise (README, "Choosing the amount"):
 *  - folds: faces the run folded (mcf__folds_against the input: turned
 *    by more than 90 degrees and lying backwards in their neighbourhood
 *    of the result), over 0.1% of the faces (and at least 3); at useful
 *    amounts a flow folds none to a handful on clean meshes. Counted
 *    face by face: a run that unfolds the noise's folds here and folds
 *    others there is not let off (the count of faces lying backwards,
 *    before and after, netted those out: the fairing guard's Y positions
 *    folded 333 of dragon_vrip_res2's faces at noise 0.1 while that
 *    count fell by 241).
 *  - edge_collapse: the shortest edge shrank more than 1000x; smoothing
 *    noise evens edges out, it never needs to collapse one.
 *  - area_loss: more than 40% of the area lost with rescale off. Noise
 *    inflates the area: removing noise of half a mean edge at the best
 *    amount loses 30-38% of it (snowden 0.62, stanford bunny 0.68),
 *    while the old default's needles lost 31-56%.
 *  - little_smoothing: less than 0.1 mean edges of diffusion (t < 0.01
 *    h^2): the result is indistinguishable from the input. */
static void flow_warnings(const flow_ctx *c, const double *X_in, mcf_flow_stats *st)
{
    const mcf_flow_params *p = c->p;
    double me0 = min_edge(X_in, c->F, c->nf), me1 = min_edge(c->X, c->F, c->nf);
    int folds = mcf__folds_against(c->X, X_in, c->F, c->nf, c->nv);
    st->folded_faces = folds < 0 ? 0 : folds;
    st->min_edge_ratio = me0 > 0.0 ? me1 / me0 : 1.0;
    st->area_ratio = st->area0 > 0.0 ? st->area1 / st->area0 : 1.0;
    st->strength = st->mean_edge > 0.0 && !is_fairing(p->scheme) ? sqrt(st->t_final) / st->mean_edge : 0.0;
    if (st->folded_faces >= 3 && st->folded_faces > 1e-3 * c->nf)
        st->warnings |= MCF_WARN_FOLDS;
    if (st->min_edge_ratio < 1e-3)
        st->warnings |= MCF_WARN_EDGE_COLLAPSE;
    if (p->rescale == MCF_RESCALE_NONE && st->area_ratio < 0.6)
        st->warnings |= MCF_WARN_AREA_LOSS;
    /* an automatic amount or a fairing filter that found little noise:
     * the finding, not a warning */
    if (!is_fairing(p->scheme) && p->scheme != MCF_TAUBIN && !p->strength_auto && st->strength < 0.1)
        st->warnings |= MCF_WARN_LITTLE_SMOOTHING;
}

/* The fairing filter's view of the run (mcf__step_hook): the cancel flag
 * before a step; the step log, the progress callback (t = the step
 * count, dt = 1, energy the area) after it. */
typedef struct {
    flow_ctx *c;
    double scale;
    const double *cen;
    double *prev;   /* 3*nv: the positions after the last step */
} fair_hook;

static int fairing_hook(void *ctx, int k, const double *X)
{
    fair_hook *h = ctx;
    flow_ctx *c = h->c;
    const mcf_flow_params *p = c->p;
    if (!X)
        return p->cancel && atomic_load_explicit(p->cancel, memory_order_acquire);
    if (p->log_steps && c->st->log && k <= c->st->t_target) {
        double maxd = 0.0;
        for (size_t i = 0; i < (size_t)c->nv; i++) {
            double d[3];
            mcf__sub3(X + 3 * i, h->prev + 3 * i, d);
            maxd = fmax(maxd, mcf__dot3(d, d));
        }
        memcpy(h->prev, X, 3 * sizeof(double) * (size_t)c->nv);
        log_step(c, X, k - 1, k, 1.0, 0, h->scale, h->cen, sqrt(maxd));
    }
    return p->progress &&
           p->progress(p->progress_ctx, k, k, 1.0, mcf__area_volume(X, c->F, c->nf, NULL, NULL) / (h->scale * h->scale));
}

/* mcf_flow_run for the fairing filters, from the normalized positions on:
 * the fixed set, the log, the filter. */
static mcf_status run_fairing(flow_ctx *c, const mcf_mesh *m, double scale, const double cen[3],
                              mcf_error *err)
{
    const mcf_flow_params *p = c->p;
    mcf_flow_stats *st = c->st;
    fair_hook h = {c, scale, cen, NULL};
    mcf_status rc = fixed_set(m, p, c->fixed, err);
    if (rc != MCF_OK)
        return rc;
    double hbar = mcf__mean_edge(c->X, c->F, c->nf);
    st->mean_edge = hbar;
    if (p->log_steps) {
        int cap = p->iterations > 0 ? p->iterations
                  : p->scheme == MCF_FAIRING ? MCF_FAIRING_MAX_STEPS : MCF_FAIRING_MAX_PASSES;
        if (cap > p->max_steps && p->iterations <= 0)
            cap = p->max_steps;
        st->log = mcf__calloc((size_t)cap, sizeof *st->log);
        h.prev = mcf__malloc(3 * (size_t)c->nv, sizeof(double));
        if (!st->log || !h.prev) {
            free(h.prev);
            return mcf__fail(err, MCF_ENOMEM, "flow: out of memory for the step log");
        }
        memcpy(h.prev, c->X, 3 * sizeof(double) * (size_t)c->nv);
    }
    rc = mcf__fairing(c->X, c->F, c->nf, c->nv, c->fixed, p, hbar, st, fairing_hook, &h, err);
    c->bytes += st->peak_bytes;
    free(h.prev);
    return rc;
}

mcf_status mcf_flow_run(mcf_mesh *m, const mcf_flow_params *p,
                        mcf_flow_stats *stats, mcf_error *err)
{
    flow_ctx c;
    mcf_flow_stats st_local;
    mcf_status rc;
    int in_step = 0;
    double t_start = mcf_now();
    memset(&c, 0, sizeof c);
    memset(&st_local, 0, sizeof st_local);
    if (!m || !p)
        return mcf__fail(err, MCF_EINVAL, "mcf_flow_run: NULL argument");
    if ((rc = mcf_flow_params_check(p, m->nv, err)) != MCF_OK)
        return rc;
    mcf_flow_stats *st = stats ? stats : &st_local;
    memset(st, 0, sizeof *st);
    c.p = p;
    c.si = mcf_scheme_get(p->scheme);
    c.st = st;
    c.nv = m->nv;
    c.nf = m->nf;
    c.F = m->F;
    c.X = m->X;
    size_t n3 = 3 * (size_t)c.nv, nv = (size_t)c.nv, nf = (size_t)c.nf;

    /* normalize: centre on the area centroid, scale to unit area */
    double cen[3] = {0, 0, 0}, scale = 1.0;
    double area_in = mcf__area_volume(m->X, m->F, m->nf, cen, &st->volume0);
    st->area0 = area_in;
    if (!isfinite(area_in))
        return mcf__fail(err, MCF_EMESH, "the mesh's area overflows double precision "
                         "(coordinates too large: keep them below about 1e150); scale it down");
    if (p->normalize) {
        if (!(area_in > 0.0))
            return mcf__fail(err, MCF_EMESH, "normalize: the mesh has zero total area");
        scale = 1.0 / sqrt(area_in);
    } else {
        cen[0] = cen[1] = cen[2] = 0.0;
    }
    /* keep an exact copy for restoring on failure: X in input units */
    double *X_in = mcf__malloc(n3, sizeof(double));
    if (!X_in)
        return mcf__fail(err, MCF_ENOMEM, "flow: out of memory (%d vertices)", c.nv);
    memcpy(X_in, m->X, n3 * sizeof(double));
    c.bytes += n3 * sizeof(double);
    if (p->normalize)
        for (size_t i = 0; i < nv; i++)
            for (int d = 0; d < 3; d++)
                c.X[3 * i + d] = (c.X[3 * i + d] - cen[d]) * scale;

    c.fixed = mcf__calloc(nv, 1);
    if (is_fairing(p->scheme)) {
        rc = c.fixed ? run_fairing(&c, m, scale, cen, err)
                     : mcf__fail(err, MCF_ENOMEM, "flow: out of memory (%d vertices)", c.nv);
        goto done;
    }
    c.w = ctx_alloc(&c, 3 * nf); c.area = ctx_alloc(&c, nf); c.mass = ctx_alloc(&c, nv);
    c.w2 = ctx_alloc(&c, 3 * nf); c.area2 = ctx_alloc(&c, nf); c.mass2 = ctx_alloc(&c, nv);
    c.V = ctx_alloc(&c, n3); c.V2 = ctx_alloc(&c, n3); c.B = ctx_alloc(&c, n3);
    c.T1 = ctx_alloc(&c, n3); c.T2 = ctx_alloc(&c, n3); c.Xold = ctx_alloc(&c, n3);
    c.Xprev = ctx_alloc(&c, n3); c.Xprev2 = ctx_alloc(&c, n3);
    /* adaptive runs reject steps that fold too many faces (see
     * folded_faces). Not every fold proves a step too large: even a stable
     * explicit step (dt = 0.25 / lambda_max on a noisy scan) folds the odd
     * sliver through the flow's own nonlinearity, and on a scan full of
     * needles (snowden) every step folds 1-20 of 109k faces at any size
     * down to 1e-9; past strength 1 the flow itself crumples ears at a
     * rate proportional to the time covered (armadillo, t = 1e-4: about
     * 2e8 folds per unit time). Rejecting those made dt collapse and the
     * run crawl (dt 1e-11 after 22k steps). So a step is rejected for
     * folds only past fold_budget (0.1% of the faces, the FOLDS warning's
     * threshold) AND past 4x what the run's own fold rate predicts for
     * its size: folds that grow with the step faster than linearly are a
     * step too large; the flow's own are reported by the FOLDS warning. */
    int check_inv = p->adaptive, fold_budget = c.nf / 1000, folds_total = 0;
    if (check_inv) {
        c.fn = ctx_alloc(&c, 3 * nf);
        c.fn2 = ctx_alloc(&c, 3 * nf);
    }
    if (!c.fixed || !c.w || !c.area || !c.mass || !c.w2 || !c.area2 || !c.mass2 || !c.V ||
        !c.V2 || !c.B || !c.T1 || !c.T2 || !c.Xold || !c.Xprev || !c.Xprev2 ||
        (check_inv && (!c.fn || !c.fn2))) {
        rc = mcf__fail(err, MCF_ENOMEM, "flow: out of memory (%d vertices, %d faces)", c.nv, c.nf);
        goto done;
    }
    if (p->log_steps) {
        size_t cap = p->adaptive ? (size_t)p->max_steps : (size_t)(p->time > 0 ? 0 : p->iterations);
        st->log = NULL;
        if (cap > 0 && !(st->log = mcf__calloc(cap, sizeof *st->log))) {
            rc = mcf__fail(err, MCF_ENOMEM, "flow: out of memory for the step log");
            goto done;
        }
    }

    /* Dirichlet vertices: user list, fixed boundary, unreferenced */
    for (int i = 0; i < p->nfixed; i++)
        c.fixed[p->fixed[i]] = 1;
    /* the pattern: the implicit schemes' matrix, and the edge
     * multiplicities that find the boundary (an explicit scheme on a mesh
     * without boundary needs neither) */
    int fix_boundary = p->boundary == MCF_BOUNDARY_FIXED;
    int odd = c.si->is_explicit && fix_boundary ? odd_edges(&c) : 0;
    if (odd < 0) {
        rc = mcf__fail(err, MCF_ENOMEM, "flow: out of memory (%d vertices)", c.nv);
        goto done;
    }
    if (p->rescale == MCF_RESCALE_VOLUME && !odd && (odd = odd_edges(&c)) < 0) {
        rc = mcf__fail(err, MCF_ENOMEM, "flow: out of memory (%d vertices)", c.nv);
        goto done;
    }
    if (p->rescale == MCF_RESCALE_VOLUME && odd) {
        /* an open surface encloses no volume: its "volume" depends on
         * where the origin is, and restoring it moved a holed bunny's
         * free vertices the wrong way (2.6x worse, 1% off its target) */
        rc = mcf__fail(err, MCF_EINVAL,
                       "rescale: volume needs a closed mesh, this one has boundary (or odd non-manifold) edges: use rescale=area");
        goto done;
    }
    if (!c.si->is_explicit || odd) {
        if ((rc = mcf__pattern_build(c.F, c.nf, c.nv, !c.si->is_explicit, &c.pat, err)) != MCF_OK)
            goto done;
        c.bytes += sizeof(int) * (2 * (size_t)c.pat.nnz + 2 * nv + (c.pat.tri ? 3 * nf : 0));
        if (fix_boundary)
            mark_boundary(&c.pat, c.fixed);
    }
    double hbar = mcf__mean_edge(c.X, c.F, c.nf);
    st->mean_edge = hbar;
    c.delta = MCF_MOLLIFY * hbar;
    /* vertices without mass stay put: the unreferenced ones (every
     * referenced vertex has barycentric mass, the mollified areas being
     * positive) and, with the Voronoi mass, any other */
    if (p->mass == MCF_MASS_BARYCENTRIC) {
        mark_unreferenced(c.F, c.nf, c.nv, c.fixed);
    } else {
        ops_at(&c, c.X, c.w, c.area, c.mass);
        for (size_t i = 0; i < nv; i++)
            if (!(c.mass[i] > 0.0))
                c.fixed[i] = 1;
    }

    if (!c.si->is_explicit && (rc = solver_init(&c, err)) != MCF_OK)
        goto done;
    if (p->scheme == MCF_CMCF || p->scheme == MCF_LINEAR)
        ops_at(&c, c.X, c.w2, c.area2, c.mass2); /* L_0 (and M_0) from the input */

    /* the amount and the steps (mcf.h, "The amount of smoothing") */
    double h = p->dt, T = p->time;
    int dt_set = p->dt_auto || p->dt > 0.0;
    int nsteps = p->iterations > 0 ? p->iterations : MCF_DEFAULT_STEPS;
    if (p->dt_auto) {
        mcf_mesh tmp = {c.nv, c.nf, c.X, (int32_t *)(uintptr_t)c.F};
        if ((rc = mcf_lambda_max(&tmp, p->laplacian, p->mass, &st->lambda_max, err)) != MCF_OK)
            goto done;
        /* 0.9/lambda_max for euler-like schemes (0.45 for neumann2): the
         * top mode then decays without changing sign, so no sliver flips;
         * 10% margin for the power iteration's underestimate */
        h = 0.45 * c.si->stability / st->lambda_max;
    }
    if (p->scheme == MCF_TAUBIN) {
        h = T = 0.0; /* passes, no time */
        if (p->strength_auto && p->iterations <= 0) {
            double sigma;
            if ((rc = mcf__auto_passes(c.X, c.F, c.nf, c.nv, c.fixed, p->laplacian, hbar, &nsteps, &sigma,
                                       err)) != MCF_OK)
                goto done;
            if (nsteps > p->max_steps)
                nsteps = p->max_steps;
            st->noise = sigma / hbar;
        }
    } else if (T <= 0.0 && p->iterations > 0 && dt_set) {
        T = p->iterations * h;
    } else if (T <= 0.0 && p->strength_auto) {
        double sigma;
        /* an implicit scheme lends its solver: one symbolic analysis
         * (mcf__chol_analyze keeps the factor the borrower made) */
        mcf__solver lend;
        if (c.chol)
            mcf__chol_lend(c.chol, c.Ax, &lend);
        if ((rc = mcf__auto_time(c.X, c.F, c.nf, c.nv, c.fixed, p->laplacian, p->mass,
                                 p->scheme != MCF_LINEAR, hbar, nsteps, c.chol ? &lend : NULL,
                                 &T, &sigma, err)) != MCF_OK)
            goto done;
        st->noise = sigma / hbar;
        if (!(T > 0.0))
            nsteps = 0; /* no noise to remove: the mesh comes back as it came */
    } else if (T <= 0.0) {
        T = p->strength * p->strength * hbar * hbar;
    }
    st->t_target = T;
    if (p->scheme != MCF_TAUBIN && !dt_set) {
        h = nsteps > 0 ? T / nsteps : 0.0;
    } else if (p->scheme != MCF_TAUBIN && !p->adaptive) {
        double k = ceil(T / h * (1.0 - 1e-12));
        /* a step count the caller gave (iterations with dt) is the
         * caller's; max_steps bounds the counts derived from a time */
        if (k > (double)p->max_steps && !(p->iterations > 0 && p->time <= 0.0)) {
            rc = mcf__fail(err, MCF_ELIMIT, "time %g at dt %g needs %.0f steps, over max_steps %d%s", T, h, k, p->max_steps,
                           p->dt_auto ? " (dt=auto is set by the stiffest triangle: use an implicit scheme such as desbrun2)" : "");
            goto done;
        }
        nsteps = k < 1 ? 1 : (int)k;
        h = T / nsteps;
    }
    if (p->adaptive)
        h = fmin(h, T);
    if (p->log_steps && !st->log && !p->adaptive && nsteps > 0 &&
        !(st->log = mcf__calloc((size_t)nsteps, sizeof *st->log))) {
        rc = mcf__fail(err, MCF_ENOMEM, "flow: out of memory for the step log");
        goto done;
    }
    st->dt_first = h;
    st->dt_min = INFINITY;
    st->dt_max = 0.0;

    /* the rescale targets, in working units (exact: a scaling maps area
     * by scale^2 and volume by scale^3, a translation keeps both) */
    double area0 = area_in * scale * scale, vol0 = st->volume0 * scale * scale * scale;
    if (check_inv)
        mcf__face_normals(c.X, c.F, c.nf, c.fn);
    double t = 0.0;
    history hist = {0, 0.0, 0.0};
    int k = 0, attempts = 0, rejected_here = 0;
    for (;;) {
        if (p->adaptive ? !(t < T * (1.0 - 1e-12)) : k >= nsteps)
            break;
        if (p->cancel && atomic_load_explicit(p->cancel, memory_order_acquire)) {
            rc = mcf__fail(err, MCF_ECANCELED, "canceled at step %d (t = %g)", k, t);
            goto done;
        }
        if (p->adaptive) {
            if (++attempts > p->max_steps) {
                rc = mcf__fail(err, MCF_ELIMIT, "adaptive: max_steps (%d attempts, %d accepted) reached at t = %g of %g; raise max_steps or tol",
                               p->max_steps, k, t, T);
                goto done;
            }
            if (t + h > T || T - (t + h) < 1e-9 * h)
                h = T - t;
        }
        c.step_solve_s = 0.0;
        double est = 0.0;
        if (p->scheme == MCF_LINEAR && !c.factor_valid) {
            /* linear: the couplings to fixed vertices never change; keep
             * their right-hand-side share -sum A_ij x_j in T2 */
            system_fill(&c, 1.0, h, c.w2, c.mass2);
            memset(c.T2, 0, n3 * sizeof(double));
            rhs_dirichlet(&c, c.X, c.T2);
            for (size_t i = 0; i < nv; i++)
                if (c.fixed[i])
                    c.T2[3 * i] = c.T2[3 * i + 1] = c.T2[3 * i + 2] = 0.0;
        }
        in_step = 1;
        rc = do_step(&c, h, &hist, p->adaptive ? &est : NULL, err);
        int finite = rc == MCF_OK && all_finite(c.X, n3);
        int inv = finite && check_inv ? folded_faces(c.X, c.F, c.nf, c.nv, c.fn, c.fn2, c.T1) : 0;
        double h_next = h;
        if (p->adaptive) {
            if (rc == MCF_ENOMEM || rc == MCF_ECANCELED)
                goto done;
            /* desbrun2's Milne estimate has the method's own order, so it
             * is controlled per unit step: a step may carry tol * h / T, and
             * the local errors add up to about tol at T. The others
             * estimate the error of a first-order companion (embedded Y,
             * the plain desbrun steps), which overstates the second-order
             * result's error by 1/(h lambda) on stiff modes: controlled per
             * step (est <= tol), that is already conservative, while per
             * unit step it would crawl through the noise transient.
             * est ~ h^(q+1): the exponent is 1/(q+1) per step, 1/q per
             * unit step (est/h ~ h^q). */
            int per_unit = p->scheme == MCF_DESBRUN2;
            int q = per_unit && hist.nhist >= 2 ? 2 : 1;
            int need_est = !(per_unit && hist.nhist == 1);
            double allowed = per_unit ? p->tol * h / T : p->tol;
            double ratio = need_est && est > 0.0 ? allowed / est : 1e3;
            double fac = 0.9 * pow(ratio, per_unit ? 1.0 / q : 1.0 / (q + 1));
            double fold_rate = t > 0.0 ? folds_total / t : 0.0;
            int folds = inv > fold_budget && inv > 4.0 * fold_rate * h;
            if (!finite || folds || (need_est && est > allowed)) {
                memcpy(c.X, c.Xold, n3 * sizeof(double));
                in_step = 0;
                st->rejected++;
                rejected_here++;
                h *= (!finite || folds) ? 0.25 : fmax(0.2, fac);
                if (h < 1e-14 * T) {
                    rc = mcf__fail(err, MCF_ENUMERIC, "adaptive: step size underflow at t = %g (%s)", t,
                                   !finite ? "non-finite positions" : folds ? "folded faces" : "error estimate");
                    goto done;
                }
                continue;
            }
            rc = MCF_OK;
            folds_total += inv;
            /* desbrun2's second step reuses h: BDF2 starts at ratio 1 */
            h_next = per_unit && hist.nhist == 0 ? h : h * fmin(2.0, fmax(0.2, fac));
        } else {
            if (rc != MCF_OK)
                goto done;
            /* An explicit scheme past its limit need not overflow: lambda
             * falls like 1/size^2 as the mesh crumples, so the result can
             * stay finite. MCF never increases the area, the instability
             * does, fast: more than 1.5x the starting area is taken as it
             * (a stable step may flip slivers, so folds prove nothing). */
            double grown = 0.0;
            if (finite && c.si->is_explicit && p->scheme != MCF_TAUBIN) {
                /* the step's own pass over the faces (ops_LX) left the
                 * area of the state before it: no extra geometry pass;
                 * the last state is checked after the loop */
                grown = c.area_sum / area0;
            }
            if (!finite || grown > 1.5) {
                rc = unstable(&c, err, !finite ? k + 1 : k, h, !finite ? 0.0 : grown);
                goto done;
            }
        }
        /* accepted: shift the history by rotating buffers (Xold is
         * rewritten at the start of every step) */
        double *spare = c.Xprev2;
        c.Xprev2 = c.Xprev;
        c.Xprev = c.Xold;
        c.Xold = spare;
        if (check_inv) {
            spare = c.fn; /* a rescale keeps normal directions */
            c.fn = c.fn2;
            c.fn2 = spare;
        }
        hist.h2 = hist.h1;
        hist.h1 = h;
        hist.nhist++;
        t += h;
        st->dt_min = fmin(st->dt_min, h);
        st->dt_max = fmax(st->dt_max, h);
        h = h_next;
        if (p->rescale != MCF_RESCALE_NONE)
            rescale(&c, area0, vol0);
        if (p->log_steps && st->log && (p->adaptive || k < nsteps)) {
            double maxd = 0.0;
            for (size_t i = 0; i < nv; i++) {
                double d[3];
                mcf__sub3(c.X + 3 * i, c.Xprev + 3 * i, d);
                maxd = fmax(maxd, mcf__dot3(d, d));
            }
            log_step(&c, c.X, k, t, hist.h1, rejected_here, scale, cen, sqrt(maxd));
        }
        rejected_here = 0;
        in_step = 0;
        k++;
        st->steps = k;
        st->t_final = t;
        if (p->progress &&
            p->progress(p->progress_ctx, k, t, hist.h1, mcf__area_volume(c.X, c.F, c.nf, NULL, NULL) / (scale * scale))) {
            rc = mcf__fail(err, MCF_ECANCELED, "canceled by the progress callback at step %d", k);
            goto done;
        }
    }
    rc = MCF_OK;
done:
    /* m gets the last accepted state in input units: the state before a
     * failed step, or the untouched input when no step was accepted */
    if (rc != MCF_OK && in_step && c.Xold)
        memcpy(c.X, c.Xold, n3 * sizeof(double));
    if (rc != MCF_OK && st->steps == 0) {
        memcpy(c.X, X_in, n3 * sizeof(double));
    } else if (p->normalize) {
        for (size_t i = 0; i < nv; i++)
            for (int d = 0; d < 3; d++)
                c.X[3 * i + d] = c.X[3 * i + d] / scale + cen[d];
        /* fixed vertices come back to the bit, not through (x-c)*s/s+c */
        for (size_t i = 0; c.fixed && i < nv; i++)
            if (c.fixed[i])
                memcpy(c.X + 3 * i, X_in + 3 * i, 3 * sizeof(double));
    }
    st->area1 = mcf__area_volume(m->X, m->F, m->nf, NULL, &st->volume1);
    /* the growth check of a fixed explicit run's last state (the loop
     * checked every state before it) */
    if (rc == MCF_OK && !p->adaptive && c.si->is_explicit && p->scheme != MCF_TAUBIN &&
        !is_fairing(p->scheme) && st->steps > 0 && st->area1 > 1.5 * area_in)
        rc = unstable(&c, err, st->steps, st->dt_max, st->area1 / area_in);
    if (st->dt_min == INFINITY || st->steps == 0)
        st->dt_min = 0.0;
    if (rc == MCF_OK)
        flow_warnings(&c, X_in, st);
    st->peak_bytes = c.bytes + mcf__chol_bytes(c.chol);
    st->time_total = mcf_now() - t_start;
    free(X_in);
    ctx_free(&c);
    if (!stats)
        mcf_flow_stats_free(&st_local);
    return rc;
}

void mcf_flow_stats_free(mcf_flow_stats *s)
{
    if (!s)
        return;
    free(s->log);
    free(s->sure);
    memset(s, 0, sizeof *s);
}
