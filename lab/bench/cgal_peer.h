/* SPDX-License-Identifier: MIT */
/*
 * cgal_peer.h - the benchmark's CGAL peer: CGAL 5.5's
 * Polygon_mesh_processing::smooth_shape on a Surface_mesh, exactly as a
 * CGAL user calls it (default solver, default options), behind a plain C
 * interface so bench_peers.c (C11) can drive it. The implementation
 * (cgal_peer.cpp) is C++17 and catches every exception at the boundary.
 *
 * What one smooth_shape iteration solves (read from CGAL 5.5.1,
 * Polygon_mesh_processing/internal/Smoothing/curvature_flow_impl.h and
 * Weights/cotangent_weights.h), in mcfd's notation (core/mcf.h: L the PSD
 * cotan stiffness with the 1/2 factor, L_ij = -1/2 (cot a + cot b), M the
 * barycentric lumped mass, m_i = sum of adjacent areas / 3):
 *   - stiffness: CGAL's edge weight is cot a + cot b (one cotangent on a
 *     border edge), off-diagonal +w, diagonal -sum w: K = -2 L;
 *   - mass: area/6 per face corner: D = M / 2;
 *   - system: (D - time K) X+ = D X, i.e. (M/2 + 2 time L) X+ = M/2 X,
 *     i.e. (M + 4 time L) X+ = M X: mcfd's `desbrun` step with
 *         dt = 4 * time      (time = dt / 4, cgal_time_from_dt);
 *   - K is computed once per smooth_shape call from the positions at the
 *     call (Kazhdan et al. 2012), D at every iteration. So
 *     number_of_iterations(1) per call, called once per step, is mcfd's
 *     `desbrun` (L and M at X^k); one call with number_of_iterations(n)
 *     is mcfd's `cmcf` (L_0 from the call's input, M at X^k);
 *   - after every iteration, on a closed mesh with at most one
 *     constrained vertex (here: none), CGAL rescales the result Y about
 *     centroids to the volume before the iteration:
 *         X+ = c(X^k) + cbrt(|V(X^k) / V(Y)|) (Y - c(Y)),
 *     c = PMP::centroid (the solid's centroid), V = PMP::volume. On a
 *     mesh with a border, no rescaling, and border vertices move (free
 *     boundary: mcfd's MCF_BOUNDARY_FREE);
 *   - solver: Eigen::BiCGSTAB preconditioned by Eigen::IncompleteLUT
 *     (drop tolerance 1e-12, fill factor 10: Eigen's defaults), stopping
 *     at a relative residual |b - A x| / |b| <= 2.2e-16 (Eigen's default,
 *     NumTraits<double>::epsilon(), on BiCGSTAB's recursively updated
 *     residual) or after 2n iterations; one ILUT compute per iteration,
 *     then three solves (x, y, z) from a zero initial guess.
 * A rescale changes the result by a similarity (translation + uniform
 * scale) only; mcfd's MCF_RESCALE_VOLUME scales by the same factor about
 * the area centroid of Y, so its `desbrun` + rescale run equals CGAL's up
 * to a translation (the step commutes with translations, L 1 = 0).
 *
 * Positions are nv x 3 row-major doubles, faces nf x 3 int32, as in
 * core/mcf.h. Vertex i of the arrays is vertex i of the Surface_mesh.
 */
#ifndef CGAL_PEER_H
#define CGAL_PEER_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct cgal_peer cgal_peer;

/* CGAL's smooth_shape `time` that solves mcfd's desbrun step of size dt
 * (same units: dt in the mesh's squared length units). */
static inline double cgal_time_from_dt(double dt) { return 0.25 * dt; }

/* Where the time of smooth_shape calls went, summed over the calls since
 * the last cgal_peer_times_reset (seconds, steady clock). factor and solve
 * are measured inside smooth_shape by a timing wrapper around CGAL's
 * default solver (same Eigen solver, same calls); total is the whole call,
 * so total - factor - solve is CGAL's assembly, stiffness, mass, and
 * rescaling. */
typedef struct {
    double total;       /* smooth_shape calls */
    double factor;      /* IncompleteLUT compute, once per iteration */
    double solve;       /* BiCGSTAB solves, three per iteration */
    int calls, iterations, solves;
    long bicgstab_iters;    /* sum over the solves */
    int bicgstab_iters_max; /* largest single solve */
    double residual_max;    /* largest BiCGSTAB error() (relative residual) */
    int failures;           /* calls smooth_shape ended early */
    long fail_iters;        /* BiCGSTAB iterations of the last failed solve */
    double fail_residual;   /* its error() (may be NaN: a breakdown) */
} cgal_peer_times;

/* Builds a Surface_mesh from the arrays. Returns NULL, with a one-line
 * reason in msg (msglen bytes, may be 0), when a face cannot be added (a
 * non-manifold configuration, index out of range), when a vertex is used
 * by no face (smooth_shape would leave its matrix row empty, so the
 * system would be singular: compact the mesh first), or when memory runs
 * out. */
cgal_peer *cgal_peer_new(int nv, const double *X, int nf, const int32_t *F,
                         char *msg, size_t msglen);
void cgal_peer_free(cgal_peer *p); /* accepts NULL */

/* Non-zero when the mesh is closed, i.e. when smooth_shape rescales the
 * volume after every iteration. */
int cgal_peer_closed(const cgal_peer *p);

/* Copies the current positions out (3*nv doubles) / in. */
void cgal_peer_get(const cgal_peer *p, double *X);
void cgal_peer_set(cgal_peer *p, const double *X);

/* One call smooth_shape(mesh, time, number_of_iterations(iterations))
 * with CGAL's default solver (wrapped for timing). max_iters > 0 caps
 * BiCGSTAB's iterations per solve (0: Eigen's default, 2n): CGAL's
 * default has no useful cap, and a stalled solve on a 43k-vertex mesh was
 * seen to run 48,775 iterations (5.6 min) before it broke down; with a cap
 * such a solve fails sooner, and converging solves are unaffected.
 * Returns 0 on success, -1 when smooth_shape stopped early (a solve or the
 * preconditioner failed: CGAL then leaves the mesh at the last solved
 * iteration and says nothing; the wrapper sees it) or threw. t (may be
 * NULL) is accumulated into. */
int cgal_peer_smooth(cgal_peer *p, double time, int iterations, long max_iters,
                     cgal_peer_times *t);

/* CGAL's post-iteration volume rescale (see the top comment), computed with
 * CGAL's own PMP::volume and PMP::centroid, applied to arbitrary positions:
 * Xout = c(Xold) + cbrt(|V(Xold) / V(Y)|) (Y - c(Y)). Used to check a
 * smooth_shape iteration against mcfd's unscaled desbrun step. Leaves the
 * peer's positions at Xout. Xout may alias Y. */
void cgal_peer_rescale_like_smooth_shape(cgal_peer *p, const double *Xold,
                                         const double *Y, double *Xout);

void cgal_peer_times_reset(cgal_peer_times *t);

/* "5.5.1" and the Eigen version CGAL was compiled with, e.g. "3.4.0". */
const char *cgal_peer_version(void);
const char *cgal_peer_eigen_version(void);

#ifdef __cplusplus
}
#endif
#endif /* CGAL_PEER_H */
