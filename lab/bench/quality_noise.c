/* SPDX-License-Identifier: MIT */
/*
 * quality_noise.c - the noise models of make quality (issue 31).
 *
 * Common to all: h = the clean mesh's mean edge (mcf_mesh_inspect's
 * mean_edge, over the unique edges), sigma = rho h. Only the vertices a
 * default run moves get noise (qn_moved: those mcf_flow_add_noise moves
 * with the default parameters, i.e. not the fixed boundary, not
 * unreferenced vertices); the others keep their positions to the bit.
 * n_i is the clean mesh's area-weighted vertex normal (the sum of the
 * unnormalized face normals around i, normalized). Every draw comes from
 * a seed; the new models (view, corr, out's spikes, quant) draw from
 * splitmix64 streams of (model, seed) only, so the three levels of one
 * seed are the same noise at three amplitudes.
 *
 *   normal  x_i + sigma g_i n_i, g_i ~ N(0,1): mcf_flow_add_noise(rho,
 *           seed) with the default parameters, bit-identical to issue 16's
 *           `normal` (note: core scales by the mean edge over the face
 *           corners, which differs from h by well under 1%).
 *   iso     x_i + sigma (g_ix, g_iy, g_iz): isotropic, sigma per
 *           coordinate, bit-identical to issue 16's `iso` (its stream is
 *           seeded with seed and rho). Its total variance is 3 sigma^2,
 *           three times `normal`'s; its component along the normal has
 *           `normal`'s sigma.
 *   view    x_i + sigma g_i u: one unit vector u per seed (a normalized
 *           standard 3D Gaussian), as depth noise from one viewpoint; the
 *           component along n_i has standard deviation sigma |u . n_i|.
 *   corr    x_i + sigma z_i n_i, z = per-vertex N(0,1) draws (every
 *           vertex, index order) smoothed by 9 Jacobi passes of the
 *           average over the closed one-ring (z_i <- (z_i + sum over the
 *           edge neighbours z_j) / (1 + degree)), then rescaled so that
 *           its RMS over the moved vertices is exactly 1: a correlation
 *           length of about 3 edges.
 *   out     `normal` at rho and seed, plus K = max(1, round(1% of the moved
 *           vertices)) distinct moved vertices (a partial Fisher-Yates
 *           draw) moved further by s a h n_i, a uniform in [3, 5], s = +-1
 *           with probability 1/2: spikes of 3-5 h whatever rho.
 *   quant   each coordinate of a moved vertex rounded to the grid
 *           o_d + k rho h (k integer; floor(v + 1/2)), the offset o_d
 *           uniform in [0, rho h) per coordinate from the seed: a scanner's
 *           depth resolution. rho must be > 0.
 *   clean   the clean mesh (rho 0): how far a filter moves what has no noise.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "quality_noise.h"

static const char *const names[QN_COUNT] = {"normal", "iso", "view", "corr", "out", "quant", "clean"};

const char *qn_name(qn_model k)
{
    return k >= 0 && k < QN_COUNT ? names[k] : "?";
}

int qn_parse(const char *s)
{
    for (int k = 0; k < QN_COUNT; k++)
        if (!strcmp(s, names[k]))
            return k;
    return -1;
}

static void fail(mcf_error *err, mcf_status code, const char *msg)
{
    if (err) {
        err->status = code;
        snprintf(err->msg, sizeof err->msg, "%s", msg);
    }
}

/* ------------------------------------------------------------ draws */

/* splitmix64, uniform in (0, 1) and Box-Muller: issue 16's generator,
 * kept as it was written so that `iso` stays bit-identical. */
typedef struct {
    uint64_t s;
} lrng;

static double uniform01(lrng *r)
{
    uint64_t z = (r->s += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    z ^= z >> 31;
    return ((z >> 11) + 0.5) * (1.0 / 9007199254740992.0);
}

static double gauss(lrng *r)
{
    return sqrt(-2.0 * log(uniform01(r))) * cos(6.283185307179586 * uniform01(r));
}

/* The stream of a new model: its own per (model, seed). */
static lrng stream(qn_model k, int seed)
{
    lrng r = {0x51ed2701ULL * (uint64_t)(k + 1) + 0x100000001b3ULL * (uint64_t)seed};
    (void)uniform01(&r); /* one warm-up draw: decorrelates nearby seeds */
    return r;
}

/* ------------------------------------------------------------ helpers */

static void vertex_normals(const mcf_mesh *m, double *N)
{
    const double *X = mcf_mesh_positions(m);
    const int32_t *F = mcf_mesh_faces(m);
    int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m);
    memset(N, 0, 3 * sizeof(double) * (size_t)nv);
    for (int f = 0; f < nf; f++) {
        const int32_t *t = F + 3 * f;
        const double *a = X + 3 * (size_t)t[0], *b = X + 3 * (size_t)t[1], *c = X + 3 * (size_t)t[2];
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
        for (int k = 0; k < 3; k++)
            for (int d = 0; d < 3; d++)
                N[3 * (size_t)t[k] + d] += n[d];
    }
    for (int i = 0; i < nv; i++) {
        double *n = N + 3 * (size_t)i, l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        for (int d = 0; d < 3; d++)
            n[d] = l > 0 ? n[d] / l : 0.0;
    }
}

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return (x > y) - (x < y);
}

/* The edge neighbours of every vertex (CSR, each once): *start (nv + 1)
 * and *nb, malloc'ed. -1 when out of memory. */
static int neighbours(const mcf_mesh *m, int **start, int **nb)
{
    int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m);
    const int32_t *F = mcf_mesh_faces(m);
    uint64_t *e = malloc(6 * sizeof(uint64_t) * (size_t)(nf > 0 ? nf : 1));
    *start = calloc((size_t)nv + 1, sizeof(int));
    *nb = malloc(6 * sizeof(int) * (size_t)(nf > 0 ? nf : 1));
    if (!e || !*start || !*nb) {
        free(e);
        free(*start);
        free(*nb);
        return -1;
    }
    size_t n = 0;
    for (int f = 0; f < nf; f++)
        for (int k = 0; k < 3; k++) {
            uint64_t a = (uint32_t)F[3 * f + k], b = (uint32_t)F[3 * f + (k + 1) % 3];
            e[n++] = a << 32 | b;
            e[n++] = b << 32 | a;
        }
    qsort(e, n, sizeof *e, cmp_u64);
    size_t u = 0;
    for (size_t i = 0; i < n; i++)
        if ((i == 0 || e[i] != e[i - 1]) && (e[i] >> 32) != (e[i] & 0xffffffffu))
            e[u++] = e[i];
    for (size_t i = 0; i < u; i++) {
        (*start)[(e[i] >> 32) + 1]++;
        (*nb)[i] = (int)(e[i] & 0xffffffffu);
    }
    for (int i = 0; i < nv; i++)
        (*start)[i + 1] += (*start)[i];
    free(e);
    return 0;
}

int qn_moved(const mcf_mesh *clean, unsigned char *moved, mcf_error *err)
{
    mcf_flow_params p;
    mcf_flow_params_init(&p);
    mcf_mesh *m = mcf_mesh_dup(clean, err);
    if (!m)
        return -1;
    if (mcf_flow_add_noise(m, &p, 1.0, 1, err) != MCF_OK) {
        mcf_mesh_free(m);
        return -1;
    }
    const double *A = mcf_mesh_positions(m), *C = mcf_mesh_positions(clean);
    int n = 0;
    for (int i = 0; i < mcf_mesh_nvertices(m); i++)
        n += moved[i] = memcmp(A + 3 * (size_t)i, C + 3 * (size_t)i, 3 * sizeof(double)) != 0;
    mcf_mesh_free(m);
    return n;
}

/* ------------------------------------------------------------ models */

/* issue 16's `iso`, as it was: the vertices `normal` noise moves get
 * sigma per coordinate from a stream seeded by seed and rho. */
static mcf_mesh *make_iso(const mcf_mesh *clean, double h, double rho, int seed, mcf_error *err)
{
    mcf_flow_params p;
    mcf_flow_params_init(&p);
    mcf_mesh *m = mcf_mesh_dup(clean, err);
    if (!m)
        return NULL;
    if (mcf_flow_add_noise(m, &p, rho, (uint64_t)seed, err) != MCF_OK) {
        mcf_mesh_free(m);
        return NULL;
    }
    int nv = mcf_mesh_nvertices(m);
    double *X = malloc(3 * sizeof(double) * (size_t)(nv > 0 ? nv : 1));
    if (!X) {
        mcf_mesh_free(m);
        fail(err, MCF_ENOMEM, "iso noise: out of memory");
        return NULL;
    }
    const double *N = mcf_mesh_positions(m), *C = mcf_mesh_positions(clean);
    lrng r = {0x15015015ULL * (uint64_t)seed + (uint64_t)(rho * 1e6)};
    for (int i = 0; i < nv; i++) {
        int mv = memcmp(N + 3 * i, C + 3 * i, 3 * sizeof(double)) != 0;
        for (int d = 0; d < 3; d++)
            X[3 * i + d] = C[3 * i + d] + (mv ? rho * h * gauss(&r) : 0.0);
    }
    mcf_mesh *out = mcf_mesh_new(nv, X, mcf_mesh_nfaces(clean), mcf_mesh_faces(clean), err);
    free(X);
    mcf_mesh_free(m);
    return out;
}

mcf_mesh *qn_make(const mcf_mesh *clean, qn_model k, double rho, int seed, int *outliers, mcf_error *err)
{
    mcf_mesh_info ci;
    mcf_flow_params p;
    if (outliers)
        *outliers = 0;
    if (!clean || k < 0 || k >= QN_COUNT || !(rho >= 0) || !isfinite(rho) || (k == QN_QUANT && rho == 0)) {
        fail(err, MCF_EINVAL, "noise: bad model or level (rho must be finite, >= 0, and > 0 for quant)");
        return NULL;
    }
    if (mcf_mesh_inspect(clean, &ci, err) != MCF_OK)
        return NULL;
    double h = ci.mean_edge, sigma = rho * h;
    if (k == QN_ISO)
        return make_iso(clean, h, rho, seed, err);
    mcf_flow_params_init(&p);
    mcf_mesh *m = mcf_mesh_dup(clean, err);
    if (!m || k == QN_CLEAN)
        return m;
    if (k == QN_NORMAL || k == QN_OUT) {
        if (mcf_flow_add_noise(m, &p, rho, (uint64_t)seed, err) != MCF_OK) {
            mcf_mesh_free(m);
            return NULL;
        }
        if (k == QN_NORMAL)
            return m;
    }
    int nv = mcf_mesh_nvertices(m), *start = NULL, *nb = NULL, *idx = NULL;
    unsigned char *moved = malloc((size_t)nv + 1);
    double *N = malloc(3 * sizeof(double) * (size_t)nv + 1), *z = NULL, *z2 = NULL;
    double *X = mcf_mesh_positions_mut(m);
    if (!moved || !N) {
        fail(err, MCF_ENOMEM, "noise: out of memory");
        goto fail;
    }
    int nmoved = qn_moved(clean, moved, err);
    if (nmoved < 0)
        goto fail;
    vertex_normals(clean, N);
    lrng r = stream(k, seed);
    if (k == QN_VIEW) {
        double u[3], l;
        do {
            u[0] = gauss(&r), u[1] = gauss(&r), u[2] = gauss(&r);
            l = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
        } while (!(l > 1e-3));
        for (int i = 0; i < nv; i++) {
            double g = gauss(&r);
            if (moved[i])
                for (int d = 0; d < 3; d++)
                    X[3 * i + d] += sigma * g * u[d] / l;
        }
    } else if (k == QN_CORR) {
        z = malloc(sizeof(double) * (size_t)nv + 1);
        z2 = malloc(sizeof(double) * (size_t)nv + 1);
        if (!z || !z2 || neighbours(clean, &start, &nb) != 0) {
            fail(err, MCF_ENOMEM, "corr noise: out of memory");
            goto fail;
        }
        for (int i = 0; i < nv; i++)
            z[i] = gauss(&r);
        for (int pass = 0; pass < 9; pass++) {
            for (int i = 0; i < nv; i++) {
                double s = z[i];
                for (int q = start[i]; q < start[i + 1]; q++)
                    s += z[nb[q]];
                z2[i] = s / (1 + start[i + 1] - start[i]);
            }
            double *t = z;
            z = z2;
            z2 = t;
        }
        double ss = 0;
        for (int i = 0; i < nv; i++)
            ss += moved[i] ? z[i] * z[i] : 0.0;
        double scale = nmoved > 0 && ss > 0 ? 1.0 / sqrt(ss / nmoved) : 0.0;
        for (int i = 0; i < nv; i++)
            if (moved[i])
                for (int d = 0; d < 3; d++)
                    X[3 * i + d] += sigma * scale * z[i] * N[3 * i + d];
    } else if (k == QN_OUT) {
        idx = malloc(sizeof(int) * (size_t)nv + 1);
        if (!idx) {
            fail(err, MCF_ENOMEM, "out noise: out of memory");
            goto fail;
        }
        int n = 0;
        for (int i = 0; i < nv; i++)
            if (moved[i])
                idx[n++] = i;
        int K = n > 0 ? (int)floor(0.01 * n + 0.5) : 0;
        if (n > 0 && K < 1)
            K = 1;
        for (int t = 0; t < K; t++) {
            int j = t + (int)(uniform01(&r) * (n - t));
            if (j >= n)
                j = n - 1;
            int v = idx[j];
            idx[j] = idx[t];
            idx[t] = v;
            double a = 3.0 + 2.0 * uniform01(&r), s = uniform01(&r) < 0.5 ? -1.0 : 1.0;
            for (int d = 0; d < 3; d++)
                X[3 * v + d] += s * a * h * N[3 * v + d];
        }
        if (outliers)
            *outliers = K;
    } else if (k == QN_QUANT) {
        double o[3] = {sigma * uniform01(&r), sigma * uniform01(&r), sigma * uniform01(&r)};
        for (int i = 0; i < nv; i++)
            if (moved[i])
                for (int d = 0; d < 3; d++)
                    X[3 * i + d] = o[d] + sigma * floor((X[3 * i + d] - o[d]) / sigma + 0.5);
    }
    free(moved);
    free(N);
    free(z);
    free(z2);
    free(start);
    free(nb);
    free(idx);
    return m;
fail:
    free(moved);
    free(N);
    free(z);
    free(z2);
    free(start);
    free(nb);
    free(idx);
    mcf_mesh_free(m);
    return NULL;
}
