/* SPDX-License-Identifier: MIT */
/*
 * mcf_laplacian.c - cotan stiffness and lumped mass: per-triangle weights,
 * matrix-free products, the job's fixed sparse pattern, lambda_max; the
 * closest point on a triangle.
 *
 * Workload: one call per flow step on meshes of up to a few million faces,
 * so the per-step path is a single pass over the faces with no allocation
 * and no sort. The sparsity pattern of L (upper triangle by columns, the
 * layout CHOLMOD takes with stype = +1) is built once per job together with
 * a face-corner -> entry map; each step only scatters new values into it.
 *
 * Degenerate triangles: a zero-area triangle has infinite cotangents. We
 * use intrinsic mollification (Sharp & Crane, "A Laplacian for Nonmanifold
 * Triangle Meshes", 2020), per triangle: the three edge lengths are
 * increased by the smallest eps >= 0 such that every triangle inequality
 * holds with margin delta = MCF_MOLLIFY * (mean edge length). The result is
 * a genuine Euclidean triangle, so its cotangents are finite and its 3x3
 * stiffness block is PSD; triangles whose inequalities already hold with
 * margin delta are untouched. The mollified area is also what the
 * barycentric mass uses, so no referenced vertex has zero mass.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_internal.h"

double mcf__mean_edge(const double *X, const int32_t *F, int nf)
{
    double sum = 0.0;
    for (int f = 0; f < nf; f++) {
        const int32_t *t = F + 3 * (size_t)f;
        for (int k = 0; k < 3; k++) {
            double e[3];
            mcf__sub3(X + 3 * (size_t)t[k], X + 3 * (size_t)t[(k + 1) % 3], e);
            sum += sqrt(mcf__dot3(e, e));
        }
    }
    return nf > 0 ? sum / (3.0 * nf) : 0.0;
}

/* Area from three side lengths, Kahan's cancellation-free Heron. */
static double heron(double a, double b, double c)
{
    double t;
    if (a < b) { t = a; a = b; b = t; }
    if (b < c) { t = b; b = c; c = t; }
    if (a < b) { t = a; a = b; b = t; }
    double p = (a + (b + c)) * (c - (a - b)) * (c + (a - b)) * (a + (b - c));
    return p > 0.0 ? 0.25 * sqrt(p) : 0.0;
}

/* The weights w[0..2] (1/2 cot at each corner) and the mollified area of
 * one triangle; see mcf__cot_weights. Always inlined: it is the body of
 * every per-face loop (measured: 13 of the explicit step's 24 ns per face
 * went to the call when GCC kept it out of line). */
#if defined(__GNUC__)
__attribute__((always_inline))
#endif
static inline void tri_weights(const double *p0, const double *p1, const double *p2,
                               mcf_laplacian lap, double delta, double *wf, double *area)
{
    double e0[3], e1[3], e2[3], n[3];
    mcf__sub3(p2, p1, e0); /* opposite corner 0 */
    mcf__sub3(p0, p2, e1); /* opposite corner 1 */
    mcf__sub3(p1, p0, e2); /* opposite corner 2 */
    double q0 = mcf__dot3(e0, e0), q1 = mcf__dot3(e1, e1), q2 = mcf__dot3(e2, e2);
    mcf__cross3(e2, e1, n);
    double n2 = mcf__dot3(n, n); /* (2A)^2 */
    double qm = q0 > q1 ? (q0 > q2 ? q0 : q2) : (q1 > q2 ? q1 : q2);
    /* Fast path, no mollification needed: with c the longest side and h
     * the height on it, every triangle inequality has slack >= h^2/c (a - x
     * >= h^2/(2a) for a leg a over a base part x), and h = 2A/c, so (2A)^2
     * >= delta c^3, i.e. n2^2 >= delta^2 qm^3, guarantees slack >= delta.
     * Then cot at corner k = <adjacent edges> / 2A. */
    if (n2 * n2 >= delta * delta * qm * qm * qm && n2 > 0.0) {
        double A2 = sqrt(n2);
        *area = 0.5 * A2;
        if (lap == MCF_LAPLACIAN_UNIFORM) {
            wf[0] = wf[1] = wf[2] = 0.5;
            return;
        }
        double s = -0.5 / A2; /* w = cot/2; the adjacent edges point away
                                 from each other, hence the sign */
        wf[0] = s * mcf__dot3(e1, e2);
        wf[1] = s * mcf__dot3(e2, e0);
        wf[2] = s * mcf__dot3(e0, e1);
        return;
    }
    double l[3] = {sqrt(q0), sqrt(q1), sqrt(q2)};
    double slack = fmin(fmin(l[0] + l[1] - l[2], l[1] + l[2] - l[0]), l[2] + l[0] - l[1]);
    if (slack < delta) {
        double eps = delta - slack;
        l[0] += eps; l[1] += eps; l[2] += eps;
    }
    double A = heron(l[0], l[1], l[2]);
    *area = A;
    if (lap == MCF_LAPLACIAN_UNIFORM) {
        wf[0] = wf[1] = wf[2] = 0.5;
        return;
    }
    q0 = l[0] * l[0]; q1 = l[1] * l[1]; q2 = l[2] * l[2];
    /* cot(angle at k) = (l_{k+1}^2 + l_{k+2}^2 - l_k^2) / (4A); w = cot/2 */
    double s = 1.0 / (8.0 * A);
    wf[0] = (q1 + q2 - q0) * s;
    wf[1] = (q2 + q0 - q1) * s;
    wf[2] = (q0 + q1 - q2) * s;
}

/* One face of the explicit pass, scalar: the weights (into w, area when
 * not NULL), then the per-vertex combined scatter of L X and of the mass.
 * Returns the face's area. */
#if defined(__GNUC__)
__attribute__((always_inline))
#endif
static inline double face_LX(const double *X, const int32_t *t, mcf_laplacian lap,
                             double delta, double *w, double *area, double *mass,
                             double *Y)
{
    const double *p0 = X + 3 * (size_t)t[0], *p1 = X + 3 * (size_t)t[1],
                 *p2 = X + 3 * (size_t)t[2];
    double *y0 = Y + 3 * (size_t)t[0], *y1 = Y + 3 * (size_t)t[1],
           *y2 = Y + 3 * (size_t)t[2];
    double wf[3], A;
    tri_weights(p0, p1, p2, lap, delta, wf, &A);
    if (w) {
        w[0] = wf[0]; w[1] = wf[1]; w[2] = wf[2];
    }
    if (area)
        *area = A;
    /* corner k's weight couples the other two corners, so
     * y0 += w2 (p0 - p1) + w1 (p0 - p2), and so on round the face:
     * three products per coordinate, each used twice */
    for (int d = 0; d < 3; d++) {
        double g2 = wf[2] * (p0[d] - p1[d]), g0 = wf[0] * (p1[d] - p2[d]),
               g1 = wf[1] * (p2[d] - p0[d]);
        y0[d] += g2 - g1;
        y1[d] += g0 - g2;
        y2[d] += g1 - g0;
    }
    double a3 = A / 3.0;
    mass[t[0]] += a3;
    mass[t[1]] += a3;
    mass[t[2]] += a3;
    return A;
}

#if defined(__GNUC__) && defined(__x86_64__)
#define LX_AVX2 1
#include <immintrin.h>

/* The same pass four faces at a time with AVX2, one face per lane. Why:
 * the pass is bound by instruction throughput, and in lanes the weights'
 * arithmetic takes a quarter of the instructions (the scatter, which
 * stays sequential because faces share vertices, adds x and y in one
 * 128-bit operation). Measured 17.9 -> 10.7 ns per face on icosphere-7,
 * 24.4 -> 12.5 on the dragon. Compiled for AVX2 whatever the build flags
 * (target attribute; GCC and clang) and called only on a CPU that has it,
 * so the binary runs on any x86-64. Each lane does tri_weights' fast-path
 * operations and face_LX's in the same order, without FMA (p0 - p1 = -e2
 * exactly, so face_LX's g2 - g1 is h1 - h2 here; max(max(q0, q1), q2) is
 * its qm wherever the fast test passes), and the scatter adds in the same
 * order: the results are the scalar loop's bit for bit. A lane the fast
 * path does not take (mollified, degenerate, NaN) is redone by
 * tri_weights. */
#define LX_INLINE __attribute__((target("avx2"), always_inline)) static inline

/* Coordinates of corner k of the four faces t[0..11], one face per lane. */
LX_INLINE void lx_corner(const double *X, const int32_t *t, int k, __m256d *x,
                         __m256d *y, __m256d *z)
{
    const double *a = X + 3 * (size_t)t[k], *b = X + 3 * (size_t)t[3 + k],
                 *c = X + 3 * (size_t)t[6 + k], *d = X + 3 * (size_t)t[9 + k];
    __m256d ac = _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_loadu_pd(a)), _mm_loadu_pd(c), 1);
    __m256d bd = _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_loadu_pd(b)), _mm_loadu_pd(d), 1);
    *x = _mm256_unpacklo_pd(ac, bd); /* a.x b.x c.x d.x */
    *y = _mm256_unpackhi_pd(ac, bd);
    *z = _mm256_set_pd(d[2], c[2], b[2], a[2]);
}

/* The scatter terms of four faces: what corner k of face j adds to its
 * vertex, x and y at xy[k] + 4 (j & 1) + 2 (j >> 1) (unpack order), z at
 * z[k][j]; area / 3 and area of face j. */
typedef struct {
    double xy[3][8], z[3][4], a3[4], A[4];
} lx_terms;

/* The weights (wk[0..2]) and areas (*Ap) of the four faces t[0..11] in
 * lanes, also into w[0..11] and area[0..3] when not NULL, and their edges
 * e[0..8] (e0 x y z, e1, e2). */
LX_INLINE void lx_tri(const double *X, const int32_t *t, mcf_laplacian lap, double delta,
                      double *w, double *area, __m256d e[9], __m256d wk[3], __m256d *Ap)
{
    __m256d p0x, p0y, p0z, p1x, p1y, p1z, p2x, p2y, p2z;
    lx_corner(X, t, 0, &p0x, &p0y, &p0z);
    lx_corner(X, t, 1, &p1x, &p1y, &p1z);
    lx_corner(X, t, 2, &p2x, &p2y, &p2z);
    __m256d e0x = p2x - p1x, e0y = p2y - p1y, e0z = p2z - p1z;
    __m256d e1x = p0x - p2x, e1y = p0y - p2y, e1z = p0z - p2z;
    __m256d e2x = p1x - p0x, e2y = p1y - p0y, e2z = p1z - p0z;
    __m256d q0 = e0x * e0x + e0y * e0y + e0z * e0z;
    __m256d q1 = e1x * e1x + e1y * e1y + e1z * e1z;
    __m256d q2 = e2x * e2x + e2y * e2y + e2z * e2z;
    __m256d nx = e2y * e1z - e2z * e1y, ny = e2z * e1x - e2x * e1z, nz = e2x * e1y - e2y * e1x;
    __m256d n2 = nx * nx + ny * ny + nz * nz;
    __m256d qm = _mm256_max_pd(_mm256_max_pd(q0, q1), q2);
    int fast = _mm256_movemask_pd(_mm256_and_pd(
        _mm256_cmp_pd(n2 * n2, _mm256_set1_pd(delta * delta) * qm * qm * qm, _CMP_GE_OQ),
        _mm256_cmp_pd(n2, _mm256_setzero_pd(), _CMP_GT_OQ)));
    __m256d A2 = _mm256_sqrt_pd(n2), A = 0.5 * A2;
    __m256d w0 = _mm256_set1_pd(0.5), w1 = w0, w2 = w0;
    if (lap != MCF_LAPLACIAN_UNIFORM) {
        __m256d s = _mm256_set1_pd(-0.5) / A2;
        w0 = s * (e1x * e2x + e1y * e2y + e1z * e2z);
        w1 = s * (e2x * e0x + e2y * e0y + e2z * e0z);
        w2 = s * (e0x * e1x + e0y * e1y + e0z * e1z);
    }
    if (fast != 15 || w || area) {
        double wl[3][4], al[4];
        _mm256_storeu_pd(wl[0], w0);
        _mm256_storeu_pd(wl[1], w1);
        _mm256_storeu_pd(wl[2], w2);
        _mm256_storeu_pd(al, A);
        for (int j = 0; j < 4; j++) {
            const int32_t *u = t + 3 * j;
            if (!(fast >> j & 1)) { /* rare: mollified or degenerate */
                double wf[3];
                tri_weights(X + 3 * (size_t)u[0], X + 3 * (size_t)u[1], X + 3 * (size_t)u[2],
                            lap, delta, wf, al + j);
                wl[0][j] = wf[0]; wl[1][j] = wf[1]; wl[2][j] = wf[2];
            }
            if (w) {
                w[3 * j] = wl[0][j]; w[3 * j + 1] = wl[1][j]; w[3 * j + 2] = wl[2][j];
            }
            if (area)
                area[j] = al[j];
        }
        w0 = _mm256_loadu_pd(wl[0]);
        w1 = _mm256_loadu_pd(wl[1]);
        w2 = _mm256_loadu_pd(wl[2]);
        A = _mm256_loadu_pd(al);
    }
    e[0] = e0x; e[1] = e0y; e[2] = e0z;
    e[3] = e1x; e[4] = e1y; e[5] = e1z;
    e[6] = e2x; e[7] = e2y; e[8] = e2z;
    wk[0] = w0; wk[1] = w1; wk[2] = w2;
    *Ap = A;
}

/* Weights (into w[0..11], area[0..3] when not NULL) and scatter terms of
 * the four faces t[0..11]. */
LX_INLINE void lx_weights(const double *X, const int32_t *t, mcf_laplacian lap,
                          double delta, double *w, double *area, lx_terms *o)
{
    __m256d e[9], wk[3], A;
    lx_tri(X, t, lap, delta, w, area, e, wk, &A);
    __m256d e0x = e[0], e0y = e[1], e0z = e[2], e1x = e[3], e1y = e[4], e1z = e[5];
    __m256d e2x = e[6], e2y = e[7], e2z = e[8], w0 = wk[0], w1 = wk[1], w2 = wk[2];
    /* h_k = w_k e_k; corner 0 gets h1 - h2 (= g2 - g1 of face_LX) */
    __m256d h0x = w0 * e0x, h0y = w0 * e0y, h0z = w0 * e0z;
    __m256d h1x = w1 * e1x, h1y = w1 * e1y, h1z = w1 * e1z;
    __m256d h2x = w2 * e2x, h2y = w2 * e2y, h2z = w2 * e2z;
    __m256d g0x = h1x - h2x, g1x = h2x - h0x, g2x = h0x - h1x;
    __m256d g0y = h1y - h2y, g1y = h2y - h0y, g2y = h0y - h1y;
    _mm256_storeu_pd(o->xy[0], _mm256_unpacklo_pd(g0x, g0y)); /* faces 0, 2 */
    _mm256_storeu_pd(o->xy[0] + 4, _mm256_unpackhi_pd(g0x, g0y)); /* 1, 3 */
    _mm256_storeu_pd(o->xy[1], _mm256_unpacklo_pd(g1x, g1y));
    _mm256_storeu_pd(o->xy[1] + 4, _mm256_unpackhi_pd(g1x, g1y));
    _mm256_storeu_pd(o->xy[2], _mm256_unpacklo_pd(g2x, g2y));
    _mm256_storeu_pd(o->xy[2] + 4, _mm256_unpackhi_pd(g2x, g2y));
    _mm256_storeu_pd(o->z[0], h1z - h2z);
    _mm256_storeu_pd(o->z[1], h2z - h0z);
    _mm256_storeu_pd(o->z[2], h0z - h1z);
    _mm256_storeu_pd(o->a3, A / 3.0);
    _mm256_storeu_pd(o->A, A);
}

/* face_LX over the nb blocks of four faces F[0 .. 12 nb - 1]. */
__attribute__((target("avx2")))
static double face_blocks_avx2(const double *X, const int32_t *F, int nb, mcf_laplacian lap,
                               double delta, double *w, double *area, double *mass,
                               double *Y)
{
    double total = 0.0;
    for (int b = 0; b < nb; b++) {
        const int32_t *t = F + 12 * (size_t)b;
        lx_terms g;
        lx_weights(X, t, lap, delta, w ? w + 12 * (size_t)b : NULL,
                   area ? area + 4 * (size_t)b : NULL, &g);
        for (int j = 0; j < 4; j++) {
            const int32_t *u = t + 3 * j;
            int o = 4 * (j & 1) + 2 * (j >> 1);
            total += g.A[j];
            for (int k = 0; k < 3; k++) {
                double *y = Y + 3 * (size_t)u[k];
                _mm_storeu_pd(y, _mm_add_pd(_mm_loadu_pd(y), _mm_loadu_pd(g.xy[k] + o)));
                y[2] += g.z[k][j];
            }
            mass[u[0]] += g.a3[j];
            mass[u[1]] += g.a3[j];
            mass[u[2]] += g.a3[j];
        }
    }
    return total;
}

/* mcf__cot_weights over the nb blocks of four faces F[0 .. 12 nb - 1]:
 * the same lanes as the explicit pass (the same bits as tri_weights). */
__attribute__((target("avx2")))
static void cot_blocks_avx2(const double *X, const int32_t *F, int nb, mcf_laplacian lap,
                            double delta, double *w, double *area)
{
    for (int b = 0; b < nb; b++) {
        __m256d e[9], wk[3], A;
        lx_tri(X, F + 12 * (size_t)b, lap, delta, w + 12 * (size_t)b, area ? area + 4 * (size_t)b : NULL,
               e, wk, &A);
    }
}
#endif

void mcf__cot_weights(const double *X, const int32_t *F, int nf,
                      mcf_laplacian lap, double delta, double *w,
                      double *area)
{
    if (!(delta > 0.0))
        delta = 1e-300; /* all points coincide: any positive margin */
    int f = 0;
#if defined(LX_AVX2)
    if (__builtin_cpu_supports("avx2")) {
        f = nf / 4 * 4;
        cot_blocks_avx2(X, F, nf / 4, lap, delta, w, area);
    }
#endif
    for (; f < nf; f++) {
        const int32_t *t = F + 3 * (size_t)f;
        double A;
        tri_weights(X + 3 * (size_t)t[0], X + 3 * (size_t)t[1], X + 3 * (size_t)t[2],
                    lap, delta, w + 3 * (size_t)f, &A);
        if (area)
            area[f] = A;
    }
}

double mcf__weights_mass_LX(const double *X, const int32_t *F, int nf, int nv,
                            mcf_laplacian lap, double delta, double *w,
                            double *area, double *mass, double *Y)
{
    double total = 0.0;
    int f = 0;
    if (!(delta > 0.0))
        delta = 1e-300;
    memset(mass, 0, sizeof(double) * (size_t)nv);
    memset(Y, 0, sizeof(double) * 3 * (size_t)nv);
#if defined(LX_AVX2)
    /* blocks of four faces when the CPU has AVX2 (checked at run time);
     * the remainder, or every face elsewhere, one at a time */
    if (__builtin_cpu_supports("avx2")) {
        f = nf / 4 * 4;
        total = face_blocks_avx2(X, F, nf / 4, lap, delta, w, area, mass, Y);
    }
#endif
    for (; f < nf; f++)
        total += face_LX(X, F + 3 * (size_t)f, lap, delta, w ? w + 3 * (size_t)f : NULL,
                         area ? area + f : NULL, mass, Y);
    return total;
}

/* Mixed Voronoi area of the three corners of one triangle (Meyer et al.
 * 2003, fig. 4): the Voronoi region for a non-obtuse triangle, else area/2
 * at the obtuse corner and area/4 at the others. Cotangents come from the
 * actual vertex positions; a triangle of zero area gives nothing. */
static void voronoi_corners(const double *p[3], double A, double out[3])
{
    double e[3][3], q[3];
    out[0] = out[1] = out[2] = 0.0;
    if (!(A > 0.0))
        return;
    for (int k = 0; k < 3; k++) { /* e[k] = edge opposite corner k */
        mcf__sub3(p[(k + 2) % 3], p[(k + 1) % 3], e[k]);
        q[k] = mcf__dot3(e[k], e[k]);
    }
    for (int k = 0; k < 3; k++) {
        /* angle at k is obtuse iff q[k] > q[k+1] + q[k+2] */
        if (q[k] > q[(k + 1) % 3] + q[(k + 2) % 3]) {
            out[k] = A / 2.0;
            out[(k + 1) % 3] = out[(k + 2) % 3] = A / 4.0;
            return;
        }
    }
    double cot[3];
    for (int k = 0; k < 3; k++)
        cot[k] = (q[(k + 1) % 3] + q[(k + 2) % 3] - q[k]) / (4.0 * A);
    for (int k = 0; k < 3; k++) /* edges at k: opposite k+1 and k+2 */
        out[k] = (q[(k + 1) % 3] * cot[(k + 1) % 3] +
                  q[(k + 2) % 3] * cot[(k + 2) % 3]) / 8.0;
}

void mcf__mass(const double *X, const int32_t *F, int nf, int nv,
               mcf_mass kind, const double *area, double *mass)
{
    memset(mass, 0, sizeof(double) * (size_t)nv);
    for (int f = 0; f < nf; f++) {
        const int32_t *t = F + 3 * (size_t)f;
        if (kind == MCF_MASS_VORONOI) {
            const double *p[3] = {X + 3 * (size_t)t[0], X + 3 * (size_t)t[1],
                                  X + 3 * (size_t)t[2]};
            double c[3];
            voronoi_corners(p, area[f], c);
            /* a degenerate triangle still lends its mollified area evenly,
             * so a vertex touching only such triangles keeps a mass */
            if (c[0] + c[1] + c[2] <= 0.0)
                c[0] = c[1] = c[2] = area[f] / 3.0;
            for (int k = 0; k < 3; k++)
                mass[t[k]] += c[k];
        } else {
            double a3 = area[f] / 3.0;
            mass[t[0]] += a3;
            mass[t[1]] += a3;
            mass[t[2]] += a3;
        }
    }
}

void mcf__apply_L(const int32_t *F, int nf, int nv, const double *w,
                  const double *X, double *Y)
{
    memset(Y, 0, sizeof(double) * 3 * (size_t)nv);
    for (int f = 0; f < nf; f++) {
        const int32_t *t = F + 3 * (size_t)f;
        for (int k = 0; k < 3; k++) {
            size_t i = (size_t)t[(k + 1) % 3], j = (size_t)t[(k + 2) % 3];
            double wk = w[3 * (size_t)f + k];
            const double *xi = X + 3 * i, *xj = X + 3 * j;
            double d0 = wk * (xi[0] - xj[0]), d1 = wk * (xi[1] - xj[1]),
                   d2 = wk * (xi[2] - xj[2]);
            Y[3 * i] += d0; Y[3 * i + 1] += d1; Y[3 * i + 2] += d2;
            Y[3 * j] -= d0; Y[3 * j + 1] -= d1; Y[3 * j + 2] -= d2;
        }
    }
}

mcf_status mcf__laplacian_apply(const double *X, const int32_t *F, int nf,
                                int nv, mcf_laplacian lap, mcf_mass mk,
                                double *LX, double *mass, mcf_error *err)
{
    double *w = mcf__malloc(3 * (size_t)nf, sizeof *w);
    double *area = mcf__malloc((size_t)nf, sizeof *area);
    if (!w || !area) {
        free(w);
        free(area);
        return mcf__fail(err, MCF_ENOMEM, "laplacian: out of memory (%d faces)", nf);
    }
    mcf__cot_weights(X, F, nf, lap, MCF_MOLLIFY * mcf__mean_edge(X, F, nf), w, area);
    if (mass)
        mcf__mass(X, F, nf, nv, mk, area, mass);
    if (LX)
        mcf__apply_L(F, nf, nv, w, X, LX);
    free(w);
    free(area);
    return MCF_OK;
}

/* ------------------------------------------------------------- pattern */

/* Columns hold a vertex's lower-numbered neighbours: a handful of rows,
 * for which insertion sort beats qsort's indirect calls several times. */
static void sort_rows(int *r, int n)
{
    for (int i = 1; i < n; i++) {
        int v = r[i], j = i - 1;
        while (j >= 0 && r[j] > v) {
            r[j + 1] = r[j];
            j--;
        }
        r[j + 1] = v;
    }
}

/* Index of row r in column c (rows sorted), -1 if absent. */
static int find_entry(const mcf__pattern *p, int r, int c)
{
    int lo = p->colptr[c], hi = p->colptr[c + 1] - 1;
    while (lo <= hi) {
        int mid = lo + (hi - lo) / 2;
        if (p->rowind[mid] == r)
            return mid;
        if (p->rowind[mid] < r)
            lo = mid + 1;
        else
            hi = mid - 1;
    }
    return -1;
}

mcf_status mcf__pattern_build(const int32_t *F, int nf, int nv, int want_tri,
                              mcf__pattern *p, mcf_error *err)
{
    mcf__pattern q = {0};
    size_t cap = 3 * (size_t)nf + (size_t)nv;
    int *cnt = mcf__calloc((size_t)nv + 1, sizeof *cnt);
    int *rows = mcf__malloc(cap, sizeof *rows);
    q.colptr = mcf__malloc((size_t)nv + 1, sizeof *q.colptr);
    q.diag = mcf__malloc((size_t)nv, sizeof *q.diag);
    q.tri = want_tri ? mcf__malloc(3 * (size_t)nf, sizeof *q.tri) : NULL;
    q.mult = mcf__malloc(cap, sizeof *q.mult);
    if (!cnt || !rows || !q.colptr || !q.diag || (want_tri && !q.tri) || !q.mult)
        goto nomem;

    /* bucket the rows of every upper entry (min, max) by column max */
    for (int f = 0; f < nf; f++)
        for (int k = 0; k < 3; k++) {
            int a = F[3 * (size_t)f + (k + 1) % 3], b = F[3 * (size_t)f + (k + 2) % 3];
            if (a != b)
                cnt[(a > b ? a : b) + 1]++;
        }
    for (int j = 0; j < nv; j++)
        cnt[j + 1]++; /* the diagonal */
    for (int j = 0; j < nv; j++)
        cnt[j + 1] += cnt[j];
    memcpy(q.colptr, cnt, sizeof(int) * ((size_t)nv + 1));
    for (int f = 0; f < nf; f++)
        for (int k = 0; k < 3; k++) {
            int a = F[3 * (size_t)f + (k + 1) % 3], b = F[3 * (size_t)f + (k + 2) % 3];
            if (a != b)
                rows[cnt[a > b ? a : b]++] = a < b ? a : b;
        }
    for (int j = 0; j < nv; j++)
        rows[cnt[j]++] = j;

    /* sort each column and drop repeats, compacting in place */
    int nnz = 0;
    for (int j = 0; j < nv; j++) {
        int s = q.colptr[j], e = q.colptr[j + 1];
        sort_rows(rows + s, e - s);
        q.colptr[j] = nnz;
        for (int t = s; t < e; t++) {
            if (t == s || rows[t] != rows[t - 1]) {
                q.mult[nnz] = 0;
                rows[nnz++] = rows[t];
            }
            q.mult[nnz - 1]++;
        }
        q.mult[nnz - 1]--; /* the diagonal's own entry is no face side */
        q.diag[j] = nnz - 1; /* the largest row of column j is j itself */
    }
    q.colptr[nv] = nnz;
    q.n = nv;
    q.nnz = nnz;
    q.rowind = realloc(rows, sizeof(int) * (size_t)(nnz ? nnz : 1));
    if (!q.rowind) {
        q.rowind = rows;
        goto nomem;
    }
    rows = NULL;
    for (int f = 0; want_tri && f < nf; f++)
        for (int k = 0; k < 3; k++) {
            int a = F[3 * (size_t)f + (k + 1) % 3], b = F[3 * (size_t)f + (k + 2) % 3];
            q.tri[3 * (size_t)f + k] =
                a == b ? -1 : find_entry(&q, a < b ? a : b, a > b ? a : b);
        }
    free(cnt);
    *p = q;
    return MCF_OK;
nomem:
    free(cnt);
    free(rows);
    mcf__pattern_free(&q);
    return mcf__fail(err, MCF_ENOMEM, "sparse pattern: out of memory (%d vertices, %d faces)", nv, nf);
}

void mcf__pattern_free(mcf__pattern *p)
{
    if (!p)
        return;
    free(p->colptr);
    free(p->rowind);
    free(p->diag);
    free(p->tri);
    free(p->mult);
    memset(p, 0, sizeof *p);
}

void mcf__pattern_fill_L(const mcf__pattern *p, const int32_t *F, int nf,
                         const double *w, double *val)
{
    memset(val, 0, sizeof(double) * (size_t)p->nnz);
    for (int f = 0; f < nf; f++)
        for (int k = 0; k < 3; k++) {
            int idx = p->tri[3 * (size_t)f + k];
            if (idx < 0)
                continue;
            double wk = w[3 * (size_t)f + k];
            int a = F[3 * (size_t)f + (k + 1) % 3], b = F[3 * (size_t)f + (k + 2) % 3];
            val[idx] -= wk;
            val[p->diag[a]] += wk;
            val[p->diag[b]] += wk;
        }
}

/* ---------------------------------------------------- public operators */

mcf_status mcf_operator_build(const mcf_mesh *m, mcf_laplacian lap,
                              mcf_mass mk, mcf_operator *out, mcf_error *err)
{
    mcf__pattern p = {0};
    mcf_operator o = {0};
    double *w = NULL, *area = NULL, *val = NULL;
    mcf_status rc;
    int *fill = NULL;
    if (!m || !out)
        return mcf__fail(err, MCF_EINVAL, "mcf_operator_build: NULL argument");
    if ((rc = mcf__pattern_build(m->F, m->nf, m->nv, 1, &p, err)) != MCF_OK)
        return rc;
    int n = m->nv, full = 2 * p.nnz - n;
    w = mcf__malloc(3 * (size_t)m->nf, sizeof *w);
    area = mcf__malloc((size_t)m->nf, sizeof *area);
    val = mcf__malloc((size_t)p.nnz, sizeof *val);
    fill = mcf__calloc((size_t)n + 1, sizeof *fill);
    o.n = n;
    o.rowptr = mcf__calloc((size_t)n + 1, sizeof *o.rowptr);
    o.col = mcf__malloc((size_t)full, sizeof *o.col);
    o.val = mcf__malloc((size_t)full, sizeof *o.val);
    o.mass = mcf__malloc((size_t)n, sizeof *o.mass);
    if (!w || !area || !val || !fill || !o.rowptr || !o.col || !o.val || !o.mass) {
        rc = mcf__fail(err, MCF_ENOMEM, "operator: out of memory");
        goto done;
    }
    mcf__cot_weights(m->X, m->F, m->nf, lap, MCF_MOLLIFY * mcf__mean_edge(m->X, m->F, m->nf), w, area);
    mcf__mass(m->X, m->F, m->nf, n, mk, area, o.mass);
    mcf__pattern_fill_L(&p, m->F, m->nf, w, val);
    /* upper CSC -> full CSR; visiting columns in order keeps rows sorted */
    for (int j = 0; j < n; j++)
        for (int t = p.colptr[j]; t < p.colptr[j + 1]; t++) {
            int i = p.rowind[t];
            o.rowptr[i + 1]++;
            if (i != j)
                o.rowptr[j + 1]++;
        }
    for (int i = 0; i < n; i++)
        o.rowptr[i + 1] += o.rowptr[i];
    for (int j = 0; j < n; j++)
        for (int t = p.colptr[j]; t < p.colptr[j + 1]; t++) {
            int i = p.rowind[t];
            int a = o.rowptr[j] + fill[j]++;
            o.col[a] = i;
            o.val[a] = val[t];
            if (i != j) {
                int b = o.rowptr[i] + fill[i]++;
                o.col[b] = j;
                o.val[b] = val[t];
            }
        }
    *out = o;
    memset(&o, 0, sizeof o);
    rc = MCF_OK;
done:
    mcf_operator_free(&o);
    mcf__pattern_free(&p);
    free(w);
    free(area);
    free(val);
    free(fill);
    return rc;
}

void mcf_operator_free(mcf_operator *op)
{
    if (!op)
        return;
    free(op->rowptr);
    free(op->col);
    free(op->val);
    free(op->mass);
    memset(op, 0, sizeof *op);
}

/* y = L x for one scalar column, from per-face weights. */
static void apply_L1(const int32_t *F, int nf, int nv, const double *w,
                     const double *x, double *y)
{
    memset(y, 0, sizeof(double) * (size_t)nv);
    for (int f = 0; f < nf; f++)
        for (int k = 0; k < 3; k++) {
            int i = F[3 * (size_t)f + (k + 1) % 3], j = F[3 * (size_t)f + (k + 2) % 3];
            double d = w[3 * (size_t)f + k] * (x[i] - x[j]);
            y[i] += d;
            y[j] -= d;
        }
}

mcf_status mcf_lambda_max(const mcf_mesh *m, mcf_laplacian lap, mcf_mass mk,
                          double *lambda, mcf_error *err)
{
    if (!m || !lambda)
        return mcf__fail(err, MCF_EINVAL, "mcf_lambda_max: NULL argument");
    int n = m->nv, nf = m->nf;
    double *w = mcf__malloc(3 * (size_t)nf, sizeof *w);
    double *area = mcf__malloc((size_t)nf, sizeof *area);
    double *mass = mcf__malloc((size_t)n, sizeof *mass);
    double *x = mcf__malloc((size_t)n, sizeof *x);
    double *y = mcf__malloc((size_t)n, sizeof *y);
    double *u = mcf__malloc((size_t)n, sizeof *u);
    mcf_status rc = MCF_OK;
    if (!w || !area || !mass || !x || !y || !u) {
        rc = mcf__fail(err, MCF_ENOMEM, "lambda_max: out of memory");
        goto done;
    }
    mcf__cot_weights(m->X, m->F, nf, lap, MCF_MOLLIFY * mcf__mean_edge(m->X, m->F, nf), w, area);
    mcf__mass(m->X, m->F, nf, n, mk, area, mass);
    /* Power iteration on S = M^-1/2 L M^-1/2 (symmetric, same spectrum as
     * M^-1 L). Start from a deterministic pseudo-random vector: the top
     * eigenvector oscillates at the grid scale, which a smooth start would
     * barely contain. Massless (unreferenced) vertices are left out. */
    uint64_t h = 0x9E3779B97F4A7C15ull;
    for (int i = 0; i < n; i++) {
        h ^= h >> 33; h *= 0xff51afd7ed558ccdull; h ^= h >> 29; h += 0x9E3779B97F4A7C15ull;
        x[i] = mass[i] > 0.0 ? (double)(h >> 11) * 0x1.0p-53 - 0.5 : 0.0;
    }
    double lam = 0.0;
    for (int it = 0; it < 200; it++) {
        double nx = 0.0;
        for (int i = 0; i < n; i++)
            nx += x[i] * x[i];
        nx = sqrt(nx);
        if (!(nx > 0.0))
            break;
        for (int i = 0; i < n; i++) {
            x[i] /= nx;
            u[i] = mass[i] > 0.0 ? x[i] / sqrt(mass[i]) : 0.0;
        }
        apply_L1(m->F, nf, n, w, u, y);
        double rq = 0.0;
        for (int i = 0; i < n; i++) {
            y[i] = mass[i] > 0.0 ? y[i] / sqrt(mass[i]) : 0.0;
            rq += x[i] * y[i];
        }
        double old = lam;
        lam = rq;
        memcpy(x, y, sizeof(double) * (size_t)n);
        if (it > 5 && fabs(lam - old) <= 1e-6 * fabs(lam))
            break;
    }
    if (!isfinite(lam) || lam < 0.0) {
        rc = mcf__fail(err, MCF_ENUMERIC, "lambda_max: power iteration gave %g", lam);
        goto done;
    }
    *lambda = lam;
done:
    free(w); free(area); free(mass); free(x); free(y); free(u);
    return rc;
}

/* The closest point to p on triangle (a, b, c) (Ericson, Real-Time
 * Collision Detection, 5.1.5) into q. */
void mcf__closest_on_triangle(const double *p, const double *a, const double *b, const double *c, double *q)
{
    double ab[3], ac[3], ap[3], bp[3], cp[3];
    mcf__sub3(b, a, ab);
    mcf__sub3(c, a, ac);
    mcf__sub3(p, a, ap);
    double d1 = mcf__dot3(ab, ap), d2 = mcf__dot3(ac, ap);
    if (d1 <= 0.0 && d2 <= 0.0) {
        memcpy(q, a, 3 * sizeof(double));
        return;
    }
    mcf__sub3(p, b, bp);
    double d3 = mcf__dot3(ab, bp), d4 = mcf__dot3(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) {
        memcpy(q, b, 3 * sizeof(double));
        return;
    }
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
        double v = d1 / (d1 - d3);
        for (int e = 0; e < 3; e++)
            q[e] = a[e] + v * ab[e];
        return;
    }
    mcf__sub3(p, c, cp);
    double d5 = mcf__dot3(ab, cp), d6 = mcf__dot3(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) {
        memcpy(q, c, 3 * sizeof(double));
        return;
    }
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
        double w = d2 / (d2 - d6);
        for (int e = 0; e < 3; e++)
            q[e] = a[e] + w * ac[e];
        return;
    }
    double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
        double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        for (int e = 0; e < 3; e++)
            q[e] = b[e] + w * (c[e] - b[e]);
        return;
    }
    double den = va + vb + vc;
    if (!(den > 0.0)) { /* degenerate triangle: its first corner */
        memcpy(q, a, 3 * sizeof(double));
        return;
    }
    double v = vb / den, w = vc / den;
    for (int e = 0; e < 3; e++)
        q[e] = a[e] + v * ab[e] + w * ac[e];
}
