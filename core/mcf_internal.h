/* SPDX-License-Identifier: MIT */
/*
 * mcf_internal.h - declarations shared by the files of libmcf, not public.
 *
 * Internal non-static functions carry the mcf__ prefix (libuv's uv__).
 * Nothing here is visible to api/ or server/.
 */
#ifndef MCF_INTERNAL_H
#define MCF_INTERNAL_H

#include "mcf.h"

struct mcf_mesh {
    int nv, nf;
    double *X;   /* 3*nv */
    int32_t *F;  /* 3*nf */
};

/* return mcf__fail(err, MCF_EINVAL, "dt %g", dt): mcf_error_set. */
#define mcf__fail mcf_error_set

/* The run's cancel flag (mcf_flow_params.cancel, may be NULL) set: loaded
 * before every step and, in the fairing filters, between the phases of
 * the set-up too (mcf_fairing.c), so that a run stopped before its first
 * step stops within a phase, not minutes later (the 7M scan's set-up: 70 s
 * of wall at load 10 before its first pass). */
static inline int mcf__cancel_set(const mcf_cancel_flag *cancel)
{
    return cancel && atomic_load_explicit(cancel, memory_order_acquire);
}

/* Overflow-checked allocation helpers: NULL on overflow or failure. */
void *mcf__calloc(size_t n, size_t size);
void *mcf__malloc(size_t n, size_t size);
/* mcf__malloc for large scratch buffers (mcf_bigmem.c): from MCF_BIG_MIN
 * bytes on (Linux), 2 MiB-aligned, the size rounded up to whole 2 MiB and
 * advised for transparent huge pages; freed with free(). mcf__big_slack:
 * the bytes it takes beyond n * size (0 where it is mcf__malloc). */
#define MCF_BIG_MIN ((size_t)1 << 20)
void *mcf__malloc_big(size_t n, size_t size);
size_t mcf__big_slack(size_t n, size_t size);

/* ---- geometry per triangle (mcf_laplacian.c) */

/* The mollification margin delta of a mesh: MCF_MOLLIFY * mean edge. */
#define MCF_MOLLIFY 1e-4
double mcf__mean_edge(const double *X, const int32_t *F, int nf);
/* The closest point to p on the triangle (a, b, c) into q (Ericson, Real-Time
 * Collision Detection, 5.1.5). */
void mcf__closest_on_triangle(const double *p, const double *a, const double *b, const double *c, double *q);

/* Per face f: w[3f+k] = 1/2 cot(angle at corner k), the weight of the edge
 * opposite corner k (vertices F[3f+(k+1)%3], F[3f+(k+2)%3]); area[f] the
 * mollified area. Edge lengths are increased by the per-triangle amount
 * that makes every triangle inequality hold with margin delta (intrinsic
 * mollification, Sharp & Crane 2020), so weights are finite and each
 * triangle's 3x3 stiffness block is PSD. Uniform: every weight 1/2... see
 * mcf_laplacian.c. area may be NULL. */
void mcf__cot_weights(const double *X, const int32_t *F, int nf,
                      mcf_laplacian lap, double delta, double *w,
                      double *area);

/* Lumped mass from per-face areas (barycentric: area/3 per corner) or
 * mixed Voronoi (Meyer 2003), accumulated into mass[nv] (zeroed first). */
void mcf__mass(const double *X, const int32_t *F, int nf, int nv,
               mcf_mass kind, const double *area, double *mass);

/* The explicit step's one pass over the faces: weights and areas (as
 * mcf__cot_weights; either may be NULL when not wanted), barycentric mass
 * (zeroed first) and Y = L X (zeroed first). delta as in mcf__cot_weights.
 * Returns the total (mollified) area. */
double mcf__weights_mass_LX(const double *X, const int32_t *F, int nf, int nv,
                            mcf_laplacian lap, double delta, double *w,
                            double *area, double *mass, double *Y);

/* Y = L X for n x 3 row-major X, from per-face weights, without forming L.
 * Y is zeroed first. */
void mcf__apply_L(const int32_t *F, int nf, int nv, const double *w,
                  const double *X, double *Y);

/* Convenience: weights + mass + L X of a configuration in one call.
 * LX and mass are caller-allocated (3*nv, nv); w/area scratch (3*nf, nf)
 * may be NULL to allocate internally. Returns ENOMEM only. */
mcf_status mcf__laplacian_apply(const double *X, const int32_t *F, int nf,
                                int nv, mcf_laplacian lap, mcf_mass mk,
                                double *LX, double *mass, mcf_error *err);

/* ---- sparse pattern (mcf_laplacian.c)
 * The symmetric matrices of a job (L, M + dt L, ...) share one pattern:
 * upper triangle stored by columns (CSC, rows sorted, diagonal last in
 * each column), which is exactly what CHOLMOD wants with stype = +1.
 * Built once per job; values are refilled by scatter each step. */
typedef struct {
    int n, nnz;
    int *colptr;    /* n + 1 */
    int *rowind;    /* nnz */
    int *diag;      /* n: index of (j,j) */
    int *tri;       /* 3*nf: entry of the edge opposite corner k, -1 when
                       the two vertices coincide (repeated index); NULL
                       unless asked for */
    int *mult;      /* nnz: face sides on each off-diagonal entry (1 on a
                       boundary edge, > 2 on a non-manifold one), 0 on the
                       diagonal */
} mcf__pattern;

/* want_tri: also build the face-corner -> entry map (needed to fill values). */
mcf_status mcf__pattern_build(const int32_t *F, int nf, int nv, int want_tri,
                              mcf__pattern *p, mcf_error *err);
void mcf__pattern_free(mcf__pattern *p);
/* val[nnz] = L's upper values from per-face weights (zeroed first). */
void mcf__pattern_fill_L(const mcf__pattern *p, const int32_t *F, int nf,
                         const double *w, double *val);

/* ---- the SPD solver (mcf_cholesky.c), every factorization in core (the
 * implicit schemes, the automatic amount, the fairing filter): CHOLMOD's
 * supernodal Cholesky of an SPD matrix on a pattern (kept by the caller,
 * unchanged while the solver lives; only n, nnz, colptr and rowind are
 * read): analysis once, then any number of numeric factorizations of
 * values on the pattern (pattern order, nnz) and solves of up to ncol
 * columns at once. */
typedef struct mcf__chol mcf__chol;
mcf__chol *mcf__chol_new(const mcf__pattern *pat, int ncol, mcf_error *err);
void mcf__chol_free(mcf__chol *ch);
/* The symbolic analysis (fill-reducing ordering, supernodes) of the
 * pattern; once (a second call returns MCF_OK). ENOMEM, ELIMIT (too large
 * for CHOLMOD's integers), ENUMERIC. */
mcf_status mcf__chol_analyze(mcf__chol *ch, mcf_error *err);
/* The numeric factorization of val (analysed first). ENOTPOSDEF, ENOMEM,
 * ELIMIT, ENUMERIC; after a failure the next call refactors as usual. */
mcf_status mcf__chol_factorize(mcf__chol *ch, const double *val, mcf_error *err);
/* X = A^-1 B after a successful factorization, for ncol (<= the ncol of
 * mcf__chol_new) columns: entry (k, c) of B and X (may alias) at
 * [k * rs + c * cs] (row-major n x ncol: rs ncol, cs 1; column-major: rs 1,
 * cs n). ENOMEM only, and only above four columns. */
mcf_status mcf__chol_solve(mcf__chol *ch, int ncol, const double *B, size_t rs, size_t cs, double *X,
                           mcf_error *err);
/* The same for n x 3 row-major B and X. */
void mcf__chol_solve3(mcf__chol *ch, const double *B, double *X);
/* Bytes the solver holds (CHOLMOD's count and its own arrays). */
size_t mcf__chol_bytes(const mcf__chol *ch);
/* The pattern it was made for. */
const mcf__pattern *mcf__chol_pattern(const mcf__chol *ch);
/* After the analysis: entries of the factor, flops of a factorization. */
void mcf__chol_size(const mcf__chol *ch, double *nnz, double *flops);

/* ---- threads (mcf_par.c)
 * fn(ctx, lo, hi) on contiguous ranges of [0, n) covering it, on up to
 * nthreads threads (the caller's among them; one below MCF_PAR_MIN
 * items); returns when all are done. Each range must write only its own
 * items: the results are then one thread's bit for bit. Never fails (a
 * thread that cannot start leaves its range to the caller). cpu_s (may
 * be NULL): += the CPU seconds of the threads it started (not the
 * caller's), added on the caller's thread after the join. */
#define MCF_PAR_MIN MCF_THREADS_MIN
typedef void (*mcf__par_fn)(void *ctx, size_t lo, size_t hi);
void mcf__par_for(int nthreads, double *cpu_s, size_t n, mcf__par_fn fn, void *ctx);

/* ---- the uniform graph Laplacian (mcf_graph.c)
 * The vertex adjacency of a mesh, weight 1 per edge: row i of the full
 * symmetric adjacency (distinct neighbours, sorted, no self) is
 * adj[ptr[i] .. ptr[i+1]), so the degree is ptr[i+1] - ptr[i]. */
typedef struct {
    int n;
    int *ptr;   /* n + 1 */
    int *adj;   /* ptr[n] */
} mcf__graph;

#define MCF_TAUBIN_LAMBDA 0.5
#define MCF_TAUBIN_MU (-0.53)

/* The faces at each vertex (CSR): vf[vp[i] .. vp[i + 1]) the faces with a
 * corner at vertex i, in increasing order (a face twice at a vertex it
 * names twice). vp: nv + 2 ints, zeroed by the caller; vf: 3 nf ints. */
void mcf__vertex_faces(const int32_t *F, int nf, int nv, int *vp, int *vf);
/* ENOMEM only; g is zeroed on failure. */
mcf_status mcf__graph_build(const int32_t *F, int nf, int nv, mcf__graph *g, mcf_error *err);
void mcf__graph_free(mcf__graph *g); /* accepts zeroed */
/* out (n x ncol, row-major) = the average of v over each vertex's
 * neighbours; v itself where a vertex has none. out != v. */
void mcf__graph_average(const mcf__graph *g, const double *v, int ncol, double *out);
/* `passes` Taubin passes (x += lambda (avg - x), then x += mu (avg - x),
 * lambda 0.5, mu -0.53) on X (n x ncol) in place; vertices with fixed[i]
 * set (fixed may be NULL) stay. tmp: n x ncol scratch. On nthreads
 * threads (mcf__par_for: the same result as one; cpu_s, may be NULL,
 * += their CPU seconds). */
void mcf__graph_taubin(const mcf__graph *g, const unsigned char *fixed, double *X, int ncol,
                       int passes, double *tmp, int nthreads, double *cpu_s);

/* ---- milestones inside a phase (the fairing's share of work, mcf_work_fn)
 * A long phase (the creases, the noise reading) calls fn(ctx, phase, f)
 * after each of its own stages, f in [0, 1] its share of that phase done
 * and never decreasing; the caller maps it into the run's share. A NULL
 * tick reports nothing. */
typedef struct {
    void (*fn)(void *ctx, const char *phase, double f);
    void *ctx;
} mcf__tick;

static inline void mcf__ticked(const mcf__tick *t, const char *phase, double f)
{
    if (t && t->fn)
        t->fn(t->ctx, phase, f);
}

/* ---- the noise level (mcf_auto.c)
 * The standard deviation sigma (X's units) of Gaussian noise along the
 * normals of X: the second-order high-pass of X along the normals of 10
 * uniform Taubin passes of X, calibrated by its response to unit noise,
 * as the ratio of medians over the free vertices (fixed[i] == 0; fixed may
 * be NULL: none) of degree >= 3; fixed vertices carry no noise. 0 when no
 * vertex qualifies. ENOMEM only. */
mcf_status mcf__noise_level(const double *X, const int32_t *F, int nf, int nv,
                            const unsigned char *fixed, double *sigma, mcf_error *err);
/* The same, and (sigma_t not NULL) the deviation of the noise in the
 * tangent planes, per direction: the same ratio of medians for the length
 * of the tangential part of the second-order high-pass (I - Avg)^2 X. A
 * clean scan's irregular triangles read as 0.02-0.12 mean edges of it. */
/* What shape (not NULL) gets: sigma_rms, the same high-pass's RMS over
 * the vertices within 4 robust deviations, calibrated the same way (it
 * reads noise whose deviation varies over the mesh, such as one
 * viewpoint's depth noise, whose normal component is s |u . n|, where the
 * ratio of medians reads low); direction_share, the largest eigenvalue's
 * share of the sum of the 3D high-pass vectors' outer products over the
 * same vertices (1/3: directions spread evenly; near 1: one direction),
 * and direction its unit eigenvector u; sigma_dir, the deviation of
 * noise along u read from the high-pass vectors' components along u
 * (their exact variance per unit noise: the row norms of (I - Avg)^2),
 * sigma_view its part along the normals (sigma_dir sqrt(mean (u .
 * n)^2)), sigma_view_t its part in the tangent planes per direction
 * (sigma_dir sqrt(mean (1 - (u . n)^2) / 2)); corr and corr_noise, the
 * correlation of the high-pass along the normals with its 1-ring average
 * (over the same vertices) for X and for the calibration's unit noise:
 * about equal when X's high-pass is noise, higher when it is the
 * surface's own. */
typedef struct {
    double sigma_rms;
    double direction_share;
    double sigma_dir, sigma_view, sigma_view_t;
    double direction[3];
    double corr, corr_noise;
} mcf__noise_shape;
/* g: the graph of F when the caller has it (NULL: built here); tick (may
 * be NULL) hears its stages end ("noise") */
mcf_status mcf__noise_levels(const mcf__graph *g, const double *X, const int32_t *F, int nf, int nv,
                             const unsigned char *fixed, double *sigma, double *sigma_t,
                             mcf__noise_shape *shape, const mcf__tick *tick, mcf_error *err);

/* ---- the automatic amount (mcf_auto.c)
 * The time t_best that minimizes SURE for K frozen implicit steps from X
 * (working units, mean edge hbar), and the noise level sigma along the
 * normals it estimated (working units). fixed (nv, may be NULL): the
 * vertices the run holds; moving_mass: the run's mass follows its area
 * (every scheme but `linear`); lend: the run's solver on the run's
 * pattern (for 4 columns: analysed here if not yet, its factor
 * overwritten, so the run refactors before it solves), or NULL. ENOMEM,
 * ENOTPOSDEF, ELIMIT, ENUMERIC. */
mcf_status mcf__auto_time(const double *X, const int32_t *F, int nf, int nv,
                          const unsigned char *fixed, mcf_laplacian lap,
                          mcf_mass mk, int moving_mass, double hbar, int K,
                          mcf__chol *lend, double *t_best,
                          double *sigma, mcf_error *err);
/* Taubin's pass count (0..MCF_AUTO_MAX_PASSES) that minimizes SURE for
 * the passes frozen at X, and sigma as above. ENOMEM. */
#define MCF_AUTO_MAX_PASSES 500
mcf_status mcf__auto_passes(const double *X, const int32_t *F, int nf, int nv,
                            const unsigned char *fixed, mcf_laplacian lap,
                            double hbar, int *passes, double *sigma,
                            mcf_error *err);

/* ---- the fairing filter (mcf_fairing.c)
 * The hook mcf_flow_run gives the filter: called with X NULL before step
 * k + 1 (k steps done) and with the positions X (3*nv, working units)
 * after step k; non-zero cancels the run (ECANCELED). */
typedef int (*mcf__step_hook)(void *ctx, int k, const double *X);

/* Runs `fairing` or `fairing_explicit` (p->scheme) on X (3*nv, working
 * units, mean edge hbar) in place; fixed[i] (nv) holds vertex i. Fills
 * st's steps, noise, sure/nsure, guard_rounds/guard_vertices,
 * factorizations, solves, timings and peak_bytes. On failure X is
 * unchanged. ENOMEM, ENUMERIC, ELIMIT (a factor too large for CHOLMOD),
 * ECANCELED. */
mcf_status mcf__fairing(double *X, const int32_t *F, int nf, int nv, const unsigned char *fixed,
                        const mcf_flow_params *p, double hbar, mcf_flow_stats *st,
                        mcf__step_hook hook, void *hook_ctx, mcf_error *err);

/* ---- exp over an array (mcf_exp.c)
 * x[i] <- exp(x[i]) for n values, within 2 ulp of libm's on [-708, 709]
 * (below -708, and a NaN, give exp(-708); above 709, exp(709)); the same
 * bits with or without AVX2. mcf__exp_scalar: one value, the same bits. */
void mcf__exp_array(double *x, size_t n);
double mcf__exp_scalar(double x);

/* ---- the feature-aware stage (mcf_feature.c)
 * Bilateral normal filtering of the face normals (Gaussian spatial and
 * range kernels over the faces sharing a vertex, Zheng et al. 2011), then
 * Sun et al.'s vertex update, on a mesh's connectivity. */
typedef struct mcf__bnf mcf__bnf;
/* The face neighbourhoods of F and the spatial width (the mean distance
 * of neighbouring centroids of X). ENOMEM, ELIMIT. */
mcf__bnf *mcf__bnf_new(const double *X, const int32_t *F, int nf, int nv, mcf_error *err);
void mcf__bnf_free(mcf__bnf *b); /* accepts NULL */
size_t mcf__bnf_bytes(const mcf__bnf *b);
/* The face normals and spatial weights of X, the filter's start. */
void mcf__bnf_start(mcf__bnf *b, const double *X);
/* nit more iterations of the normal filter with range width sigma_r
 * (on |n_i - n_j|); returns the normals (3*nf, valid until the next call). */
const double *mcf__bnf_normals(mcf__bnf *b, double sigma_r, int nit);
/* vit vertex updates of Y (3*nv, in place) toward the planes of the face
 * normals n (3*nf); vertices with fixed[i] (may be NULL) stay. */
void mcf__bnf_vertices(mcf__bnf *b, const double *n, const unsigned char *fixed, int vit, double *Y);
/* The same with the vertex tensors S (6*nv: sum over a vertex's faces of
 * n_f n_f', upper triangle by rows) of n made once by mcf__bnf_tensors,
 * for runs that go on with the same normals. */
void mcf__bnf_tensors(const mcf__bnf *b, const double *n, double *S);
void mcf__bnf_vertices_s(mcf__bnf *b, const double *n, const double *S, const unsigned char *fixed, int vit,
                         double *Y);
/* All three from X into Y. */
void mcf__bnf_run(mcf__bnf *b, const double *X, const unsigned char *fixed, double sigma_r, int nit, int vit,
                  double *Y);

/* What SURE sums over and what the feature stage is compared with. */
typedef struct {
    int nfree;                /* the vertices SURE sums over */
    const int *vert;          /* their indices */
    const double *w;          /* nv: their weights (mean 1) */
    const double *probe;      /* nprobe x nfree Rademacher probes */
    int nprobe;
    double s, s2_rel;         /* the noise level and its square's relative
                                 standard error */
    int s_known;              /* s is known (quantized positions), not
                                 read again from the residuals */
    const double *Ylin;       /* the linear fairing's result (3*nv), or
                                 NULL: the input */
    const double *X0;         /* what Ylin's displacement is measured from */
    const double *trlin;      /* nprobe: the probes' weighted traces of
                                 Ylin's filter */
    double lin_penalty;       /* added to Ylin's SURE (sum w units) */
    double min_z;             /* the gain over Ylin's SURE the stage needs,
                                 in standard errors */
} mcf__feature_frame;

typedef struct {
    int won;                  /* SURE's gain passed min_z */
    double sigma_r;           /* the chosen candidate */
    int normal_iters, vertex_iters;
    double risk, risk_lin;    /* SURE (mean per vertex, squared units) of
                                 the chosen candidate and of Ylin */
    double z;                 /* the gain in standard errors */
    double s;                 /* the noise level it read from its own
                                 residuals (working units; see mcf_feature.c) */
    double div, vdiv;         /* (internal) the divergence, its variance */
    int outliers;             /* vertices left out of the comparison with
                                 Ylin (residual beyond 4 s; mcf_feature.c) */
    size_t bytes;             /* held at the peak */
} mcf__feature_pick;

/* The candidates' SURE with Monte-Carlo divergence (the frame's first
 * probe, steps of 0.3 s along reference normals), the least into Yout
 * (3*nv) and pick; Yout untouched when there is nothing to filter (s 0,
 * no vertex). fixed: the vertices the filter holds. ENOMEM, ELIMIT. */
mcf_status mcf__feature(const double *X, const int32_t *F, int nf, int nv, const unsigned char *fixed,
                        const mcf__feature_frame *fr, double *Yout, mcf__feature_pick *pick, mcf_error *err);
/* One probe's estimate of the divergence sum_k w_i d(m_i . f_i)/d(y_i
 * along m_i) over the frame's vertices i = vert[k]: sum_k w_i z_k m_i .
 * (Yz_i - Y_i) / eps, Y = f(y), Yz = f(y + eps z m) (Ramani et al. 2008). */
double mcf__feature_div(const mcf__feature_frame *fr, const double *w, const double *m, const double *Y,
                        const double *Yz, const double *z, double eps);
/* A bound on that estimate's variance from the same probe: for Rademacher
 * z, Var z'Az = sum_{i != j} A_ij (A_ij + A_ji) <= 2 |A|_F^2 (Cauchy-
 * Schwarz on the transposed terms) = 2 E |Az|^2, A the weighted Jacobian
 * above; its one-probe estimate 2 sum_k (w_i m_i . (Yz_i - Y_i))^2 / eps^2. */
double mcf__feature_div_bound(const mcf__feature_frame *fr, const double *w, const double *m, const double *Y,
                              const double *Yz, double eps);
/* The output: X = Xin + n <n, Y - Xin> on the vertices not fixed (n the
 * normals of Y), moves beyond rmax taken back, then, when flips is not
 * NULL (the default request), the repair of the faces the input had
 * without area (mcf__flips_repair against Y's normals; its count into
 * *flips), when turned is not NULL the drift repair (mcf__turned_repair;
 * its count into *turned), then the fold guard (mcf__unfold with
 * fn_orig, Y's positions first). grid (may be NULL): quantized positions'
 * steps (mcf__lattice), the moves then clipped into the input's cells
 * (mcf__lattice_clip) after the bound.
 * ENOMEM. */
mcf_status mcf__feature_output(const double *Xin, const double *fn_orig, const double *Y, const int32_t *F, int nf,
                               int nv, const unsigned char *fixed, double rmax, const double *grid, int *flips,
                               int *turned, double *X,
                               int *rounds, int *moves, mcf_error *err);
/* ---- spikes (mcf_spikes.c)
 * The vertices of X (graph g, mean edge hbar) far off the surface their
 * neighbours define (their height over their 1-ring many robust
 * deviations of the heights and at least a mean edge, far above their
 * neighbours', pulling their neighbours' rings towards them), not fixed
 * (fixed: nv) and off the plane through their ring's centroid by more
 * than the heights' threshold, moved back along the surface's normal onto
 * that plane (or to the centroid, when that folds fewer faces). Returns
 * their count, -1 when out of memory (X then unchanged). */
/* The share of the vertices not fixed and with an edge whose 1-ring lies
 * within tol of the plane through them along their normal N (3*nv): every
 * neighbour j with |N_i . (x_j - x_i)| <= tol. 0 when there is none.
 * (mcf_spikes.c; the default request's test for exact positions) */
double mcf__flat_share(const mcf__graph *g, const double *X, const double *N, const unsigned char *fixed,
                       double tol);
int mcf__spikes(const mcf__graph *g, const int32_t *F, int nf, const unsigned char *fixed, double hbar,
                double *X);

/* ---- quantized positions (mcf_lattice.c)
 * The grid the coordinates of the vertices not fixed sit on: per axis the
 * greatest common divisor q of the gaps between distinct values (two
 * values within 1e-6 hbar are one), when at least 99% of the values lie
 * within 1e-6 hbar of the levels v0 + k q (v0 the least) and
 * 1e-3 hbar <= q <= 0.6 hbar. Returns
 * 1 with the three steps in step, 0 (steps 0) when some axis has none or
 * fewer than 16 vertices are free, -1 when out of memory. */
int mcf__lattice(const double *X, int nv, const unsigned char *fixed, double hbar, double step[3]);
/* Every vertex not fixed of X into the cell of its grid point in Xin: each
 * coordinate within step/2 of Xin's (the set of positions that round to
 * Xin's; a projection onto a convex set holding the truth: no vertex ends
 * further from it). */
void mcf__lattice_clip(double *X, const double *Xin, int nv, const unsigned char *fixed, const double step[3]);

/* ---- creases (mcf_creases.c)
 * The creases of the mesh (X, F; graph g): the edges between two faces of
 * X smoothed by 10 Taubin passes that meet at more than 40 degrees, kept
 * where they form chains of at least 12 edges (noise and a scan's isolated
 * sharp spots make short bits). crease[i] (nv) gets 1 on their vertices;
 * those inside a chain (two crease edges, not fixed) are smoothed along it
 * in X by 3 Taubin passes on the chain alone, across it only; corners and
 * chain ends stay (the fairing's guard puts a crease vertex back where its
 * smoothing folded a face). chains (NULL, or g->ptr[nv] bytes) gets the
 * chains' edges marked, in both directions. Returns the number of crease
 * vertices, -1 when out of memory. tick (may be NULL) hears the stages end
 * ("creases"). */
int mcf__creases(const mcf__graph *g, const int32_t *F, int nf, int nv,
                 const unsigned char *fixed, double *X, unsigned char *crease, unsigned char *chains,
                 const mcf__tick *tick);
/* The smoothing alone along the chains a call of mcf__creases found
 * (chains: its g->ptr[nv] edge marks), on X. 0, or -1 when out of
 * memory. */
int mcf__creases_smooth(const mcf__graph *g, int nv, const unsigned char *fixed, const unsigned char *chains,
                        double *X);

/* ---- folds (mcf_folds.c)
 * A face a run folded: its normal turned against the same face's normal
 * in a reference (fn_ref: the input's, or the step before's) and it lies
 * backwards in its neighbourhood of X (its normal against the sum of its
 * vertices' summed face normals, or that sum within rounding of
 * perpendicular to it: a two-sided fin has no side to lie on). */
void mcf__face_normals(const double *X, const int32_t *F, int nf, double *fn); /* unnormalized */
/* The count; fn (3*nf) gets X's face normals, N (4*nv) is scratch, mask
 * (nf, may be NULL) gets 1 on each folded face. */
int mcf__folded_faces(const double *X, const int32_t *F, int nf, int nv, const double *fn_ref,
                      double *fn, double *N, unsigned char *mask);
/* The faces of X lying backwards in their neighbourhood (the second test
 * above alone; degenerate faces not), mask (nf) 1 on each; fn (3*nf)
 * gets X's face normals, N (4*nv) is scratch. Returns their count. */
int mcf__backwards_faces(const double *X, const int32_t *F, int nf, int nv, double *fn, double *N,
                         unsigned char *mask);
/* The faces of X folded against X_ref's; -1 when out of memory. */
int mcf__folds_against(const double *X, const double *X_ref, const int32_t *F, int nf, int nv);
/* The fairing filter's guard: while X has faces folded against X_in's
 * (or against fn_orig, when not NULL: the face normals of the request's
 * own input, where a stage before the filter, the spike repair, made
 * X_in), their vertices that the run moved (X != X_in) take Y's positions
 * (2 rounds), then halve their displacement from X_in (6 rounds), then
 * take X_in's positions. rounds: rounds that moved a vertex; moves:
 * vertex moves; left: folded faces left (0 unless the 64-round cap was
 * hit; with fn_orig, the faces X_in itself folded against it may stay).
 * ENOMEM only. */
mcf_status mcf__unfold(double *X, const double *X_in, const double *fn_orig, const double *Y, const int32_t *F,
                       int nf, int nv, int *rounds, int *moves, int *left, mcf_error *err);

/* ---- flips (mcf_flips.c)
 * The fairing filter's faces that were degenerate in its input X_in and
 * that X gives an orientation not facing along the filtered normal field
 * (field: unit vertex normals, 3*nv) by 60 degrees, taken back: their
 * vertices that X moved halve their displacement from X_in (6 rounds),
 * then take X_in's positions. grid (a quantized input, mcf__lattice):
 * by 41 degrees and within 63 degrees of X_in's face normals summed over
 * the vertices within 3 rings of the face, and also the faces X_in had with an orientation facing
 * along the field that X turns against it, taken back the same way. repaired: such faces
 * before the first round; moves: vertex moves. ENOMEM only. */
mcf_status mcf__flips_repair(double *X, const double *X_in, const double *field, const int32_t *F, int nf,
                             int nv, int grid, int *repaired, int *moves, mcf_error *err);

/* ---- turned faces (mcf_turned.c)
 * The fairing filter's output X (its input X_in) against its own normal
 * field averaged over 16 rings: a vertex of a face whose normal points
 * against the field there moves to X_in + m <m, x - X_in> (m the field at
 * it: its displacement along the field only) when that leaves fewer such
 * faces around it; up to 4 rounds. moved: the moves. A vertex where X_in
 * has it stays. ENOMEM only. */
mcf_status mcf__turned_repair(double *X, const double *X_in, const int32_t *F, int nf, int nv, int *moved,
                              mcf_error *err);

/* n standard normal draws from a 64-bit seed, mcf_mesh_add_noise's
 * generator (the same draws in the same order). (mcf_mesh.c) */
void mcf__gauss_fill(uint64_t seed, double *z, size_t n);

/* ---- small helpers */
#define MCF_PI 3.14159265358979323846
/* splitmix64's finalizer: a bijection of 64-bit words that mixes well. */
static inline uint64_t mcf__mix64(uint64_t z)
{
    z = (z ^ (z >> 30)) * UINT64_C(0xbf58476d1ce4e5b9);
    z = (z ^ (z >> 27)) * UINT64_C(0x94d049bb133111eb);
    return z ^ (z >> 31);
}

static inline double mcf__dot3(const double *a, const double *b)
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static inline void mcf__sub3(const double *a, const double *b, double *r)
{
    r[0] = a[0] - b[0];
    r[1] = a[1] - b[1];
    r[2] = a[2] - b[2];
}
static inline void mcf__cross3(const double *a, const double *b, double *r)
{
    r[0] = a[1] * b[2] - a[2] * b[1];
    r[1] = a[2] * b[0] - a[0] * b[2];
    r[2] = a[0] * b[1] - a[1] * b[0];
}

/* Total area, area centroid (may be NULL; the origin when the area is
 * 0) and signed enclosed volume (divergence theorem, may be NULL) of the
 * faces F over positions X, in one pass. Returns the area. (mcf_mesh.c;
 * the flow's normalization and mcf_mesh_area_centroid) */
double mcf__area_volume(const double *X, const int32_t *F, int nf,
                        double *centroid, double *volume);

/* angle[v] += corner angles at v; mass[v] += true area/3 and used[v] = 1
 * for referenced vertices when those are non-NULL. Angles by atan2 of
 * |cross| and dot (accurate near 0 and pi). (mcf_curvature.c) */
void mcf__corner_sums(const double *X, const int32_t *F, int nf,
                      double *angle, double *mass, unsigned char *used);

/* G (3*nv) = area-weighted average over the faces at each vertex of the
 * face gradient of the linear interpolant of f (nv); zero-area faces are
 * skipped, vertices without a face get 0. (mcf_curvature.c) */
void mcf__vertex_gradient(const double *X, const int32_t *F, int nf, int nv,
                          const double *f, double *G);

/* Area-weighted vertex normals (unit; zero where undefined). (mcf_curvature.c) */
void mcf__vertex_normals(const double *X, const int32_t *F, int nf, int nv,
                         double *N);

/* Sorts key[0..n) ascending, stable (LSD radix by bytes, O(n) per byte
 * that differs between keys), permuting val alongside when it is not
 * NULL; tk (n keys) and tv (n values, when val) are scratch.
 * (mcf_sort.c) */
void mcf__radix_sort_u64(uint64_t *key, uint32_t *val, size_t n, uint64_t *tk,
                         uint32_t *tv);
/* An order-preserving map of finite doubles to uint64 (-0 as +0) and its
 * inverse, for sorting doubles with mcf__radix_sort_u64. (mcf_sort.c) */
uint64_t mcf__double_key(double x);
double mcf__key_double(uint64_t u);
/* The median of v[0..n) (finite values; v is reordered): the middle value,
 * or the mean of the two middle ones, exactly as a sort would give them;
 * 0 for n = 0. Linear time on any data but an adversarial order, which
 * falls back to sorting (mcf_sort.c) */
double mcf__median(double *v, size_t n);
/* Percentile q in [0, 1] of v[0..n) (finite values; v is reordered),
 * linear between the order statistics at q (n - 1) (the "type 7" rule of
 * R and NumPy's default), exactly as from a sorted copy; 0 for n = 0.
 * Linear time as mcf__median (mcf_sort.c) */
double mcf__percentile(double *v, size_t n, double q);

#endif /* MCF_INTERNAL_H */
