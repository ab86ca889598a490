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
 * the implicit K first, as the request does. That explicit run also takes
 * the implicit run's set-up (creases, free set, weights, normals, its
 * input clamped along the creases: mcf_fairing.c, setup_copy): its run
 * is checked here to the bit against the same run finding its own.
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
/* The vertices of m on an edge of one face (graph g), calloc'd. */
static unsigned char *boundary(const mcf_mesh *m, const mcf__graph *g)
{
    int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m);
    const int32_t *F = mcf_mesh_faces(m);
    unsigned char *bnd = calloc((size_t)nv, 1);
    int *cnt = calloc((size_t)g->ptr[nv] + 1, sizeof(int));
    assert_non_null(bnd);
    assert_non_null(cnt);
    for (int f = 0; f < nf; f++)
        for (int e = 0; e < 3; e++) {
            int a = F[3 * f + e], b = F[3 * f + (e + 1) % 3];
            for (int t = g->ptr[a]; t < g->ptr[a + 1]; t++)
                if (g->adj[t] == b)
                    cnt[t]++;
            for (int t = g->ptr[b]; t < g->ptr[b + 1]; t++)
                if (g->adj[t] == a)
                    cnt[t]++;
        }
    for (int i = 0; i < nv; i++)
        for (int t = g->ptr[i]; t < g->ptr[i + 1]; t++)
            if (cnt[t] == 1)
                bnd[i] = 1;
    free(cnt);
    return bnd;
}

static void make_ctx(const mcf_mesh *m, int hold, fair_ctx *c)
{
    mcf_error err = {0};
    int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m);
    const int32_t *F = mcf_mesh_faces(m);
    const double *X = mcf_mesh_positions(m);
    memset(c, 0, sizeof *c);
    c->nv = nv;
    assert_int_equal(mcf__graph_build(F, nf, nv, &c->g, &err), MCF_OK);
    unsigned char *bnd = boundary(m, &c->g);
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

/* The default request's explicit run after its implicit run on car.drc
 * with noise 0.25 mean edges along the normals (seed 1: creases found,
 * and their smoothing along them clamped at one noise level), made twice
 * from the same implicit run: taking its set-up (setup_from) and finding
 * its own; both carry their probes as columns (no lz_from), so the runs
 * must agree to the bit: the same free set, weights, normals, input,
 * steps, SURE and result. */
static void test_pick_setup_shared(void **state)
{
    (void)state;
    mcf_mesh *m = tl_load("car.drc");
    mcf_error err = {0};
    mcf_flow_params p;
    mcf_flow_params_init(&p);
    p.scheme = MCF_FAIRING;
    p.fairing_pick = 1;
    p.fairing_robust = 1;
    assert_int_equal(mcf_flow_add_noise(m, &p, 0.25, 1, &err), MCF_OK);
    int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m);
    const int32_t *F = mcf_mesh_faces(m);
    const double *X = mcf_mesh_positions(m);
    double hbar = mcf__mean_edge(X, F, nf), cpu = 0.0;
    mcf__graph g;
    assert_int_equal(mcf__graph_build(F, nf, nv, &g, &err), MCF_OK);
    unsigned char *fixed = boundary(m, &g); /* held, as the request holds it */
    fair_ctx ci, ce[2];
    mcf_flow_stats si, se[2];
    memset(&ci, 0, sizeof ci);
    memset(ce, 0, sizeof ce);
    memset(&si, 0, sizeof si);
    memset(se, 0, sizeof se);
    ci.threads_cpu_s = &cpu;
    if (mcf__fair_filter_run(&ci, &g, X, F, nf, nv, fixed, &p, hbar, &si, NULL, NULL, &err) != MCF_OK)
        fail_msg("the implicit run: %s", err.msg);
    assert_true(ci.cap > 0 && ci.kbest > 0);
    int moved = 0; /* crease vertices the smoothing along them moved */
    for (int i = 0; i < 3 * nv; i++)
        moved += ci.crease[i / 3] && ci.X0[i] != X[i];
    ci.share.probe = ci.probe;
    ci.share.fid = ci.fid;
    ci.share.nfree = ci.nfree;
    ci.share.nprobe = ci.nprobe;
    for (int r = 0; r < 2; r++) {
        ce[r].is_explicit = ce[r].quiet = 1;
        ce[r].threads_cpu_s = &cpu;
        ce[r].like = &ci.share;
        ce[r].setup_from = r == 0 ? &ci : NULL;
        assert_int_equal(mcf__fair_filter_run(&ce[r], &g, X, F, nf, nv, fixed, &p, hbar, &se[r], NULL, NULL, &err),
                         MCF_OK);
    }
    const fair_ctx *a = &ce[0], *b = &ce[1];
    size_t n3 = 3 * sizeof(double) * (size_t)nv;
    print_message("car.drc noise 0.25: %d crease vertices (%d coordinates moved along them), %d free; passes: "
                  "K %d, taken set-up and own: SURE %.17g, %.17g\n",
                  si.crease_vertices, moved, a->nfree, a->kbest, a->risk, b->risk);
    assert_true(si.crease_vertices > 0 && moved > 0);
    assert_int_equal(se[0].crease_vertices, se[1].crease_vertices);
    assert_int_equal(a->nfree, b->nfree);
    assert_memory_equal(a->fid, b->fid, sizeof(int) * (size_t)nv);
    assert_memory_equal(a->crease, b->crease, (size_t)nv);
    assert_memory_equal(a->w, b->w, sizeof(double) * (size_t)nv);
    assert_memory_equal(a->n0, b->n0, n3);
    assert_memory_equal(a->X0, b->X0, n3);
    assert_memory_equal(a->Xin, b->Xin, n3);
    assert_memory_equal(a->probe, b->probe, sizeof(double) * (size_t)a->nprobe * (size_t)a->nfree);
    assert_true(a->kbest > 0);
    assert_int_equal(a->kbest, b->kbest);
    assert_memory_equal(&a->risk, &b->risk, sizeof a->risk);
    assert_memory_equal(a->Ybest, b->Ybest, n3);
    for (int r = 0; r < 2; r++) {
        free(se[r].sure);
        mcf__fair_free(&ce[r]);
    }
    free(si.sure);
    mcf__fair_free(&ci);
    mcf__graph_free(&g);
    free(fixed);
    mcf_mesh_free(m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_traces_bunny),
        cmocka_unit_test(test_traces_car),
        cmocka_unit_test(test_pick_setup_shared),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
