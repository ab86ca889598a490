/* SPDX-License-Identifier: MIT */
/*
 * test_core_trace.c - the fairing's probe traces by Lanczos quadrature
 * (core/mcf_fairing_trace.c) against the same quantities computed here
 * without it, on real meshes of the repository: per Rademacher probe z,
 * z' W f_K(N) z with N = D_F^-1/2 L_FF D_F^-1/2 on the free vertices,
 * f_K = P^K for K lambda|mu passes (P(l) = (1 - mu l)(1 - lambda l), applied
 * here as 2K products with N) and (1 + l^2)^-K for K implicit steps (each a
 * solve of (I + N^2) y = x by conjugate gradients to a relative residual of
 * 1e-15). The default request's explicit run continues its implicit run's
 * Lanczos runs (mcf_fairing.c, run_init): the same state is read for both,
 * the implicit K first, as the request does.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"
#include "mcf_fairing_ctx.h"

/* |Lanczos - reference| / n, n the free vertices (SURE's terms are s^2 n):
 * the quadrature settles to 1e-12 n between successive Lanczos lengths
 * (LZ_TOL); the reference's rounding is about 1e-16 n per product or
 * solve, up to 4,000 of them here (2 x MAXK passes), and CG's 1e-15
 * relative residual through a system of condition at most 5. Measured:
 * see the messages (1e-14 n and below). */
#define TRACE_TOL 1e-10
enum { MAXK = 512, KIMP = 32 };

/* (N x)_k = x_k - (1 / sq_k) sum over free neighbours j of x_j / sq_j */
static void apply_n(const fair_ctx *c, const double *x, double *y)
{
    for (int k = 0; k < c->nfree; k++) {
        int i = c->vert[k];
        double s = 0.0;
        for (int e = c->g.ptr[i]; e < c->g.ptr[i + 1]; e++) {
            int j = c->fid[c->g.adj[e]];
            if (j >= 0)
                s += x[j] / c->sq[j];
        }
        y[k] = x[k] - s / c->sq[k];
    }
}

/* y = (I + N^2)^-1 x by conjugate gradients (the system is SPD with
 * eigenvalues in [1, 5]) */
static void solve_imp(const fair_ctx *c, const double *x, double *y, double *r, double *p, double *q, double *t)
{
    int n = c->nfree;
    double rr = 0.0, xx = 0.0;
    memset(y, 0, sizeof(double) * (size_t)n);
    memcpy(r, x, sizeof(double) * (size_t)n);
    memcpy(p, x, sizeof(double) * (size_t)n);
    for (int k = 0; k < n; k++)
        rr += r[k] * r[k];
    xx = rr;
    for (int it = 0; it < 200 && rr > 1e-30 * xx; it++) {
        apply_n(c, p, t);
        apply_n(c, t, q);
        double pq = 0.0, rn = 0.0;
        for (int k = 0; k < n; k++) {
            q[k] += p[k];
            pq += p[k] * q[k];
        }
        double a = rr / pq;
        for (int k = 0; k < n; k++) {
            y[k] += a * p[k];
            r[k] -= a * q[k];
            rn += r[k] * r[k];
        }
        for (int k = 0; k < n; k++)
            p[k] = r[k] + rn / rr * p[k];
        rr = rn;
    }
    assert_true(rr <= 1e-30 * xx);
}

/* The free set: every vertex with an edge but the boundary's and every
 * hold-th one (as the fairing holds its creases), the degrees, the
 * barycentric weights over their mean and six Rademacher probes. */
static void make_ctx(const mcf_mesh *m, int hold, fair_ctx *c)
{
    mcf_error err = {0};
    int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m);
    const int32_t *F = mcf_mesh_faces(m);
    const double *X = mcf_mesh_positions(m);
    memset(c, 0, sizeof *c);
    c->nv = nv;
    assert_int_equal(mcf__graph_build(F, nf, nv, &c->g, &err), MCF_OK);
    unsigned char *bnd = calloc((size_t)nv, 1);
    int *cnt = calloc((size_t)c->g.ptr[nv] + 1, sizeof(int));
    assert_non_null(bnd);
    assert_non_null(cnt);
    for (int f = 0; f < nf; f++) /* an edge of one face: the boundary */
        for (int e = 0; e < 3; e++) {
            int a = F[3 * f + e], b = F[3 * f + (e + 1) % 3];
            for (int t = c->g.ptr[a]; t < c->g.ptr[a + 1]; t++)
                if (c->g.adj[t] == b)
                    cnt[t]++;
            for (int t = c->g.ptr[b]; t < c->g.ptr[b + 1]; t++)
                if (c->g.adj[t] == a)
                    cnt[t]++;
        }
    for (int i = 0; i < nv; i++)
        for (int t = c->g.ptr[i]; t < c->g.ptr[i + 1]; t++)
            if (cnt[t] == 1)
                bnd[i] = 1;
    c->fid = malloc(sizeof(int) * (size_t)nv);
    c->vert = malloc(sizeof(int) * (size_t)nv);
    c->sq = malloc(sizeof(double) * (size_t)nv);
    c->w = calloc((size_t)nv, sizeof(double));
    assert_true(c->fid && c->vert && c->sq && c->w);
    for (int i = 0; i < nv; i++) {
        int d = c->g.ptr[i + 1] - c->g.ptr[i];
        c->fid[i] = -1;
        if (d > 0 && !bnd[i] && i % hold != 0) {
            c->fid[i] = c->nfree;
            c->sq[c->nfree] = sqrt((double)d);
            c->vert[c->nfree++] = i;
        }
    }
    for (int f = 0; f < nf; f++) {
        const double *a = X + 3 * (size_t)F[3 * f], *b = X + 3 * (size_t)F[3 * f + 1], *d = X + 3 * (size_t)F[3 * f + 2];
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
        double cx = u[1] * v[2] - u[2] * v[1], cy = u[2] * v[0] - u[0] * v[2], cz = u[0] * v[1] - u[1] * v[0];
        for (int e = 0; e < 3; e++)
            c->w[F[3 * f + e]] += sqrt(cx * cx + cy * cy + cz * cz) / 6.0;
    }
    double sum = 0.0;
    for (int i = 0; i < nv; i++)
        sum += c->fid[i] >= 0 ? c->w[i] : 0.0;
    for (int i = 0; i < nv; i++)
        c->w[i] = c->fid[i] >= 0 ? c->w[i] * c->nfree / sum : 0.0;
    c->nprobe = NPROBE;
    c->probe = malloc(sizeof(double) * NPROBE * (size_t)c->nfree);
    assert_non_null(c->probe);
    for (int q = 0; q < NPROBE; q++)
        for (int k = 0; k < c->nfree; k++)
            c->probe[(size_t)q * c->nfree + k] = (mcf__mix64((uint64_t)q * 977 + (uint64_t)k + 1) >> 63) ? 1.0 : -1.0;
    free(bnd);
    free(cnt);
}

static void free_ctx(fair_ctx *c)
{
    mcf__fair_lz_free(c->lz);
    mcf__graph_free(&c->g);
    free(c->fid);
    free(c->vert);
    free(c->sq);
    free(c->w);
    free(c->probe);
}

/* ref[q][K] = z_q' W f_K(N) z_q for K = 0..kmax: the implicit steps' or the
 * passes' (is_explicit) */
static void reference(const fair_ctx *c, int is_explicit, int kmax, double *ref)
{
    int n = c->nfree;
    double *y = malloc(sizeof(double) * 6 * (size_t)n);
    assert_non_null(y);
    double *t = y + n, *r = t + n, *p = r + n, *q = p + n, *u = q + n;
    for (int pr = 0; pr < NPROBE; pr++) {
        const double *z = c->probe + (size_t)pr * n;
        memcpy(y, z, sizeof(double) * (size_t)n);
        for (int K = 0; K <= kmax; K++) {
            if (K > 0 && is_explicit) {
                apply_n(c, y, t);
                for (int k = 0; k < n; k++)
                    y[k] -= MCF_TAUBIN_LAMBDA * t[k];
                apply_n(c, y, t);
                for (int k = 0; k < n; k++)
                    y[k] -= MCF_TAUBIN_MU * t[k];
            } else if (K > 0) {
                solve_imp(c, y, u, r, p, q, t);
                memcpy(y, u, sizeof(double) * (size_t)n);
            }
            double s = 0.0;
            for (int k = 0; k < n; k++)
                s += c->w[c->vert[k]] * z[k] * y[k];
            ref[(size_t)pr * (kmax + 1) + K] = s;
        }
    }
    free(y);
}

/* The run's estimates for K = 1..kmax, asked in order as run_steps does,
 * against ref: the largest difference over n */
static double worst(fair_ctx *c, int kmax, const double *ref)
{
    mcf_error err = {0};
    double wmax = 0.0;
    c->cap = kmax;
    for (int K = 1; K <= kmax; K++) {
        double est[NPROBE];
        assert_int_equal(mcf__fair_lz_trace(c, K, est, &err), MCF_OK);
        for (int q = 0; q < NPROBE; q++)
            wmax = fmax(wmax, fabs(est[q] - ref[(size_t)q * (kmax + 1) + K]) / c->nfree);
    }
    return wmax;
}

static void check_mesh(const char *name, int hold)
{
    mcf_mesh *m = tl_load(name);
    mcf_error err = {0};
    fair_ctx c, d;
    make_ctx(m, hold, &c);
    double *ri = malloc(sizeof(double) * NPROBE * (KIMP + 1)), *re = malloc(sizeof(double) * NPROBE * (MAXK + 1));
    assert_non_null(ri);
    assert_non_null(re);
    reference(&c, 0, KIMP, ri);
    reference(&c, 1, MAXK, re);

    /* the passes alone (fairing_explicit, or above 150,000 vertices) */
    c.is_explicit = 1;
    assert_int_equal(mcf__fair_lz_new(&c, &err), MCF_OK);
    double we = worst(&c, MAXK, re);
    mcf__fair_lz_free(c.lz);
    c.lz = NULL;

    /* the default request: the implicit steps, then the passes on the same
     * Lanczos runs */
    c.is_explicit = 0;
    assert_int_equal(mcf__fair_lz_new(&c, &err), MCF_OK);
    double wi = worst(&c, KIMP, ri);
    d = c; /* the explicit run's context: the same arrays */
    d.lz = NULL;
    d.is_explicit = 1;
    assert_true(mcf__fair_lz_fits(&d, &c));
    d.lz = c.lz;
    c.lz = NULL;
    double ws = worst(&d, MAXK, re);
    c.lz = d.lz;
    print_message("%s: %d free of %d; |Lanczos - reference| / n: passes alone %.1e (K <= %d), implicit %.1e "
                  "(K <= %d), passes after it %.1e\n",
                  name, c.nfree, c.nv, we, MAXK, wi, KIMP, ws);
    assert_true(we <= TRACE_TOL);
    assert_true(wi <= TRACE_TOL);
    assert_true(ws <= TRACE_TOL);

    /* other probes, or another free set: not the same Lanczos runs */
    d.lz = NULL;
    d.probe = malloc(sizeof(double) * NPROBE * (size_t)c.nfree);
    assert_non_null(d.probe);
    memcpy(d.probe, c.probe, sizeof(double) * NPROBE * (size_t)c.nfree);
    d.probe[3] = -d.probe[3];
    assert_false(mcf__fair_lz_fits(&d, &c));
    d.probe[3] = -d.probe[3];
    assert_true(mcf__fair_lz_fits(&d, &c));
    d.nfree--;
    assert_false(mcf__fair_lz_fits(&d, &c));
    free(d.probe);
    free(ri);
    free(re);
    free_ctx(&c);
    mcf_mesh_free(m);
}

/* A closed organic mesh, every 7th vertex held (as creases are); an open
 * CAD mesh of many pieces, its boundary held. */
static void test_traces_bunny(void **state)
{
    (void)state;
    check_mesh("bunny_npm_closed.obj", 7);
}

static void test_traces_car(void **state)
{
    (void)state;
    check_mesh("car.drc", 1 << 30);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_traces_bunny),
        cmocka_unit_test(test_traces_car),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
