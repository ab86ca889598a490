/* SPDX-License-Identifier: MIT */
/*
 * mcf.h - the public interface of libmcf, the numeric core of mcfd.
 *
 * libmcf smooths triangle meshes by mean curvature flow (MCF). It is a pure
 * C11 library: it depends on libc, libm and CHOLMOD only, does no I/O, keeps
 * no mutable globals and is reentrant. Arrays come in, arrays go out.
 *
 * Conventions (docs/MATH.md): positions X are n x 3 doubles stored
 * row-major (x0 y0 z0 x1 ...); faces are m x 3 int32 vertex indices. The
 * cotan stiffness L is positive semi-definite, the lumped mass M diagonal,
 * the MCF velocity is F(X) = -M^-1 L X, the mean curvature H = (k1+k2)/2 is
 * positive on a sphere with outward normals, and Delta X = -2 H n.
 *
 * Errors: every fallible call returns an mcf_status and, when the caller
 * passes a non-NULL mcf_error, writes a one-line explanation into it. No
 * global error state exists. Out-parameters are left unchanged on failure.
 */
#ifndef MCF_H
#define MCF_H

#include <stddef.h>
#include <stdint.h>
#ifndef __cplusplus
#include <stdatomic.h>
#endif

#ifdef __cplusplus
extern "C" {
#endif

/* ---------------------------------------------------------------- errors */

/* One table yields the enum, mcf_strerror() and the server's HTTP map.
 * Codes are only ever appended, never renumbered. */
#define MCF_ERRORS(X)                                                  \
    X(OK, 0, "success")                                                \
    X(ENOMEM, 1, "out of memory")                                      \
    X(EINVAL, 2, "invalid argument")                                   \
    X(EMESH, 3, "malformed mesh")                                      \
    X(ENOTPOSDEF, 4, "system matrix not positive definite")            \
    X(ELIMIT, 5, "input exceeds a configured limit")                   \
    X(EDECODE, 6, "cannot decode input")                               \
    X(ENUMERIC, 7, "numerical failure (NaN, divergence or inverted faces)") \
    X(ECANCELED, 8, "canceled")                                        \
    X(ENOCONV, 9, "iteration did not converge")                        \
    X(EFORMAT, 10, "unsupported format")                               \
    X(EIO, 11, "input/output error")

typedef enum {
#define MCF_X_(name, code, text) MCF_##name = code,
    MCF_ERRORS(MCF_X_)
#undef MCF_X_
} mcf_status;

#define MCF_ERRMSG_SIZE 256

/* Caller-owned error detail. status repeats the returned code. */
typedef struct {
    mcf_status status;
    char msg[MCF_ERRMSG_SIZE];
} mcf_error;

/* Fills err (if non-NULL) with code and a printf-formatted one-line
 * message (truncated to MCF_ERRMSG_SIZE) and returns code, so a failure is
 * one line in any layer: return mcf_error_set(err, MCF_EINVAL, "dt %g", dt); */
mcf_status mcf_error_set(mcf_error *err, mcf_status code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/* Static text for a code ("unknown error" for an unknown one). */
const char *mcf_strerror(mcf_status s);
/* The symbolic name of a code, e.g. "EMESH". */
const char *mcf_status_name(mcf_status s);

/* ------------------------------------------------------------------ mesh */

typedef struct mcf_mesh mcf_mesh;

/* Copies nv positions (3*nv doubles) and nf faces (3*nf ints). Refuses
 * (EMESH) an index out of [0, nv), a non-finite coordinate, nv == 0 or
 * nf == 0, with the first offending element named in err. Everything else
 * (degenerate, duplicate, non-manifold faces, unreferenced vertices) is
 * accepted and reported by mcf_mesh_inspect(). */
mcf_mesh *mcf_mesh_new(int nv, const double *X, int nf, const int32_t *F,
                       mcf_error *err);
mcf_mesh *mcf_mesh_dup(const mcf_mesh *m, mcf_error *err);
void mcf_mesh_free(mcf_mesh *m); /* accepts NULL */

int mcf_mesh_nvertices(const mcf_mesh *m);
int mcf_mesh_nfaces(const mcf_mesh *m);
/* Lends the arrays; valid until the mesh is freed. Positions may be
 * written through mcf_mesh_positions_mut (same length, 3*nv). */
const double *mcf_mesh_positions(const mcf_mesh *m);
double *mcf_mesh_positions_mut(mcf_mesh *m);
const int32_t *mcf_mesh_faces(const mcf_mesh *m);

/* A closed icosphere of the given radius: level 0 is the icosahedron
 * (12 vertices), each level quadruples the faces: nv = 10*4^level + 2
 * (level 7: 163,842 vertices). level in [0, 10]. */
mcf_mesh *mcf_mesh_new_icosphere(int level, double radius, mcf_error *err);

/* What validation found. Counts are exact; genus is -1 where it is not
 * meaningful (non-manifold or several components: see genus_sum). */
typedef struct {
    int nv, nf, ne;                 /* vertices, faces, unique edges */
    int unreferenced;               /* vertices used by no face */
    int degenerate_faces;           /* zero area or repeated index */
    int duplicate_faces;            /* same vertex set as an earlier face */
    int boundary_edges;             /* edges with exactly one face */
    int boundary_loops;             /* connected boundary curves */
    int nonmanifold_edges;          /* edges with more than two faces */
    int nonmanifold_vertices;       /* face fan splits into several pieces */
    int components;                 /* connected through faces */
    int euler;                      /* chi = V - E + F (referenced V) */
    int genus;                      /* (2 - chi - b)/2 if manifold & 1 comp */
    int manifold;                   /* no non-manifold edge or vertex */
    int closed;                     /* no boundary edge */
    int inconsistent_orientation;   /* interior edges traversed same way */
    double area, volume;            /* volume: signed, divergence theorem */
    double mean_edge, min_edge, max_edge;
    double bbox_min[3], bbox_max[3];
} mcf_mesh_info;

/* Fills info. Cost linear in the mesh (bucket sorts by vertex). Fails only
 * on allocation (ENOMEM). */
mcf_status mcf_mesh_inspect(const mcf_mesh *m, mcf_mesh_info *info,
                            mcf_error *err);

/* Total area and signed enclosed volume (exact for closed meshes). */
double mcf_mesh_area(const mcf_mesh *m);
double mcf_mesh_volume(const mcf_mesh *m);
/* Total area, returned, and the area centroid (the area-weighted mean of
 * the face centroids) into centroid; the origin when the area is 0. The
 * point the flow's normalization centres on (mcf_flow_params.normalize):
 * a caller that wants the flow's working units uses
 * (x - centroid) / sqrt(area). */
double mcf_mesh_area_centroid(const mcf_mesh *m, double centroid[3]);

/* Adds Gaussian noise along the area-weighted vertex normals with
 * sigma = rho * mean edge length, from a 64-bit seed (deterministic on
 * every platform: the generator is part of libmcf). */
mcf_status mcf_mesh_add_noise(mcf_mesh *m, double rho, uint64_t seed,
                              mcf_error *err);

/* ------------------------------------------------------------- operators */

typedef enum { MCF_LAPLACIAN_COTAN = 0, MCF_LAPLACIAN_UNIFORM = 1 } mcf_laplacian;
typedef enum { MCF_MASS_BARYCENTRIC = 0, MCF_MASS_VORONOI = 1 } mcf_mass;

/* The stiffness matrix L (full symmetric CSR, sorted columns, diagonal
 * included) and the lumped mass m (length n) of a mesh. Caller owns the
 * arrays: release with mcf_operator_free. Cotan weights of degenerate
 * triangles are guarded by intrinsic mollification (see mcf_laplacian.c):
 * entries are always finite and L stays PSD. */
typedef struct {
    int n;
    int *rowptr;   /* n + 1 */
    int *col;      /* rowptr[n] */
    double *val;   /* rowptr[n] */
    double *mass;  /* n */
} mcf_operator;

mcf_status mcf_operator_build(const mcf_mesh *m, mcf_laplacian lap,
                              mcf_mass mass, mcf_operator *out,
                              mcf_error *err);
void mcf_operator_free(mcf_operator *op); /* accepts zeroed struct */

/* Largest eigenvalue of M^-1 L by power iteration (at most 200 iterations,
 * relative change below 1e-6), the quantity explicit step limits use. */
mcf_status mcf_lambda_max(const mcf_mesh *m, mcf_laplacian lap, mcf_mass mass,
                          double *lambda, mcf_error *err);

/* ------------------------------------------------------------- curvature */

/* Per-vertex quantities; each output array is caller-allocated, may be
 * NULL when not wanted. N: 3*nv unit area-weighted normals. H: nv signed
 * mean curvature (H = <M^-1 L X, n>/2, since -M^-1 L X = -2 H n). K: nv Gaussian curvature by angle
 * deficit over the barycentric mass (0 on boundary vertices). A2: nv
 * |A|^2 = k1^2 + k2^2 = 4H^2 - 2K, never negative: where the discrete
 * estimates give H^2 < K (cone-like vertices) the discriminant H^2 - K is
 * clamped at 0, so A2 = 2H^2 there. Unreferenced vertices get 0. */
mcf_status mcf_curvature(const mcf_mesh *m, double *N, double *H, double *K,
                         double *A2, mcf_error *err);

/* Tangential gradient of a per-vertex scalar field f (nv): the area-
 * weighted average of the face gradients of its linear interpolant, into
 * caller-allocated G (3*nv). E.g. grad H with H from mcf_curvature. */
mcf_status mcf_gradient(const mcf_mesh *m, const double *f, double *G,
                        mcf_error *err);

typedef struct {
    double min, max, mean, rms, p05, p50, p95;
} mcf_stats;

typedef struct {
    mcf_stats H, K, A2;
    double total_K;          /* sum K_i m_i over interior vertices */
    double gauss_bonnet;     /* total_K + boundary geodesic term - 2 pi chi */
    int euler;
} mcf_curvature_summary;

mcf_status mcf_curvature_summarize(const mcf_mesh *m,
                                   mcf_curvature_summary *out, mcf_error *err);

/* --------------------------------------------------------------- schemes */

typedef enum {
    MCF_EULER = 0,
    MCF_TAYLOR2,
    MCF_DESBRUN,
    MCF_NEUMANN2,
    MCF_DESBRUN2,
    MCF_ROS2,
    MCF_RICHARDSON,
    MCF_IMPLICIT,
    MCF_HUISKEN2,
    MCF_ARC,
    MCF_CMCF,
    MCF_LINEAR,
    MCF_TAUBIN,
    MCF_FAIRING,
    MCF_FAIRING_EXPLICIT,
    MCF_FAIRING_FEATURE,
    MCF_NSCHEMES
} mcf_scheme;

typedef struct {
    const char *name;          /* "desbrun2" */
    const char *title;         /* one line */
    int order;                 /* temporal order on MCF (0: not a flow) */
    int is_explicit;           /* needs no linear solve */
    double stability;          /* explicit: dt <= stability / lambda_max;
                                  0: unconditional */
    int solves_per_step;       /* right-hand-side blocks (3 columns each) */
    int factorizations_per_step;
    int has_estimate;          /* supports adaptive stepping */
    const char *estimate;      /* how the local error is estimated */
    const char *best_use;
} mcf_scheme_info;

/* Static description; NULL for an out-of-range scheme. */
const mcf_scheme_info *mcf_scheme_get(mcf_scheme s);
/* MCF_OK and *out set when name is a scheme's name, else EINVAL. */
mcf_status mcf_scheme_from_name(const char *name, mcf_scheme *out);

/* ------------------------------------------------------------------ flow */

typedef enum { MCF_BOUNDARY_FIXED = 0, MCF_BOUNDARY_FREE = 1 } mcf_boundary;
typedef enum { MCF_RESCALE_NONE = 0, MCF_RESCALE_VOLUME, MCF_RESCALE_AREA } mcf_rescale;

/* The cancel flag of a run: another thread (or a signal handler) stores
 * non-zero, mcf_flow_run loads it before every step. A C11 atomic, so the
 * store and the load are no data race (a lock-free atomic_int is also
 * safe to store from a signal handler). C++ units, which only pass the
 * parameters through, see an int of the same size. */
#ifndef __cplusplus
typedef atomic_int mcf_cancel_flag;
#else
typedef int mcf_cancel_flag;
#endif

/* Called after every accepted step. Return non-zero to cancel the run
 * (mcf_flow_run then returns MCF_ECANCELED and leaves the mesh at the last
 * accepted step). energy is the surface's area after the step in input
 * units (the Dirichlet energy 1/2 tr(X^T L X) of the cotan Laplacian),
 * the step log's (mcf_step_log.area) when the run keeps one
 * (log_steps); NaN when it keeps none: a diagnostic costs nothing unless
 * asked for (the area is a pass over all faces, 10% of a default request
 * on a 7M scan, where a pass of the filter is about two).
 * During the run the mesh's positions are the working copy: with
 * normalize on they are (x - c) / sqrt(A0) for the input's area centroid
 * c and area A0 (input units only after mcf_flow_run returns). */
typedef int (*mcf_progress_fn)(void *ctx, int step, double t, double dt,
                               double energy);

/* Called at the milestones of a run with the share of its work done, in
 * [0, 1] and never decreasing: after every step of a flow (t / T), and
 * after each phase of the fairing filters (the noise reading, the
 * factorization, every step or pass, the second filter of the default's
 * pick, the output). The share is the core's estimate from the phases'
 * measured costs (mcf_fairing.c), for a progress line and an estimate of
 * the time left; phase is a static string naming what just ended
 * ("spikes", "graph", "creases", "setup", "noise", "factor", "probes",
 * "steps", "passes", "output"; the long ones, the creases and the noise
 * reading, also after their own stages, under the same name). Cancel with
 * mcf_flow_params.cancel. */
typedef void (*mcf_work_fn)(void *ctx, const char *phase, double done);

/* The amount of smoothing. MCF moves a surface by about sqrt(t) in time t,
 * so the amount is naturally measured in the mesh's own resolution: with
 * h the mean edge length (in the working units), a total time
 * strength^2 * h^2 diffuses the positions over about `strength` mean
 * edges, whatever the mesh's size or units. How time, dt, iterations and
 * strength combine (the first rule that applies):
 *   time > 0                  total time = time
 *   iterations > 0 and dt set total time = iterations * dt (dt or dt_auto)
 *   otherwise                 total time = strength^2 * h^2
 * and the steps: dt set -> ceil(total / dt) steps of total/steps;
 * otherwise `iterations` steps (MCF_DEFAULT_STEPS when 0) of equal size.
 * An adaptive run starts from dt (or total / iterations) when either is
 * given, else from the total time, and ends at the total time.
 * `taubin` is a filter: it runs `iterations` passes (MCF_DEFAULT_STEPS
 * when 0) and ignores the amount. strength_auto estimates the noise and
 * picks the time that minimizes the expected error (mcf_auto.c), in place
 * of strength. The default strength was chosen on real
 * scans with injected noise (lab/results/amount.md): it reduces
 * the error at every noise level measured and harms none. */
#define MCF_DEFAULT_STRENGTH 0.33
#define MCF_DEFAULT_STEPS 10

/* The fairing filters (`fairing`, `fairing_explicit`; mcf_fairing.c) are
 * no flows: they take no time, dt, dt_auto or adaptive (EINVAL), and
 * ignore strength, strength_auto, laplacian, mass and rescale (they work
 * on the uniform graph Laplacian, along the normals). The amount is a
 * step count K: `fairing` runs K implicit bi-Laplacian steps
 *     (D + L D^-1 L) x' = D x   (on the free vertices, L = D - A the
 *                                 uniform graph Laplacian, one
 *                                 factorization per run),
 * `fairing_explicit` K Taubin passes (lambda 0.5, mu -0.53) on the same
 * graph, no factorization. K is `iterations` when set; otherwise the K
 * that minimizes Stein's unbiased risk estimate of the result's error for
 * Gaussian noise of deviation noise_sigma mean edges along the normals
 * (0: mcf_noise_estimate's), evaluated after every step up to the first
 * power of two past K* + 5 (K* the best so far), at most MCF_FAIRING_MAX_STEPS steps (implicit) or
 * MCF_FAIRING_MAX_PASSES passes (explicit) and max_steps. A mesh without
 * noise gets K = 0: it is returned as it came. With the automatic
 * amount the result is SURE's best combination X0 + sum_j c_j (Y_kj -
 * X0) of the positions after the last MCF_FAIRING_COMB powers of two kj
 * of steps when its SURE is lower than Y_K's (docs/fairing.md). The
 * result moves every free vertex along the normal of the filtered
 * surface only, and a guard takes back every face it would fold (turned
 * against the input's face and lying backwards in its neighbourhood):
 * the filtered positions first, then halfway to the input, then the
 * input's. With fairing_pick (the default request's `fairing`) and the
 * automatic amount the explicit passes run too and replace the implicit
 * result along the normals when their SURE is lower by one standard
 * error (docs/fairing.md; mcf_flow_stats.filter_explicit).
 * `fairing_feature` (mcf_feature.c) is the feature-aware stage for
 * piecewise-smooth shapes: bilateral normal filtering of the face normals
 * (Zheng et al. 2011) and the vertex update of Sun et al. 2007, the range
 * kernel's width and both iterations chosen among a few candidates by SURE
 * with a Monte-Carlo divergence (Ramani et al. 2008), for the noise level
 * noise_sigma (0: estimated). It takes no iterations (EINVAL). Its result
 * (along its normals, moves bounded and guarded as above) is taken when
 * its SURE's gain over the input is twice its standard error, else the
 * input comes back; mcf_flow_stats.feature* report it. The default
 * request (fairing_pick, automatic amount) runs the same stage after the
 * linear fairing when the creases it holds are 10-50% of its moving
 * vertices, and takes its result when its SURE beats the linear result's
 * (docs/fairing.md, "In the default request"). */
#define MCF_FAIRING_MAX_STEPS 200
#define MCF_FAIRING_MAX_PASSES 2000
/* the fairing filters combine the positions after the last
 * MCF_FAIRING_COMB powers of two of steps (mcf_flow_stats.comb_*) */
#define MCF_FAIRING_COMB 4

typedef struct {
    mcf_scheme scheme;        /* default MCF_DESBRUN2 */
    double dt;                /* step (dimensionless if normalize); 0: not
                                 set, derived from the amount (see above) */
    int dt_auto;              /* explicit schemes: 0.45*stability/lambda_max
                                 (euler: 0.9/lambda_max, no sign change) */
    int iterations;           /* steps; 0: not set (see above) */
    double time;              /* total time; > 0 overrides everything */
    double strength;          /* diffusion length in mean edges, > 0
                                 (default MCF_DEFAULT_STRENGTH) */
    double noise_sigma;       /* fairing: the noise (standard deviation
                                 along the normals, in mean edges) whose
                                 removal SURE optimizes; 0: estimated */
    int fairing_pick;         /* `fairing` with the automatic amount: also
                                 run the explicit passes (as
                                 `fairing_explicit`) and keep theirs when
                                 their SURE is clearly lower (the default
                                 request's; mcf_flow_stats.filter_explicit
                                 says which) */
    int fairing_robust;       /* the fairing filters with the automatic
                                 amount: first repair the spikes (vertices
                                 far off the surface their neighbours
                                 define, mcf_flow_stats.spikes_repaired),
                                 and take back the faces without area in
                                 the input that the output turned against
                                 the filtered normals
                                 (mcf_flow_stats.flips_repaired); where it
                                 found creases, run the filter again with
                                 none held and take that run when SURE says
                                 so (crease_vertices then 0); the default
                                 request's. With the explicit passes that
                                 choice is judged on the submesh near the
                                 creases when they are few, and only the
                                 winner's passes run over the whole mesh
                                 (docs/fairing.md; crease_look_near) */
    int fairing_look_whole;   /* tests and the lab: that choice judged on
                                 the whole mesh, both runs in full, as
                                 before the submesh (its reference) */
    int strength_auto;        /* 1: the amount from the mesh's own noise
                                 (mcf_auto.c: a noise estimate and Stein's
                                 unbiased risk estimate); replaces strength */
    mcf_boundary boundary;    /* default fixed */
    const int32_t *fixed;     /* extra fixed vertex indices (borrowed) */
    int nfixed;
    mcf_rescale rescale;      /* about the area centroid, after each step;
                                 volume needs a closed mesh (EINVAL) */
    int normalize;            /* default 1: centre, unit area, undo after */
    mcf_laplacian laplacian;
    mcf_mass mass;
    int adaptive;             /* needs a scheme with has_estimate */
    double tol;               /* adaptive, relative to the unit-area size
                                 (M-weighted RMS): desbrun2, ros2: the
                                 error at T, as 0.3 tol per unit time of
                                 their own (Milne) local estimate
                                 (measured 0.02-0.27 tol on scans:
                                 docs/numerics.md); richardson, desbrun:
                                 local error per step of the first-order
                                 companion (global <= steps*tol); the
                                 max over the vertices too, with 20x the
                                 RMS's share (desbrun2, richardson,
                                 desbrun; not ros2), but through a local
                                 singularity (a max estimate that does
                                 not fall with the step), where the RMS
                                 alone decides */
    int max_steps;            /* hard cap on steps, rejected ones included
                                 (adaptive); ELIMIT naming max_steps when
                                 a run would need more */
    double implicit_tol;      /* `implicit`: Picard stop, relative */
    int implicit_maxit;
    int log_steps;            /* keep the per-step log in the stats */
    mcf_progress_fn progress;
    void *progress_ctx;
    mcf_work_fn work;         /* may be NULL; called with progress_ctx */
    const mcf_cancel_flag *cancel; /* loaded before every step; may be NULL */
    int threads;              /* threads of the fairing filters' passes
                                 (0 or 1: the caller's only); the result
                                 is one thread's bit for bit. The caller
                                 owns the policy: mcf gives its cores,
                                 mcfd the cores no other job holds */
} mcf_flow_params;

/* Below this many vertices a run's loops stay on the caller's thread
 * whatever mcf_flow_params.threads says (starting threads would cost more
 * than they give): a caller sharing cores gives such a run one. */
#define MCF_THREADS_MIN 20000

/* Fills p with the defaults: desbrun2, the amount from the mesh
 * (strength MCF_DEFAULT_STRENGTH in MCF_DEFAULT_STEPS steps: dt, time
 * and iterations unset), fixed boundary, no rescale, normalize on, cotan,
 * barycentric, tol 1e-4, max_steps 1000, implicit_tol 1e-10,
 * implicit_maxit 200. */
void mcf_flow_params_init(mcf_flow_params *p);

/* Checks ranges and combinations (e.g. adaptive with a scheme that has no
 * estimate, a fixed index out of range); EINVAL naming the field. */
mcf_status mcf_flow_params_check(const mcf_flow_params *p, int nv,
                                 mcf_error *err);

/* mcf_mesh_add_noise on the vertices a run with parameters p would move
 * only: its fixed vertices (p's list, the boundary with boundary=fixed,
 * unreferenced vertices) keep their positions to the bit, so a noisy
 * experiment fixes what the flow fixes. The other vertices get exactly
 * mcf_mesh_add_noise's draws. EINVAL for parameters that do not check
 * (mcf_flow_params_check), ENOMEM. */
mcf_status mcf_flow_add_noise(mcf_mesh *m, const mcf_flow_params *p,
                              double rho, uint64_t seed, mcf_error *err);

/* The standard deviation of the noise along the normals of m, in m's
 * units, estimated from m alone (mcf_auto.c: a second-order high-pass
 * along the normals of 10 uniform Taubin passes of m, calibrated by its
 * response to unit noise, as a median over the vertices a run with p
 * would move, of degree >= 3: the fixed ones carry no noise). What
 * strength=auto and the fairing filters use. EINVAL for parameters that
 * do not check, ENOMEM. */
mcf_status mcf_noise_estimate(const mcf_mesh *m, const mcf_flow_params *p, double *sigma,
                              mcf_error *err);

typedef struct {
    double t, dt;
    double area, volume;      /* input units; the volume is volume0/1's
                                 (mcf_mesh_volume's), about the origin */
    double max_disp;          /* largest vertex displacement this step */
    double solve_s;           /* seconds in factorize + solve this step */
    int rejected;             /* adaptive attempts rejected before it */
} mcf_step_log;

/* What a finished run can warn about (mcf_flow_stats.warnings): the
 * result may not be what the caller wanted even though the flow itself
 * succeeded. Thresholds are in mcf_flow.c (flow_warnings). */
#define MCF_WARNINGS(X)                                                   \
    X(FOLDS, 0, "folds", "the flow folded faces the input did not have") \
    X(EDGE_COLLAPSE, 1, "edge_collapse",                                  \
      "the shortest edge collapsed by orders of magnitude")               \
    X(AREA_LOSS, 2, "area_loss", "a large part of the area was lost")    \
    X(LITTLE_SMOOTHING, 3, "little_smoothing",                            \
      "the run covered a negligible amount of smoothing")

enum {
#define MCF_X_(name, bit, id, text) MCF_WARN_##name = 1u << bit,
    MCF_WARNINGS(MCF_X_)
#undef MCF_X_
};

/* The symbolic name ("folds", "edge_collapse", ...) and text of one
 * warning bit; NULL for anything else. */
const char *mcf_warning_name(unsigned bit);
const char *mcf_warning_text(unsigned bit);

/* What the amount assumed of the noise (mcf_flow_stats.noise_kind). */
typedef enum {
    MCF_NOISE_NONE = 0,      /* nothing read: the amount was set */
    MCF_NOISE_GIVEN,         /* the level given (noise_sigma) */
    MCF_NOISE_NORMAL,        /* read: along the normals only */
    MCF_NOISE_ISOTROPIC,     /* read: along the normals and in the tangent
                                planes (there at most as much) */
    MCF_NOISE_ONE_DIRECTION  /* read: along one direction (one viewpoint's
                                depth noise), split into its parts along
                                the normals and in the tangent planes */
} mcf_noise_kind;

typedef struct {
    int steps;                /* accepted steps (fairing: K, the steps or
                                 passes the result is made of) */
    int rejected;             /* adaptive rejections */
    int solves;               /* 3-column right-hand-side solves */
    int factorizations;       /* numeric factorizations */
    int picard_iterations;    /* `implicit` only: total inner iterations */
    double t_final;
    double dt_first, dt_min, dt_max;
    double lambda_max;        /* when estimated (dt_auto), else 0 */
    double error_estimate;    /* adaptive: the sum of the accepted steps'
                                 local error estimates (M-weighted RMS
                                 relative to the unit-area size, as tol),
                                 the run's own bound on its error at
                                 t_final; else 0 */
    double area0, area1, volume0, volume1;   /* in input units */
    double time_assemble, time_analyze, time_factorize, time_solve,
           time_total;        /* seconds, monotonic clock */
    double threads_cpu_s;     /* CPU seconds of the threads the run started
                                 besides the caller's (threads > 1: the
                                 passes), CLOCK_THREAD_CPUTIME_ID, added
                                 after each join on the caller's thread: a
                                 progress callback reads it as it grows
                                 (the caller's own CPU is its own clock's) */
    size_t peak_bytes;        /* peak heap held by the solver for this job */
    double factor_nnz;        /* implicit schemes: entries of the Cholesky */
    double factor_flops;      /* factor, flops of one factorization (0 else) */
    double mean_edge;         /* h, working units (unit area if normalize) */
    double t_target;          /* the total time the run was asked to cover
                                 (set, with mean_edge, before the first
                                 progress call: a progress callback may
                                 read them to show a fraction) */
    double strength;          /* sqrt(t_final) / h: what the run did */
    double noise;             /* strength_auto and fairing: the noise
                                 along the normals its amount assumed
                                 (estimated or noise_sigma), in mean
                                 edges of the input; else 0 */
    double *sure;             /* fairing's automatic amount: SURE(K) for
                                 K = 0 .. nsure-1 steps, the estimated
                                 mean squared error per vertex (area
                                 weighted) in squared mean edges; the
                                 minimum is at K = steps. NULL otherwise */
    int nsure;
    double noise_tangential;  /* fairing: the tangential noise its
                                 relaxation assumed, in mean edges */
    int tangential_steps;     /* fairing: the steps whose tangential
                                 displacement the result took (0: none) */
    int ncomb;                /* fairing: the result along the normals is
                                 X0 + sum_j comb_weight[j] (Y_comb_steps[j]
                                 - X0), Y_K the positions after K steps,
                                 for j < ncomb (SURE's best combination);
                                 0: Y_steps itself */
    int comb_steps[MCF_FAIRING_COMB];     /* the weights SURE found, */
    double comb_weight[MCF_FAIRING_COMB]; /* taken or not (steps 0: none) */
    int filter_explicit;      /* fairing: 1 when the result is the
                                 explicit lambda|mu passes' (always for
                                 `fairing_explicit`; `fairing` with the
                                 automatic amount when their SURE is
                                 lower), 0 the implicit steps' */
    int feature_ran;          /* fairing (the default request) and
                                 fairing_feature: the feature-aware stage
                                 ran (bilateral normal filtering and a
                                 vertex update, mcf_feature.c) */
    int feature;              /* 1 when the result is that stage's */
    double feature_sigma_r;   /* its candidate of least SURE: the range */
    int feature_normal_iters; /* kernel's width (unit normals), the normal */
    int feature_vertex_iters; /* filter's and vertex update's iterations */
    double feature_sure;      /* its SURE and the SURE it was compared */
    double feature_sure_against; /* with (the linear fairing's result, or
                                 the input's), along the same normals, mean
                                 per vertex, squared mean edges */
    double feature_z;         /* the gain in its standard errors */
    double feature_noise;     /* the noise level the stage read from its
                                 candidates' residuals (mean edges; SURE
                                 and the move bound use it) */
    int crease_vertices;      /* fairing: vertices on the creases it kept
                                 (smoothed along them, held for the
                                 surface's filter) */
    int crease_look_near;     /* fairing_robust: 1 when holding the
                                 creases or not was judged on the submesh
                                 near them, 2 near a sample of their
                                 chains (too many for the first), 0 on the
                                 whole mesh (fairing_look_whole) */
    int guard_rounds;         /* fairing: fold-guard rounds that moved a
                                 vertex (0-64, 1-7 measured) */
    int guard_vertices;       /* fairing: vertex moves by the guard */
    int robust;               /* 1 when fairing_robust's stages ran (the
                                 spike repair, the reading of the noise's
                                 direction, the flips' repair) */
    int noise_kind;           /* mcf_noise_kind: what the amount assumed */
    double noise_share;       /* robust: the high-pass vectors' largest
                                 eigenvalue's share (1/3 directions spread
                                 evenly, 1 one direction; the reading
                                 switches to one direction at 0.7) */
    double noise_direction[3]; /* MCF_NOISE_ONE_DIRECTION: the unit
                                 direction read (its sign arbitrary), else
                                 zeros */
    mcf_scheme filter;        /* the filter whose result was taken: the
                                 fairing filters MCF_FAIRING,
                                 MCF_FAIRING_EXPLICIT (filter_explicit) or
                                 MCF_FAIRING_FEATURE (feature); else the
                                 scheme */
    int spikes_repaired;      /* fairing_robust: vertices found far off
                                 the surface their neighbours define and
                                 put back on it before the filter */
    int flips_repaired;       /* fairing_robust: faces without area in the
                                 input that the output gave an orientation
                                 against the filtered normals, taken back
                                 toward the input (on a quantized input
                                 also faces with area it turned against
                                 them) */
    int turned_repaired;      /* fairing_robust: vertices of the output's
                                 faces turned against its smoothed normal
                                 field moved back to their displacement
                                 along that field (their slide along the
                                 surface taken back) */
    unsigned warnings;        /* MCF_WARN_* bits */
    int folded_faces;         /* faces the run folded: turned by more
                                 than 90 degrees against the input's same
                                 face and lying backwards in their
                                 neighbourhood of the result */
    double min_edge_ratio;    /* shortest edge after / before */
    double area_ratio;        /* area1 / area0 */
    mcf_step_log *log;        /* steps entries when log_steps, else NULL;
                                 entry k is written before progress
                                 reports step k + 1 */
    int nlog;
} mcf_flow_stats;

/* Runs the flow on m in place. On success m holds the result. On failure
 * (EINVAL, ENOMEM, ENOTPOSDEF, ENUMERIC, ENOCONV, ECANCELED) m holds the
 * last accepted state (never NaN) and err says why. stats may be NULL;
 * release its log with mcf_flow_stats_free. Not thread-safe per mesh;
 * distinct meshes may be smoothed concurrently. */
mcf_status mcf_flow_run(mcf_mesh *m, const mcf_flow_params *p,
                        mcf_flow_stats *stats, mcf_error *err);
void mcf_flow_stats_free(mcf_flow_stats *s); /* frees log, zeroes */

/* --------------------------------------------------------------- metrics */

typedef struct {
    double rms_m;            /* sqrt(sum m_i |x_i - y_i|^2 / sum m_i), target mass */
    double rms_rel;          /* rms_m / sqrt(target area) */
    double frobenius;        /* ||X - Y||_F (the article's metric) */
    double max_err;          /* max_i |x_i - y_i| */
    double normal_angle_deg; /* mean angle between face normals */
    int inverted_faces;      /* faces whose normal turned > 90 degrees */
} mcf_compare_result;

/* Compares two meshes with the same connectivity (EINVAL otherwise). */
mcf_status mcf_compare(const mcf_mesh *x, const mcf_mesh *target,
                       mcf_compare_result *out, mcf_error *err);

/* Wall clock in seconds (C11 timespec_get, TIME_UTC), for phase timings:
 * it jumps when the system clock is set, so deadlines belong on a
 * monotonic clock of the caller's (mcfd uses CLOCK_MONOTONIC). */
double mcf_now(void);

#ifdef __cplusplus
}
#endif
#endif /* MCF_H */
