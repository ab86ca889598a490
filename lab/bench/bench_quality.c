/* SPDX-License-Identifier: MIT */
/*
 * bench_quality.c - `make quality` (issue 16): how close to the clean
 * surface a noisy scan comes back, for the default request, every scheme
 * at its automatic amount, Taubin at its best pass count and Open3D's
 * filter_smooth_taubin, all in one run.
 *
 * Cases: every mesh of the list (default: the shared meshes) x noise kind
 * (`normal`: Gaussian along the vertex normals, mcf_flow_add_noise;
 * `iso`: isotropic Gaussian, each coordinate sigma = rho mean edges) x rho
 * (0.1, 0.25, 0.5 mean edges of the clean mesh) x seed (1..3). The noise
 * moves only what a run moves (the boundary and unreferenced vertices
 * stay, as mcf_flow_add_noise does for the default parameters).
 *
 * Methods (one row each per case in quality.csv):
 *   default      api_params_init + api_params_finish with nothing set:
 *                whatever the service does with `curl -F mesh=@scan /smooth`
 *   auto:S       the request `scheme=S` and no amount, for S in desbrun2,
 *                desbrun, ros2, richardson, cmcf, linear, taubin and every
 *                scheme whose name starts with "fairing" (the implicit MCF
 *                schemes and the filters; the explicit MCF schemes are
 *                unstable at 10 steps on scans, `implicit` too slow)
 *   fixed        desbrun2, strength 0.33, 10 steps (the old default): the
 *                peer of the CPU-time ratio of the automatic amounts
 *   taubin_best  scheme taubin at its best pass count (an oracle that
 *                knows the clean mesh: passes 1 .. 500 cumulatively on a
 *                growing schedule, stopped 5% past the minimum at twice
 *                the best count)
 *   o3d_default  Open3D's mesh.filter_smooth_taubin() (1 iteration,
 *                lambda 0.5, mu -0.53, uniform weights; Debian's
 *                python3-open3d through lab/bench/o3d_taubin.py, a coprocess)
 *   o3d_best     the same at its best pass count (the same oracle)
 *
 * Metrics per result: the per-vertex error (mcf_compare's area-weighted
 * RMS distance to the clean vertex) and the surface error (symmetric RMS
 * point-to-surface distance: samples at the vertices and face centroids of
 * one mesh, weighted by area, to the nearest point of the other's
 * triangles, both ways), each as a ratio of the noisy input's; new folds
 * (faces inverted against the clean mesh beyond the input's, and away
 * from the clean mesh's own creases); drift (volume of closed meshes, area
 * of open ones, vs clean); CPU time of the one run (this process's, or
 * the coprocess's for Open3D) and wall time.
 *
 * Output (QUALITY_OUT, lab/results/quality): quality.csv (every run), quality.md
 * (the tables: per method the median and worst over all cases of its
 * error against taubin_best, o3d_best and o3d_default, per-vertex and
 * surface; runs worse than the input; CPU time against `fixed` per mesh;
 * per mesh x noise the default's medians), worst.png (clean / noisy /
 * default / taubin_best / o3d_best of the case where the default does
 * worst against taubin_best, whole and zoomed). Single-threaded
 * (lab/Makefile pins OpenBLAS and OpenMP to one thread). Exit status 1
 * on an error.
 */
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "api.h"
#include "bench_common.h"
#include "lab.h"
#include "mcf.h"

#define PROG "bench_quality"
#define MAXMESH 24
#define MAXNOISE 4
#define MAXSEED 5
#define MAXMETHOD 16

typedef enum { K_DEFAULT, K_AUTO, K_FIXED, K_TAUBIN_BEST, K_O3D_DEFAULT, K_O3D_BEST } method_kind;

typedef struct {
    char name[32];
    method_kind kind;
    char scheme[24];
} method;

typedef struct {
    int ok;
    double ratio;        /* per-vertex error / the input's */
    double sratio;       /* surface error / the input's */
    int folds, folds_off;
    double drift;
    double cpu, wall;    /* seconds */
    double param;        /* t/h^2 for MCF, passes for the filters, steps for fairing */
    char note[200];
} result;

/* Taubin pass counts evaluated (cumulative) for the oracle. */
static const int g_passes[] = {1, 2, 3, 4, 5, 6, 8, 10, 12, 15, 20, 25, 30, 40, 50, 60,
                               80, 100, 120, 150, 200, 250, 300, 400, 500};
#define NPASSES ((int)(sizeof g_passes / sizeof g_passes[0]))

/* ------------------------------------------------------------ helpers */

static void die(const char *what, const mcf_error *e)
{
    fprintf(stderr, PROG ": %s: %s\n", what, e ? e->msg : "failed");
    exit(1);
}

static double cpu_now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}

static int cmp_d(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Median and maximum of the finite values of v (NaN when none); v is
 * sorted in place. */
static double median_max(double *v, int n, double *mx)
{
    int k = 0;
    for (int i = 0; i < n; i++)
        if (isfinite(v[i]))
            v[k++] = v[i];
    qsort(v, (size_t)k, sizeof *v, cmp_d);
    *mx = k ? v[k - 1] : NAN;
    return k ? (k % 2 ? v[k / 2] : 0.5 * (v[k / 2 - 1] + v[k / 2])) : NAN;
}

/* ------------------------------------------------------------ noise */

static uint64_t g_rng;
static double uniform01(void)
{
    uint64_t z = (g_rng += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    z ^= z >> 31;
    return ((z >> 11) + 0.5) * (1.0 / 9007199254740992.0);
}
static double gauss(void)
{
    return sqrt(-2.0 * log(uniform01())) * cos(6.283185307179586 * uniform01());
}

/* The noisy input: normal (mcf_flow_add_noise with the default
 * parameters) or isotropic noise of rho mean edges (sigma per coordinate)
 * on the vertices that normal noise moves (the others, the run's fixed
 * ones, stay). */
static mcf_mesh *make_noisy(const mcf_mesh *clean, int iso, double rho, int seed)
{
    mcf_flow_params p;
    mcf_error e = {0};
    mcf_flow_params_init(&p);
    mcf_mesh *m = bench_dup_mesh(PROG, clean);
    if (mcf_flow_add_noise(m, &p, rho, (uint64_t)seed, &e) != MCF_OK)
        die("mcf_flow_add_noise", &e);
    if (!iso)
        return m;
    mcf_mesh_info ci;
    if (mcf_mesh_inspect(clean, &ci, &e) != MCF_OK)
        die("mcf_mesh_inspect", &e);
    int nv = mcf_mesh_nvertices(m);
    double *X = malloc(3 * sizeof(double) * (size_t)nv);
    const double *N = mcf_mesh_positions(m), *C = mcf_mesh_positions(clean);
    g_rng = 0x15015015ULL * (uint64_t)seed + (uint64_t)(rho * 1e6);
    for (int i = 0; i < nv; i++) {
        int moved = memcmp(N + 3 * i, C + 3 * i, 3 * sizeof(double)) != 0;
        for (int d = 0; d < 3; d++)
            X[3 * i + d] = C[3 * i + d] + (moved ? rho * ci.mean_edge * gauss() : 0.0);
    }
    mcf_mesh *out = mcf_mesh_new(nv, X, mcf_mesh_nfaces(clean), mcf_mesh_faces(clean), &e);
    if (!out)
        die("mcf_mesh_new", &e);
    free(X);
    mcf_mesh_free(m);
    return out;
}
/* The clean mesh's own near-reversals: mask[f] = 1 when face f shares an
 * edge with a face whose normal is turned by more than 120 degrees from
 * its own, or has an edge with more than two faces. Models like snowden
 * (thin fins, fold-overs) and the crudely decimated dragon have thousands;
 * any smoothing flattens them, which turns such faces by over 90 degrees
 * against the clean normals, so the folds there are counted apart. */
typedef struct {
    int a, b, f;
} edge_ref;

static int cmp_edge(const void *x, const void *y)
{
    const edge_ref *p = x, *q = y;
    return p->a != q->a ? (p->a > q->a) - (p->a < q->a) : (p->b > q->b) - (p->b < q->b);
}

static void face_normal(const double *X, const int32_t *t, double n[3])
{
    const double *p = X + 3 * (size_t)t[0], *q = X + 3 * (size_t)t[1], *r = X + 3 * (size_t)t[2];
    double u[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]}, v[3] = {r[0] - p[0], r[1] - p[1], r[2] - p[2]};
    n[0] = u[1] * v[2] - u[2] * v[1];
    n[1] = u[2] * v[0] - u[0] * v[2];
    n[2] = u[0] * v[1] - u[1] * v[0];
}

static unsigned char *crease_mask(const mcf_mesh *m, int *count)
{
    int nf = mcf_mesh_nfaces(m);
    const int32_t *F = mcf_mesh_faces(m);
    const double *X = mcf_mesh_positions(m);
    edge_ref *E = malloc(3 * (size_t)nf * sizeof *E);
    unsigned char *mask = calloc((size_t)nf, 1);
    if (!E || !mask) {
        fprintf(stderr, PROG ": out of memory\n");
        exit(1);
    }
    for (int f = 0; f < nf; f++)
        for (int k = 0; k < 3; k++) {
            int a = F[3 * f + k], b = F[3 * f + (k + 1) % 3];
            E[3 * f + k] = (edge_ref){a < b ? a : b, a < b ? b : a, f};
        }
    qsort(E, 3 * (size_t)nf, sizeof *E, cmp_edge);
    for (size_t i = 0, j; i < 3 * (size_t)nf; i = j) {
        for (j = i + 1; j < 3 * (size_t)nf && E[j].a == E[i].a && E[j].b == E[i].b; j++)
            ;
        if (j - i > 2)
            for (size_t k = i; k < j; k++)
                mask[E[k].f] = 1;
        else if (j - i == 2) {
            double n1[3], n2[3];
            face_normal(X, F + 3 * E[i].f, n1);
            face_normal(X, F + 3 * E[i + 1].f, n2);
            double d = n1[0] * n2[0] + n1[1] * n2[1] + n1[2] * n2[2];
            double l = sqrt((n1[0] * n1[0] + n1[1] * n1[1] + n1[2] * n1[2]) *
                            (n2[0] * n2[0] + n2[1] * n2[1] + n2[2] * n2[2]));
            if (l > 0 && d < -0.5 * l)
                mask[E[i].f] = mask[E[i + 1].f] = 1;
        }
    }
    free(E);
    *count = 0;
    for (int f = 0; f < nf; f++)
        *count += mask[f];
    return mask;
}

/* Faces of x inverted against target (normals more than 90 degrees apart,
 * as mcf_compare counts them) that are not in the crease mask. */
static int inverted_off_crease(const mcf_mesh *x, const mcf_mesh *target, const unsigned char *mask)
{
    int nf = mcf_mesh_nfaces(x), n = 0;
    const int32_t *F = mcf_mesh_faces(x);
    for (int f = 0; f < nf; f++) {
        double a[3], b[3];
        if (mask[f])
            continue;
        face_normal(mcf_mesh_positions(x), F + 3 * f, a);
        face_normal(mcf_mesh_positions(target), F + 3 * f, b);
        double la = a[0] * a[0] + a[1] * a[1] + a[2] * a[2], lb = b[0] * b[0] + b[1] * b[1] + b[2] * b[2];
        if (la > 0 && lb > 0 && a[0] * b[0] + a[1] * b[1] + a[2] * b[2] < 0)
            n++;
    }
    return n;
}


/* ------------------------------------------------- surface distance */

/* A uniform grid over the triangles of a mesh: cell c holds the faces
 * whose bounding boxes overlap it (CSR: start[c] .. start[c + 1] of idx). */
typedef struct {
    const double *X;
    const int32_t *F;
    double lo[3], cell;
    int n[3];
    int *start, *idx;
} tri_grid;

static int clampi(int v, int lo, int hi)
{
    return v < lo ? lo : v > hi ? hi : v;
}

static void grid_build(tri_grid *g, const mcf_mesh *m)
{
    int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m);
    double hi[3] = {-INFINITY, -INFINITY, -INFINITY}, edge = 0.0;
    g->X = mcf_mesh_positions(m);
    g->F = mcf_mesh_faces(m);
    for (int d = 0; d < 3; d++)
        g->lo[d] = INFINITY;
    for (int i = 0; i < nv; i++)
        for (int d = 0; d < 3; d++) {
            g->lo[d] = fmin(g->lo[d], g->X[3 * i + d]);
            hi[d] = fmax(hi[d], g->X[3 * i + d]);
        }
    for (int f = 0; f < nf; f++) {
        const double *a = g->X + 3 * (size_t)g->F[3 * f], *b = g->X + 3 * (size_t)g->F[3 * f + 1];
        edge += sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
    }
    /* cells of about a mean edge (a few triangles each), at most 2^22 */
    g->cell = fmax(edge / (nf > 0 ? nf : 1), 1e-12);
    for (;;) {
        double cells = 1;
        for (int d = 0; d < 3; d++) {
            g->n[d] = (int)((hi[d] - g->lo[d]) / g->cell) + 1;
            cells *= g->n[d];
        }
        if (cells <= 4194304)
            break;
        g->cell *= 1.5;
    }
    size_t nc = (size_t)g->n[0] * g->n[1] * g->n[2];
    g->start = calloc(nc + 1, sizeof(int));
    int *cnt = NULL;
    for (int pass = 0; pass < 2; pass++) {
        for (int f = 0; f < nf; f++) {
            int b0[3], b1[3];
            for (int d = 0; d < 3; d++) {
                double mn = INFINITY, mx = -INFINITY;
                for (int k = 0; k < 3; k++) {
                    double v = g->X[3 * (size_t)g->F[3 * f + k] + d];
                    mn = fmin(mn, v);
                    mx = fmax(mx, v);
                }
                b0[d] = clampi((int)((mn - g->lo[d]) / g->cell), 0, g->n[d] - 1);
                b1[d] = clampi((int)((mx - g->lo[d]) / g->cell), 0, g->n[d] - 1);
            }
            for (int x = b0[0]; x <= b1[0]; x++)
                for (int y = b0[1]; y <= b1[1]; y++)
                    for (int z = b0[2]; z <= b1[2]; z++) {
                        size_t c = ((size_t)x * g->n[1] + y) * g->n[2] + z;
                        if (pass == 0)
                            g->start[c + 1]++;
                        else
                            g->idx[cnt[c]++] = f;
                    }
        }
        if (pass == 0) {
            for (size_t c = 0; c < nc; c++)
                g->start[c + 1] += g->start[c];
            g->idx = malloc(sizeof(int) * (size_t)(g->start[nc] > 0 ? g->start[nc] : 1));
            cnt = malloc(sizeof(int) * nc);
            if (!g->idx || !cnt) {
                fprintf(stderr, PROG ": out of memory (grid)\n");
                exit(1);
            }
            memcpy(cnt, g->start, sizeof(int) * nc);
        }
    }
    free(cnt);
}

static void grid_free(tri_grid *g)
{
    free(g->start);
    free(g->idx);
}

/* |a + t e - p|^2 */
static double along2(const double *a, const double *e, double t, const double *p)
{
    double q[3] = {a[0] + t * e[0] - p[0], a[1] + t * e[1] - p[1], a[2] + t * e[2] - p[2]};
    return q[0] * q[0] + q[1] * q[1] + q[2] * q[2];
}

/* Squared distance from p to triangle abc (Ericson, Real-Time Collision
 * Detection, 5.1.5: the closest point by Voronoi regions). */
static double tri_dist2(const double *p, const double *a, const double *b, const double *c)
{
    double ab[3], ac[3], ap[3], q[3];
    for (int d = 0; d < 3; d++) {
        ab[d] = b[d] - a[d];
        ac[d] = c[d] - a[d];
        ap[d] = p[d] - a[d];
    }
#define DOT(u, v) ((u)[0] * (v)[0] + (u)[1] * (v)[1] + (u)[2] * (v)[2])
    double d1 = DOT(ab, ap), d2 = DOT(ac, ap);
    if (d1 <= 0 && d2 <= 0)
        return DOT(ap, ap);
    double bp[3] = {p[0] - b[0], p[1] - b[1], p[2] - b[2]};
    double d3 = DOT(ab, bp), d4 = DOT(ac, bp);
    if (d3 >= 0 && d4 <= d3)
        return DOT(bp, bp);
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0)
        return along2(a, ab, d1 / (d1 - d3), p);
    double cp[3] = {p[0] - c[0], p[1] - c[1], p[2] - c[2]};
    double d5 = DOT(ab, cp), d6 = DOT(ac, cp);
    if (d6 >= 0 && d5 <= d6)
        return DOT(cp, cp);
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0)
        return along2(a, ac, d2 / (d2 - d6), p);
    double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
        double bc[3] = {c[0] - b[0], c[1] - b[1], c[2] - b[2]};
        return along2(b, bc, (d4 - d3) / ((d4 - d3) + (d5 - d6)), p);
    }
    double den = 1.0 / (va + vb + vc), v = vb * den, w = vc * den;
    for (int d = 0; d < 3; d++)
        q[d] = a[d] + ab[d] * v + ac[d] * w - p[d];
    return DOT(q, q);
#undef DOT
}

/* Squared distance from p to the nearest triangle of g: shells of cells
 * around p's cell until the shell lies farther than the best so far. */
static double grid_dist2(const tri_grid *g, const double *p)
{
    int c0[3];
    double margin = INFINITY; /* p's distance to its own cell's nearest face */
    for (int d = 0; d < 3; d++) {
        double u = (p[d] - g->lo[d]) / g->cell;
        c0[d] = clampi((int)floor(u), 0, g->n[d] - 1);
        double fr = u - c0[d];
        margin = fmin(margin, fr < 0 || fr > 1 ? 0.0 : fmin(fr, 1.0 - fr));
    }
    double best = INFINITY;
    int rmax = g->n[0] + g->n[1] + g->n[2];
    for (int r = 0; r <= rmax; r++) {
        /* every cell of shell r lies at least (r - 1 + margin) cells from p */
        double near = (r - 1 + margin) * g->cell;
        if (r > 0 && near > 0 && near * near >= best)
            break;
        for (int x = c0[0] - r; x <= c0[0] + r; x++)
            for (int y = c0[1] - r; y <= c0[1] + r; y++)
                for (int z = c0[2] - r; z <= c0[2] + r; z++) {
                    int dx = abs(x - c0[0]), dy = abs(y - c0[1]), dz = abs(z - c0[2]);
                    int cheb = dx > dy ? (dx > dz ? dx : dz) : (dy > dz ? dy : dz);
                    if (cheb != r || x < 0 || y < 0 || z < 0 || x >= g->n[0] || y >= g->n[1] || z >= g->n[2])
                        continue;
                    size_t c = ((size_t)x * g->n[1] + y) * g->n[2] + z;
                    for (int k = g->start[c]; k < g->start[c + 1]; k++) {
                        const int32_t *t = g->F + 3 * (size_t)g->idx[k];
                        double d2 = tri_dist2(p, g->X + 3 * (size_t)t[0], g->X + 3 * (size_t)t[1],
                                              g->X + 3 * (size_t)t[2]);
                        if (d2 < best)
                            best = d2;
                    }
                }
    }
    return best;
}

/* Area-weighted mean squared distance from the samples of m (vertices,
 * weight area/6 per face corner, and face centroids, area/2) to g's
 * surface. */
static double sampled_ms(const mcf_mesh *m, const tri_grid *g)
{
    const double *X = mcf_mesh_positions(m);
    const int32_t *F = mcf_mesh_faces(m);
    int nf = mcf_mesh_nfaces(m), nv = mcf_mesh_nvertices(m);
    double *w = calloc((size_t)nv, sizeof(double)), s = 0.0, ws = 0.0;
    for (int f = 0; f < nf; f++) {
        const double *a = X + 3 * (size_t)F[3 * f], *b = X + 3 * (size_t)F[3 * f + 1], *c = X + 3 * (size_t)F[3 * f + 2];
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
        double A = 0.5 * sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        double p[3] = {(a[0] + b[0] + c[0]) / 3, (a[1] + b[1] + c[1]) / 3, (a[2] + b[2] + c[2]) / 3};
        s += 0.5 * A * grid_dist2(g, p);
        ws += 0.5 * A;
        for (int k = 0; k < 3; k++)
            w[F[3 * f + k]] += A / 6;
    }
    for (int i = 0; i < nv; i++)
        if (w[i] > 0) {
            s += w[i] * grid_dist2(g, X + 3 * (size_t)i);
            ws += w[i];
        }
    free(w);
    return ws > 0 ? s / ws : 0.0;
}

/* The symmetric RMS surface distance between m and the clean mesh (whose
 * grid is given). */
static double surface_error(const mcf_mesh *m, const mcf_mesh *clean, const tri_grid *gclean)
{
    tri_grid gm;
    grid_build(&gm, m);
    double a = sampled_ms(m, gclean), b = sampled_ms(clean, &gm);
    grid_free(&gm);
    return sqrt(0.5 * (a + b));
}

/* ------------------------------------------------------------ cases */

typedef struct {
    const mcf_mesh *clean, *noisy;
    const tri_grid *gclean;
    double e0, s0;       /* the noisy input's vertex and surface errors */
    int fold0, fold0_off;
    const unsigned char *crease;
    double ref_size;     /* clean volume (closed) or area (open) */
    int closed;
    double h;            /* noisy mean edge / sqrt(noisy area): the t/h^2 unit */
} case_ctx;

/* Fills r's error metrics for result m (a smoothed copy of c->noisy). */
static void measure(const case_ctx *c, const mcf_mesh *m, result *r)
{
    mcf_compare_result a;
    mcf_error e = {0};
    if (mcf_compare(m, c->clean, &a, &e) != MCF_OK)
        die("mcf_compare", &e);
    r->ratio = a.rms_m / c->e0;
    r->sratio = surface_error(m, c->clean, c->gclean) / c->s0;
    r->folds = a.inverted_faces - c->fold0;
    r->folds_off = inverted_off_crease(m, c->clean, c->crease) - c->fold0_off;
    double s = c->closed ? mcf_mesh_volume(m) : mcf_mesh_area(m);
    r->drift = (s - c->ref_size) / fabs(c->ref_size);
}

static void failed(result *r, const char *what, const char *msg)
{
    r->ok = 0;
    r->ratio = r->sratio = r->drift = NAN;
    r->folds = r->folds_off = -1;
    snprintf(r->note, sizeof r->note, "%s: %s", what, msg);
    for (char *q = r->note; *q; q++)
        if (*q == '"' || *q == '\n')
            *q = '\'';
}

/* A request through the api layer's parameters: nothing set (default),
 * scheme=S alone (auto) or desbrun2 strength 0.33 (fixed). */
static void run_request(const case_ctx *c, const method *md, result *r, mcf_mesh **out)
{
    api_limits lim;
    api_params p;
    mcf_error e = {0};
    mcf_flow_stats st;
    mcf_mesh *m = bench_dup_mesh(PROG, c->noisy);
    memset(&st, 0, sizeof st);
    api_limits_default(&lim);
    api_params_init(&p);
    if ((md->kind == K_AUTO && api_params_set(&p, "scheme", md->scheme, &lim, &e) != MCF_OK) ||
        (md->kind == K_FIXED && (api_params_set(&p, "scheme", "desbrun2", &lim, &e) != MCF_OK ||
                                 api_params_set(&p, "strength", "0.33", &lim, &e) != MCF_OK))) {
        failed(r, md->name, e.msg);
        goto done;
    }
    double c0 = cpu_now(), w0 = mcf_now();
    if (api_params_finish(&p, mcf_mesh_nvertices(m), &lim, &e) != MCF_OK ||
        mcf_flow_run(m, &p.flow, &st, &e) != MCF_OK) {
        failed(r, md->name, e.msg);
        goto done;
    }
    r->cpu = cpu_now() - c0;
    r->wall = mcf_now() - w0;
    r->ok = 1;
    const mcf_scheme_info *si = mcf_scheme_get(p.flow.scheme);
    r->param = p.flow.scheme == MCF_TAUBIN || (si && si->order == 0) ? st.steps : st.t_final / (c->h * c->h);
    measure(c, m, r);
done:
    mcf_flow_stats_free(&st);
    api_params_free(&p);
    if (out && r->ok)
        *out = m;
    else
        mcf_mesh_free(m);
}

/* Taubin at its best pass count (see the file comment). */
static void run_taubin_best(const case_ctx *c, result *best, mcf_mesh **out)
{
    mcf_flow_params p;
    mcf_error e = {0};
    mcf_mesh *m = bench_dup_mesh(PROG, c->noisy);
    int have = 0, bestp = 0;
    double bestr = INFINITY;
    mcf_flow_params_init(&p);
    p.scheme = MCF_TAUBIN;
    for (int i = 0; i < NPASSES; i++) {
        p.iterations = g_passes[i] - have;
        if (mcf_flow_run(m, &p, NULL, &e) != MCF_OK)
            break;
        have = g_passes[i];
        mcf_compare_result a;
        if (mcf_compare(m, c->clean, &a, &e) != MCF_OK)
            die("mcf_compare", &e);
        if (a.rms_m < bestr) {
            bestr = a.rms_m;
            bestp = have;
        }
        if ((a.rms_m > 1.05 * bestr && have >= 2 * bestp) || a.rms_m > 1.5 * bestr)
            break;
    }
    mcf_mesh_free(m);
    if (bestp == 0) {
        failed(best, "taubin_best", e.msg);
        return;
    }
    m = bench_dup_mesh(PROG, c->noisy);
    p.iterations = bestp;
    double c0 = cpu_now(), w0 = mcf_now();
    mcf_status s = mcf_flow_run(m, &p, NULL, &e);
    best->cpu = cpu_now() - c0;
    best->wall = mcf_now() - w0;
    best->param = bestp;
    if (s != MCF_OK)
        failed(best, "taubin_best", e.msg);
    else {
        best->ok = 1;
        measure(c, m, best);
    }
    if (out && best->ok)
        *out = m;
    else
        mcf_mesh_free(m);
}

/* ------------------------------------------------------------ Open3D */

/* The coprocess (lab/bench/o3d_taubin.py): pid, its stdin and stdout. */
static struct {
    pid_t pid;
    FILE *to, *from;
    char version[64];
} g_o3d;
static char g_tmp[256];

static void o3d_start(const char *script)
{
    int in[2], outp[2];
    if (pipe(in) != 0 || pipe(outp) != 0)
        return;
    pid_t pid = fork();
    if (pid < 0)
        return;
    if (pid == 0) {
        dup2(in[0], 0);
        dup2(outp[1], 1);
        close(in[1]);
        close(outp[0]);
        setenv("OMP_NUM_THREADS", "1", 1);
        execl("/usr/bin/python3", "python3", script, (char *)NULL);
        _exit(127);
    }
    close(in[0]);
    close(outp[1]);
    g_o3d.pid = pid;
    g_o3d.to = fdopen(in[1], "w");
    g_o3d.from = fdopen(outp[0], "r");
    char line[256];
    if (!g_o3d.from || !fgets(line, sizeof line, g_o3d.from) || strncmp(line, "ready ", 6) != 0) {
        fprintf(stderr, PROG ": %s did not start (python3-open3d missing?): the Open3D columns are skipped\n", script);
        if (g_o3d.to)
            fclose(g_o3d.to);
        if (g_o3d.from)
            fclose(g_o3d.from);
        waitpid(pid, NULL, 0);
        memset(&g_o3d, 0, sizeof g_o3d);
        return;
    }
    line[strcspn(line, "\n")] = 0;
    snprintf(g_o3d.version, sizeof g_o3d.version, "%.60s", line + 6);
}

static void o3d_stop(void)
{
    if (!g_o3d.pid)
        return;
    fclose(g_o3d.to);
    fclose(g_o3d.from);
    waitpid(g_o3d.pid, NULL, 0);
    g_o3d.pid = 0;
}

static void write_raw(const char *path, const mcf_mesh *m)
{
    FILE *f = fopen(path, "wb");
    int32_t n[2] = {mcf_mesh_nvertices(m), mcf_mesh_nfaces(m)};
    if (!f || fwrite(n, sizeof n, 1, f) != 1 ||
        fwrite(mcf_mesh_positions(m), 3 * sizeof(double), (size_t)n[0], f) != (size_t)n[0] ||
        fwrite(mcf_mesh_faces(m), 3 * sizeof(int32_t), (size_t)n[1], f) != (size_t)n[1] || fclose(f) != 0) {
        fprintf(stderr, PROG ": cannot write %s\n", path);
        exit(1);
    }
}

/* Open3D's default and best on c->noisy into r[0] and r[1]. */
static void run_o3d(const case_ctx *c, result r[2], mcf_mesh *out[2])
{
    char pn[300], pc[300], po[300], line[512];
    if (!g_o3d.pid) {
        failed(&r[0], "o3d_default", "python3-open3d not available");
        failed(&r[1], "o3d_best", "python3-open3d not available");
        return;
    }
    snprintf(pn, sizeof pn, "%s/noisy.bin", g_tmp);
    snprintf(pc, sizeof pc, "%s/clean.bin", g_tmp);
    snprintf(po, sizeof po, "%s/out.bin", g_tmp);
    write_raw(pn, c->noisy);
    write_raw(pc, c->clean);
    fprintf(g_o3d.to, "%s %s %s\n", pn, pc, po);
    fflush(g_o3d.to);
    if (!fgets(line, sizeof line, g_o3d.from) || strncmp(line, "ok", 2) != 0) {
        line[strcspn(line, "\n")] = 0;
        failed(&r[0], "o3d_default", line);
        failed(&r[1], "o3d_best", line);
        return;
    }
    FILE *f = fopen(po, "rb");
    int nv = mcf_mesh_nvertices(c->noisy);
    int32_t passes = 0;
    double cpu[2];
    mcf_mesh *m[2] = {bench_dup_mesh(PROG, c->noisy), bench_dup_mesh(PROG, c->noisy)};
    if (!f || fread(&passes, sizeof passes, 1, f) != 1 || fread(cpu, sizeof cpu, 1, f) != 1 ||
        fread(mcf_mesh_positions_mut(m[0]), 3 * sizeof(double), (size_t)nv, f) != (size_t)nv ||
        fread(mcf_mesh_positions_mut(m[1]), 3 * sizeof(double), (size_t)nv, f) != (size_t)nv) {
        fprintf(stderr, PROG ": cannot read %s\n", po);
        exit(1);
    }
    fclose(f);
    for (int k = 0; k < 2; k++) {
        r[k].ok = 1;
        r[k].cpu = r[k].wall = cpu[k];
        r[k].param = k ? passes : 1;
        measure(c, m[k], &r[k]);
        if (out)
            out[k] = m[k];
        else
            mcf_mesh_free(m[k]);
    }
}
/* ------------------------------------------------------------ figure */

/* Writes the triangles of m (those whose centroid passes the crop box,
 * when crop) as gnuplot polygon blocks with a Lambert grey per face from a
 * fixed light, in the view frame given by the rotation R (3x3 row-major). */
static void write_tris(const char *dir, const char *name, const mcf_mesh *m, const double R[9],
                       const double *crop)
{
    FILE *f = bench_open_out(dir, name);
    const double *X = mcf_mesh_positions(m);
    const int32_t *F = mcf_mesh_faces(m);
    int nf = mcf_mesh_nfaces(m);
    const double L[3] = {0.35, 0.45, 0.82}; /* view frame: toward the viewer, up-right */
    fprintf(f, "# %s: one triangle per block, x y z rgb (view frame)\n", name);
    for (int t = 0; t < nf; t++) {
        double P[3][3];
        for (int k = 0; k < 3; k++) {
            const double *x = X + 3 * (size_t)F[3 * t + k];
            for (int r = 0; r < 3; r++)
                P[k][r] = R[3 * r] * x[0] + R[3 * r + 1] * x[1] + R[3 * r + 2] * x[2];
        }
        if (crop) {
            double cx = (P[0][0] + P[1][0] + P[2][0]) / 3, cy = (P[0][1] + P[1][1] + P[2][1]) / 3;
            if (cx < crop[0] || cx > crop[1] || cy < crop[2] || cy > crop[3])
                continue;
        }
        double u[3], v[3], n[3];
        for (int r = 0; r < 3; r++) {
            u[r] = P[1][r] - P[0][r];
            v[r] = P[2][r] - P[0][r];
        }
        n[0] = u[1] * v[2] - u[2] * v[1];
        n[1] = u[2] * v[0] - u[0] * v[2];
        n[2] = u[0] * v[1] - u[1] * v[0];
        double nn = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        if (nn == 0)
            continue;
        double lam = (n[0] * L[0] + n[1] * L[1] + n[2] * L[2]) / nn;
        /* two-sided, a little ambient so back faces are not black */
        double g = 0.12 + 0.88 * fabs(lam);
        if (n[2] < 0)
            g *= 0.75; /* back-facing: darker */
        int gi = (int)(255 * g);
        int rgb = (gi * 235 / 255) << 16 | (gi * 225 / 255) << 8 | (gi * 205 / 255);
        for (int k = 0; k < 3; k++)
            fprintf(f, "%.6g %.6g %.6g %d\n", P[k][0], P[k][1], P[k][2], rgb);
        fprintf(f, "\n");
    }
    fclose(f);
}

typedef struct {
    const char *mesh;
    double rho;
    int seed;
    double view_rot_y; /* degrees about the vertical axis */
    double crop[4];    /* fraction of the bounding box in the view frame: x0 x1 y0 y1 */
} figure_spec;

/* A view rotation: about x by ax degrees (y up -> the mesh's up axis),
 * then about the vertical axis by ay degrees. */
static void view_matrix(double ax, double ay, double R[9])
{
    const double deg = 3.14159265358979323846 / 180;
    double a = ax * deg, b = ay * deg;
    double Rx[9] = {1, 0, 0, 0, cos(a), -sin(a), 0, sin(a), cos(a)};
    double Ry[9] = {cos(b), 0, sin(b), 0, 1, 0, -sin(b), 0, cos(b)};
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double s = 0;
            for (int k = 0; k < 3; k++)
                s += Ry[3 * i + k] * Rx[3 * k + j];
            R[3 * i + j] = s;
        }
}

static void figure(const char *out, const char *stem, const figure_spec *fs,
                   const mcf_mesh *const ms[], const char *const titles[], int n)
{
    double R[9], lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY}, crop[4];
    view_matrix(0, fs->view_rot_y, R);
    const double *X = mcf_mesh_positions(ms[0]);
    for (int i = 0; i < mcf_mesh_nvertices(ms[0]); i++)
        for (int r = 0; r < 2; r++) {
            double y = R[3 * r] * X[3 * i] + R[3 * r + 1] * X[3 * i + 1] + R[3 * r + 2] * X[3 * i + 2];
            lo[r] = y < lo[r] ? y : lo[r];
            hi[r] = y > hi[r] ? y : hi[r];
        }
    crop[0] = lo[0] + fs->crop[0] * (hi[0] - lo[0]);
    crop[1] = lo[0] + fs->crop[1] * (hi[0] - lo[0]);
    crop[2] = lo[1] + fs->crop[2] * (hi[1] - lo[1]);
    crop[3] = lo[1] + fs->crop[3] * (hi[1] - lo[1]);
    char gp[256], png[256];
    int rows = n > 3 ? 2 : 1, cols = (n + rows - 1) / rows;
    double aspect = (crop[3] - crop[2]) / (crop[1] - crop[0]);
    snprintf(gp, sizeof gp, "%s.gp", stem);
    snprintf(png, sizeof png, "%s.png", stem);
    FILE *g = bench_open_out(out, gp);
    fprintf(g, "# SPDX-License-Identifier: MIT\n# bench_quality: clean / noisy / smoothed renders of %s at noise %g (seed %d)\n"
               "# run in this folder: gnuplot %s (needs the render-*.dat files bench_quality\n"
               "# writes and removes; rerun bench_quality to regenerate)\n"
               "set terminal pngcairo size %d,%d font 'sans,11'\n"
               "set output '%s'\n"
               "set multiplot layout %d,%d title '%s, noise %g mean edges (seed %d): clean, noisy, smoothed "
               "(error / noisy error)' noenhanced\n"
               "set view 0,0,1.4\nset view equal xy\nset size ratio -1\nunset border\nunset tics\nunset key\nunset colorbox\n"
               "set xrange [%.9g:%.9g]\nset yrange [%.9g:%.9g]\n"
               "set pm3d depthorder lighting primary 0.45 specular 0.15 spec2 0.25\n"
               "set style fill solid noborder\n",
            fs->mesh, fs->rho, fs->seed, gp, 420 * cols, (int)(rows * (420 * aspect + 40) + 40), png,
            rows, cols, fs->mesh, fs->rho, fs->seed, crop[0], crop[1], crop[2], crop[3]);
    for (int i = 0; i < n; i++) {
        char name[64];
        snprintf(name, sizeof name, "render-%d.dat", i);
        write_tris(out, name, ms[i], R, crop);
        fprintf(g, "set title '%s' noenhanced\nsplot '%s' using 1:2:3 with polygons fc rgb '#e0d4bc'\n",
                titles[i], name);
    }
    fprintf(g, "unset multiplot\n");
    fclose(g);
    if (lab_gnuplot(out, gp) == 0)
        printf("figure: %s/%s\n", out, png);
    else
        printf("figure: gnuplot failed or is missing (%s/%s written)\n", out, gp);
    for (int i = 0; i < n; i++) {
        char path[4096];
        snprintf(path, sizeof path, "%s/render-%d.dat", out, i);
        remove(path);
    }
}

/* ------------------------------------------------------------ main */

static void split(char *s, char **out, int max, int *n)
{
    *n = 0;
    for (char *t = strtok(s, ","); t && *n < max; t = strtok(NULL, ","))
        out[(*n)++] = t;
}

static void usage(void)
{
    fprintf(stderr,
            "usage: bench_quality [--meshes DIR] [--out DIR] [--list a.obj,b.drc,...] [--noise 0.1,0.25,0.5]\n"
            "                     [--kinds normal,iso] [--seeds N] [--methods NAME,...] [--o3d SCRIPT]\n"
            "                     [--no-figure]\n"
            "  methods: default, auto:SCHEME, fixed, taubin_best, o3d_default, o3d_best (default: all)\n");
    exit(2);
}

static const char *const kind_names[2] = {"normal", "iso"};

/* results[mesh][kind][noise][seed][method] */
static result *g_res;
static int g_nk, g_nr, g_ns, g_nmeth;
static result *R(int m, int k, int j, int s, int q)
{
    return &g_res[((((size_t)m * g_nk + k) * g_nr + j) * g_ns + s) * g_nmeth + q];
}

/* Per method over the cases of kind k (-1: all): median and worst of the
 * ratio of its error (surface error when surf) against method `peer`'s
 * in the same case. */
static void versus(int nm, int k, int q, int peer, int surf, double *med, double *worst)
{
    double *v = malloc(sizeof(double) * (size_t)(nm * g_nk * g_nr * g_ns) + 1);
    int n = 0;
    for (int m = 0; m < nm; m++)
        for (int kk = 0; kk < g_nk; kk++)
            for (int j = 0; j < g_nr; j++)
                for (int s = 0; s < g_ns; s++) {
                    if (k >= 0 && kk != k)
                        continue;
                    const result *a = R(m, kk, j, s, q), *b = peer >= 0 ? R(m, kk, j, s, peer) : NULL;
                    double x = surf ? a->sratio : a->ratio, y = !b ? 1.0 : surf ? b->sratio : b->ratio;
                    v[n++] = !a->ok ? INFINITY : b && !b->ok ? NAN : x / y;
                }
    *med = median_max(v, n, worst);
    free(v);
}

int main(int argc, char **argv)
{
    const char *meshes = "../shared/meshes", *out = "lab/results/quality", *o3d_script = "o3d_taubin.py";
    char list_buf[1024] = "sphere_cgal.obj,bunny_npm_closed.obj,spot.obj,knot1.obj,fertility.obj,"
                          "stanford-bunny.obj,bunny.drc,armadillo.obj,snowden.obj,dragon_vrip_res2.obj";
    char noise_buf[256] = "0.1,0.25,0.5", kinds_buf[64] = "normal,iso", methods_buf[512] = "";
    int do_figure = 1;
    double t_start = mcf_now();
    g_ns = 3;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--meshes") && v)
            meshes = v, i++;
        else if (!strcmp(a, "--out") && v)
            out = v, i++;
        else if (!strcmp(a, "--list") && v)
            snprintf(list_buf, sizeof list_buf, "%s", v), i++;
        else if (!strcmp(a, "--noise") && v)
            snprintf(noise_buf, sizeof noise_buf, "%s", v), i++;
        else if (!strcmp(a, "--kinds") && v)
            snprintf(kinds_buf, sizeof kinds_buf, "%s", v), i++;
        else if (!strcmp(a, "--methods") && v)
            snprintf(methods_buf, sizeof methods_buf, "%s", v), i++;
        else if (!strcmp(a, "--seeds") && v)
            g_ns = atoi(v), i++;
        else if (!strcmp(a, "--o3d") && v)
            o3d_script = v, i++;
        else if (!strcmp(a, "--no-figure"))
            do_figure = 0;
        else
            usage();
    }
    if (g_ns < 1 || g_ns > MAXSEED)
        usage();

    /* the methods: every one, or those named */
    method meth[MAXMETHOD];
    int nmeth = 0;
    meth[nmeth++] = (method){"default", K_DEFAULT, ""};
    static const char *const autos[] = {"desbrun2", "desbrun", "ros2", "richardson", "cmcf", "linear", "taubin"};
    for (int s = 0; s < MCF_NSCHEMES + 8; s++) {
        const mcf_scheme_info *si = mcf_scheme_get((mcf_scheme)s);
        if (si && !strncmp(si->name, "fairing", 7) && nmeth < MAXMETHOD) {
            meth[nmeth] = (method){"", K_AUTO, ""};
            snprintf(meth[nmeth].name, sizeof meth[nmeth].name, "auto:%s", si->name);
            snprintf(meth[nmeth++].scheme, sizeof meth[0].scheme, "%s", si->name);
        }
    }
    for (size_t s = 0; s < sizeof autos / sizeof autos[0]; s++) {
        meth[nmeth] = (method){"", K_AUTO, ""};
        snprintf(meth[nmeth].name, sizeof meth[nmeth].name, "auto:%s", autos[s]);
        snprintf(meth[nmeth++].scheme, sizeof meth[0].scheme, "%s", autos[s]);
    }
    meth[nmeth++] = (method){"fixed", K_FIXED, ""};
    meth[nmeth++] = (method){"taubin_best", K_TAUBIN_BEST, ""};
    meth[nmeth++] = (method){"o3d_default", K_O3D_DEFAULT, ""};
    meth[nmeth++] = (method){"o3d_best", K_O3D_BEST, ""};
    if (methods_buf[0]) {
        char *mt[MAXMETHOD];
        int nmt, keep = 0;
        split(methods_buf, mt, MAXMETHOD, &nmt);
        for (int q = 0; q < nmeth; q++)
            for (int k = 0; k < nmt; k++)
                if (!strcmp(mt[k], meth[q].name))
                    meth[keep++] = meth[q];
        nmeth = keep;
    }
    int q_default = -1, q_fixed = -1, q_tb = -1, q_od = -1, q_ob = -1;
    for (int q = 0; q < nmeth; q++)
        switch (meth[q].kind) {
        case K_DEFAULT: q_default = q; break;
        case K_FIXED: q_fixed = q; break;
        case K_TAUBIN_BEST: q_tb = q; break;
        case K_O3D_DEFAULT: q_od = q; break;
        case K_O3D_BEST: q_ob = q; break;
        default: break;
        }
    g_nmeth = nmeth;

    char *names[MAXMESH], *ntext[MAXNOISE], *ktext[2];
    int nm, kinds[2];
    double rho[MAXNOISE];
    /* the lists as given, for quality.md (split cuts them up) */
    char noise_given[sizeof noise_buf], kinds_given[sizeof kinds_buf];
    memcpy(noise_given, noise_buf, sizeof noise_buf);
    memcpy(kinds_given, kinds_buf, sizeof kinds_buf);
    split(list_buf, names, MAXMESH, &nm);
    split(noise_buf, ntext, MAXNOISE, &g_nr);
    split(kinds_buf, ktext, 2, &g_nk);
    for (int j = 0; j < g_nr; j++)
        rho[j] = atof(ntext[j]);
    for (int k = 0; k < g_nk; k++) {
        if (strcmp(ktext[k], "normal") && strcmp(ktext[k], "iso"))
            usage();
        kinds[k] = !strcmp(ktext[k], "iso");
    }

    bench_print_machine();
    lab_prog = PROG;
    if (lab_mkdir_p(out) != 0)
        return 1;
    {
        api_params p;
        api_params_init(&p);
        api_params_finish(&p, 1000, NULL, NULL);
        printf("default request: scheme %s, automatic amount %s\n", mcf_scheme_get(p.flow.scheme)->name,
               p.flow.strength_auto ? "yes" : "no");
        api_params_free(&p);
    }
    snprintf(g_tmp, sizeof g_tmp, "/tmp/bench_quality.%d", (int)getpid());
    if (lab_mkdir_p(g_tmp) != 0)
        return 1;
    if (q_od >= 0 || q_ob >= 0) {
        o3d_start(o3d_script);
        if (g_o3d.pid)
            printf("Open3D %s (coprocess %s)\n", g_o3d.version, o3d_script);
    }
    signal(SIGPIPE, SIG_IGN);

    g_res = calloc((size_t)nm * g_nk * g_nr * g_ns * nmeth, sizeof(result));
    if (!g_res)
        die("calloc", NULL);
    FILE *csv = bench_open_out(out, "quality.csv");
    fprintf(csv, "mesh,nv,nf,closed,noise_kind,noise,seed,e0,s0,method,param,ok,ratio,surface_ratio,"
                 "new_folds,new_folds_off_crease,drift,cpu_s,wall_s,note\n");
    int mesh_nv[MAXMESH];
    /* the worst case of the default against taubin_best, for the renders */
    double worst_vs = -INFINITY;
    int wm = -1, wk = 0, wj = 0, ws = 0;

    for (int mi = 0; mi < nm; mi++) {
        double tm0 = mcf_now();
        mcf_mesh *clean = bench_load_mesh(PROG, meshes, names[mi]);
        mcf_mesh_info ci;
        mcf_error e = {0};
        if (mcf_mesh_inspect(clean, &ci, &e) != MCF_OK)
            die("mcf_mesh_inspect", &e);
        int closed = ci.boundary_edges == 0, ncrease;
        mesh_nv[mi] = ci.nv;
        unsigned char *crease = crease_mask(clean, &ncrease);
        tri_grid gclean;
        grid_build(&gclean, clean);
        printf("\n%s: %d vertices, %d faces, %s%s, %d faces at creases\n", names[mi], ci.nv, ci.nf,
               closed ? "closed" : "open", ci.manifold ? "" : ", non-manifold", ncrease);
        fflush(stdout);
        for (int k = 0; k < g_nk; k++)
            for (int j = 0; j < g_nr; j++)
                for (int s = 0; s < g_ns; s++) {
                    mcf_mesh *noisy = make_noisy(clean, kinds[k], rho[j], s + 1);
                    mcf_mesh_info ni;
                    mcf_compare_result c0;
                    if (mcf_mesh_inspect(noisy, &ni, &e) != MCF_OK || mcf_compare(noisy, clean, &c0, &e) != MCF_OK)
                        die("noisy input", &e);
                    case_ctx c = {clean, noisy, &gclean, c0.rms_m, surface_error(noisy, clean, &gclean),
                                  c0.inverted_faces, inverted_off_crease(noisy, clean, crease), crease,
                                  closed ? ci.volume : ci.area, closed, ni.mean_edge / sqrt(ni.area)};
                    int o3d_done = 0;
                    for (int q = 0; q < nmeth; q++) {
                        result *r = R(mi, k, j, s, q);
                        if (meth[q].kind == K_DEFAULT || meth[q].kind == K_AUTO || meth[q].kind == K_FIXED)
                            run_request(&c, &meth[q], r, NULL);
                        else if (meth[q].kind == K_TAUBIN_BEST)
                            run_taubin_best(&c, r, NULL);
                        else if (!o3d_done) {
                            result two[2];
                            memset(two, 0, sizeof two);
                            run_o3d(&c, two, NULL);
                            if (q_od >= 0)
                                *R(mi, k, j, s, q_od) = two[0];
                            if (q_ob >= 0)
                                *R(mi, k, j, s, q_ob) = two[1];
                            o3d_done = 1;
                        }
                    }
                    for (int q = 0; q < nmeth; q++) {
                        const result *r = R(mi, k, j, s, q);
                        fprintf(csv, "%s,%d,%d,%d,%s,%g,%d,%.6g,%.6g,%s,%.6g,%d,%.6g,%.6g,%d,%d,%.6g,%.5f,%.5f,\"%s\"\n",
                                names[mi], ci.nv, ci.nf, closed, kind_names[kinds[k]], rho[j], s + 1, c.e0, c.s0,
                                meth[q].name, r->param, r->ok, r->ratio, r->sratio, r->folds, r->folds_off,
                                r->drift, r->cpu, r->wall, r->note);
                        if (!r->ok)
                            printf("  %s %s %g seed %d: %s\n", meth[q].name, kind_names[kinds[k]], rho[j], s + 1,
                                   r->note);
                    }
                    fflush(csv);
                    if (q_default >= 0 && q_tb >= 0) {
                        const result *d = R(mi, k, j, s, q_default), *t = R(mi, k, j, s, q_tb);
                        double vs = d->ok && t->ok ? d->ratio / t->ratio : INFINITY;
                        if (vs > worst_vs) {
                            worst_vs = vs;
                            wm = mi, wk = k, wj = j, ws = s;
                        }
                    }
                    mcf_mesh_free(noisy);
                }
        /* a line per noise kind and level: medians over seeds */
        printf("  %-6s %5s |", "noise", "rho");
        for (int q = 0; q < nmeth; q++)
            printf(" %*s", (int)(strlen(meth[q].name) > 7 ? strlen(meth[q].name) : 7), meth[q].name);
        printf("\n");
        for (int k = 0; k < g_nk; k++)
            for (int j = 0; j < g_nr; j++) {
                printf("  %-6s %5g |", kind_names[kinds[k]], rho[j]);
                for (int q = 0; q < nmeth; q++) {
                    double v[MAXSEED], mx;
                    for (int s = 0; s < g_ns; s++)
                        v[s] = R(mi, k, j, s, q)->ok ? R(mi, k, j, s, q)->ratio : INFINITY;
                    printf(" %*.3f", (int)(strlen(meth[q].name) > 7 ? strlen(meth[q].name) : 7),
                           median_max(v, g_ns, &mx));
                }
                printf("\n");
            }
        printf("  (%.1f s)\n", mcf_now() - tm0);
        fflush(stdout);
        grid_free(&gclean);
        free(crease);
        mcf_mesh_free(clean);
    }
    fclose(csv);

    /* ---- the tables (stdout and quality.md) */
    FILE *md = bench_open_out(out, "quality.md");
    fprintf(md, "# make quality (bench/bench_quality.c)\n\n"
                "%d meshes x noise %s x rho %s mean edges x %d seeds; error = area-weighted RMS distance to the\n"
                "clean vertex (vertex) and symmetric RMS point-to-surface distance (surface), each against the\n"
                "same case's taubin_best (Taubin at its best pass count, an oracle), o3d_best (Open3D's\n"
                "filter_smooth_taubin at its best count, the same oracle) and o3d_default (its default, one\n"
                "iteration): median and worst over the cases. `> input`: runs whose vertex error exceeds the\n"
                "noisy input's. CPU: median over the cases of the run's CPU time / `fixed` (desbrun2 strength\n"
                "0.33, 10 steps, the old default) in the same case.%s\n",
            nm, kinds_given, noise_given, g_ns, g_o3d.pid ? "" : " Open3D was not available: its columns are empty.");
    for (int k = -1; k < g_nk; k++) {
        char title[64];
        snprintf(title, sizeof title, "%s", k < 0 ? "all noise kinds" : k == 0 && kinds[0] == 0 ? "normal noise"
                                              : kinds[k] ? "isotropic noise" : "normal noise");
        fprintf(md, "\n## %s\n\n| method | vs taubin_best: vertex median / worst | surface median / worst | "
                    "vs o3d_best: vertex | surface | vs o3d_default: vertex | surface | vs input: vertex median / worst | > input | CPU / fixed |\n"
                    "|---|---|---|---|---|---|---|---|---|---|\n", title);
        printf("\n== %s: method error against ... (median / worst over the cases)\n", title);
        printf("%-22s | %-17s %-17s | %-17s %-17s | %-17s %-17s | %-17s %7s | %8s\n", "method",
               "taubin_best vert", "surface", "o3d_best vert", "surface", "o3d_default vert", "surface",
               "input vert", ">input", "cpu/fix");
        for (int q = 0; q < nmeth; q++) {
            double a[8][2], cm = NAN, cw;
            int peers[3] = {q_tb, q_ob, q_od};
            for (int p = 0; p < 3; p++)
                for (int sf = 0; sf < 2; sf++) {
                    if (peers[p] >= 0)
                        versus(nm, k, q, peers[p], sf, &a[2 * p + sf][0], &a[2 * p + sf][1]);
                    else
                        a[2 * p + sf][0] = a[2 * p + sf][1] = NAN;
                }
            versus(nm, k, q, -1, 0, &a[6][0], &a[6][1]);
            int worse = 0, runs = 0;
            double *cv = malloc(sizeof(double) * (size_t)(nm * g_nk * g_nr * g_ns) + 1);
            int ncv = 0;
            for (int m = 0; m < nm; m++)
                for (int kk = 0; kk < g_nk; kk++)
                    for (int j = 0; j < g_nr; j++)
                        for (int s = 0; s < g_ns; s++) {
                            if (k >= 0 && kk != k)
                                continue;
                            const result *r = R(m, kk, j, s, q);
                            runs++;
                            worse += !r->ok || r->ratio > 1.0;
                            if (q_fixed >= 0 && r->ok && R(m, kk, j, s, q_fixed)->ok)
                                cv[ncv++] = r->cpu / R(m, kk, j, s, q_fixed)->cpu;
                        }
            if (ncv)
                cm = median_max(cv, ncv, &cw);
            free(cv);
            char b[8][2][16];
            for (int x = 0; x < 7; x++)
                for (int y = 0; y < 2; y++)
                    snprintf(b[x][y], 16, isnan(a[x][y]) ? "-" : "%.3f", a[x][y]);
            printf("%-22s | %6s / %-8s %6s / %-8s | %6s / %-8s %6s / %-8s | %6s / %-8s %6s / %-8s | %6s / %-8s %3d/%-3d | %8.2f\n",
                   meth[q].name, b[0][0], b[0][1], b[1][0], b[1][1], b[2][0], b[2][1], b[3][0], b[3][1], b[4][0],
                   b[4][1], b[5][0], b[5][1], b[6][0], b[6][1], worse, runs, cm);
            fprintf(md, "| %s | %s / %s | %s / %s | %s / %s | %s / %s | %s / %s | %s / %s | %s / %s | %d of %d | %.2f |\n",
                    meth[q].name, b[0][0], b[0][1], b[1][0], b[1][1], b[2][0], b[2][1], b[3][0], b[3][1], b[4][0],
                    b[4][1], b[5][0], b[5][1], b[6][0], b[6][1], worse, runs, cm);
        }
    }
    /* CPU time against the fixed default, per mesh (the automatic amount's
     * budget: at most 1.5x on every shared mesh) */
    if (q_fixed >= 0) {
        fprintf(md, "\n## CPU time / fixed (desbrun2 strength 0.33), median over the mesh's cases\n\n| mesh | nv |");
        printf("\n== CPU time / fixed, median over each mesh's cases\n%-22s %7s", "mesh", "nv");
        for (int q = 0; q < nmeth; q++)
            if (meth[q].kind == K_AUTO || meth[q].kind == K_DEFAULT) {
                fprintf(md, " %s |", meth[q].name);
                printf(" %12s", meth[q].name);
            }
        fprintf(md, " fixed CPU s |\n|---|---|");
        for (int q = 0; q < nmeth; q++)
            if (meth[q].kind == K_AUTO || meth[q].kind == K_DEFAULT)
                fprintf(md, "---|");
        fprintf(md, "---|\n");
        printf(" %12s\n", "fixed s");
        for (int m = 0; m < nm; m++) {
            fprintf(md, "| %s | %d |", names[m], mesh_nv[m]);
            printf("%-22s %7d", names[m], mesh_nv[m]);
            for (int q = 0; q <= nmeth; q++) {
                if (q < nmeth && meth[q].kind != K_AUTO && meth[q].kind != K_DEFAULT)
                    continue;
                double v[MAXNOISE * MAXSEED * 2], mx;
                int n = 0;
                for (int k = 0; k < g_nk; k++)
                    for (int j = 0; j < g_nr; j++)
                        for (int s = 0; s < g_ns; s++) {
                            const result *f = R(m, k, j, s, q_fixed);
                            if (q == nmeth)
                                v[n++] = f->ok ? f->cpu : NAN;
                            else if (R(m, k, j, s, q)->ok && f->ok)
                                v[n++] = R(m, k, j, s, q)->cpu / f->cpu;
                        }
                double med = median_max(v, n, &mx);
                fprintf(md, q == nmeth ? " %.3f |" : " %.2f |", med);
                printf(q == nmeth ? " %12.3f" : " %12.2f", med);
            }
            fprintf(md, "\n");
            printf("\n");
        }
    }
    /* the default per mesh x noise: medians over the seeds */
    if (q_default >= 0) {
        fprintf(md, "\n## The default request per mesh and noise (median over seeds; vertex error / input's, "
                    "surface in brackets)\n\n| mesh | noise | rho | default | taubin_best | o3d_default | o3d_best | "
                    "default param | new folds (max) | drift (median) |\n|---|---|---|---|---|---|---|---|---|---|\n");
        for (int m = 0; m < nm; m++)
            for (int k = 0; k < g_nk; k++)
                for (int j = 0; j < g_nr; j++) {
                    int qs[4] = {q_default, q_tb, q_od, q_ob}, fmx = 0;
                    fprintf(md, "| %s | %s | %g |", names[m], kind_names[kinds[k]], rho[j]);
                    for (int x = 0; x < 4; x++) {
                        double v[MAXSEED], w[MAXSEED], mx;
                        for (int s = 0; s < g_ns; s++) {
                            const result *r = qs[x] >= 0 ? R(m, k, j, s, qs[x]) : NULL;
                            v[s] = r && r->ok ? r->ratio : NAN;
                            w[s] = r && r->ok ? r->sratio : NAN;
                        }
                        double a = median_max(v, g_ns, &mx), b = median_max(w, g_ns, &mx);
                        fprintf(md, isnan(a) ? " - |" : " %.3f (%.3f) |", a, b);
                    }
                    double p[MAXSEED], d[MAXSEED], mx;
                    for (int s = 0; s < g_ns; s++) {
                        const result *r = R(m, k, j, s, q_default);
                        p[s] = r->ok ? r->param : NAN;
                        d[s] = r->ok ? 100 * r->drift : NAN;
                        fmx = r->folds > fmx ? r->folds : fmx;
                    }
                    fprintf(md, " %.3g | %d | %+.2f%% |\n", median_max(p, g_ns, &mx), fmx, median_max(d, g_ns, &mx));
                }
    }
    fprintf(md, "\nRenders of the case where the default does worst against taubin_best: worst.png, worst-zoom.png.\n");
    fclose(md);

    /* ---- renders of the worst case */
    if (do_figure && wm >= 0) {
        mcf_mesh *clean = bench_load_mesh(PROG, meshes, names[wm]);
        mcf_mesh_info ci;
        mcf_error e = {0};
        mcf_mesh_inspect(clean, &ci, &e);
        int ncrease;
        unsigned char *crease = crease_mask(clean, &ncrease);
        tri_grid gclean;
        grid_build(&gclean, clean);
        mcf_mesh *noisy = make_noisy(clean, kinds[wk], rho[wj], ws + 1);
        mcf_mesh_info ni;
        mcf_compare_result c0;
        mcf_mesh_inspect(noisy, &ni, &e);
        mcf_compare(noisy, clean, &c0, &e);
        case_ctx c = {clean, noisy, &gclean, c0.rms_m, surface_error(noisy, clean, &gclean), c0.inverted_faces,
                      inverted_off_crease(noisy, clean, crease), crease,
                      ci.boundary_edges == 0 ? ci.volume : ci.area, ci.boundary_edges == 0,
                      ni.mean_edge / sqrt(ni.area)};
        const mcf_mesh *ms[6] = {clean, noisy};
        const char *titles[6] = {"clean", "noisy"};
        char tb[4][96];
        mcf_mesh *res[4] = {0};
        result r[4];
        memset(r, 0, sizeof r);
        int n = 2;
        run_request(&c, &meth[q_default], &r[0], &res[0]);
        run_taubin_best(&c, &r[1], &res[1]);
        mcf_mesh *o3[2] = {0};
        if (g_o3d.pid) {
            result two[2];
            memset(two, 0, sizeof two);
            run_o3d(&c, two, o3);
            r[2] = two[1];
            res[2] = o3[1];
            mcf_mesh_free(o3[0]);
        }
        static const char *const lab[3] = {"default", "taubin best", "open3d best"};
        for (int x = 0; x < 3; x++)
            if (res[x]) {
                snprintf(tb[x], sizeof tb[x], "%s (%.3g): %.2f, surface %.2f", lab[x], r[x].param, r[x].ratio, r[x].sratio);
                titles[n] = tb[x];
                ms[n++] = res[x];
            }
        char label[96];
        snprintf(label, sizeof label, "%s, %s noise", names[wm], kind_names[kinds[wk]]);
        figure_spec fs = {label, rho[wj], ws + 1, 0, {0.0, 1.0, 0.0, 1.0}};
        figure(out, "worst", &fs, ms, titles, n);
        figure_spec zoom = fs;
        double zc[4] = {0.3, 0.7, 0.4, 0.8};
        memcpy(zoom.crop, zc, sizeof zc);
        figure(out, "worst-zoom", &zoom, ms, titles, n);
        for (int x = 0; x < 3; x++)
            mcf_mesh_free(res[x]);
        grid_free(&gclean);
        free(crease);
        mcf_mesh_free(noisy);
        mcf_mesh_free(clean);
    }
    o3d_stop();
    char p1[300], p2[300], p3[300];
    snprintf(p1, sizeof p1, "%s/noisy.bin", g_tmp);
    snprintf(p2, sizeof p2, "%s/clean.bin", g_tmp);
    snprintf(p3, sizeof p3, "%s/out.bin", g_tmp);
    remove(p1);
    remove(p2);
    remove(p3);
    rmdir(g_tmp);
    printf("\nCSV: %s/quality.csv, tables: %s/quality.md; run time %.0f s\n", out, out, mcf_now() - t_start);
    free(g_res);
    return 0;
}
