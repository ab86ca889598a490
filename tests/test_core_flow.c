/* SPDX-License-Identifier: MIT */
/*
 * test_core_flow.c - the integrators: measured temporal order by the
 * MATH.md protocol, the sphere radius law, the neumann2 erratum, fixed
 * vertices, degenerate triangles, adaptive stepping, cancel and progress.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

static mcf_mesh *sphere(int level)
{
    mcf_mesh *m = mcf_mesh_new_icosphere(level, 1.0, NULL);
    assert_non_null(m);
    return m;
}

static void run(mcf_mesh *m, mcf_scheme s, double dt, int iters, int normalize)
{
    mcf_flow_params p;
    mcf_error err = {0};
    mcf_flow_params_init(&p);
    p.scheme = s;
    p.dt = dt;
    p.iterations = iters;
    p.normalize = normalize;
    mcf_status rc = mcf_flow_run(m, &p, NULL, &err);
    if (rc != MCF_OK)
        fail_msg("%s: %s", mcf_scheme_get(s)->name, err.msg);
}

/* ||a - b||_M / sqrt(area) with the barycentric mass of b (MATH.md). */
static double merr(const mcf_mesh *a, const mcf_mesh *b)
{
    mcf_compare_result r;
    assert_int_equal(mcf_compare(a, b, &r, NULL), MCF_OK);
    return r.rms_rel;
}

/* Mean and spread (max - min) of the distance to the vertex centroid. */
static void radius(const mcf_mesh *m, double *mean, double *spread)
{
    const double *X = mcf_mesh_positions(m);
    int n = mcf_mesh_nvertices(m);
    double c[3] = {0, 0, 0}, lo = INFINITY, hi = 0, s = 0;
    for (int i = 0; i < n; i++)
        for (int d = 0; d < 3; d++)
            c[d] += X[3 * i + d] / n;
    for (int i = 0; i < n; i++) {
        double r = sqrt(pow(X[3 * i] - c[0], 2) + pow(X[3 * i + 1] - c[1], 2) + pow(X[3 * i + 2] - c[2], 2));
        s += r;
        lo = fmin(lo, r);
        hi = fmax(hi, r);
    }
    *mean = s / n;
    *spread = hi - lo;
}

/* Temporal order by MATH.md: icosphere of radius 1 (642 vertices), T =
 * 0.01 in 64, 128 and 256 steps, error against richardson at 4096 steps
 * (dt_ref = dt_min / 16). Returns the two observed orders. */
static mcf_mesh *reference;

static int setup_reference(void **state)
{
    (void)state;
    reference = sphere(3);
    run(reference, MCF_RICHARDSON, 0.01 / 4096, 4096, 0);
    return 0;
}

static int teardown_reference(void **state)
{
    (void)state;
    mcf_mesh_free(reference);
    return 0;
}

static void orders(mcf_scheme s, double p[2])
{
    double e[3];
    for (int k = 0; k < 3; k++) {
        int n = 64 << k;
        mcf_mesh *m = sphere(3);
        run(m, s, 0.01 / n, n, 0);
        e[k] = merr(m, reference);
        mcf_mesh_free(m);
    }
    p[0] = log2(e[0] / e[1]);
    p[1] = log2(e[1] / e[2]);
    print_message("order %-10s e = %.3e %.3e %.3e  p = %.3f %.3f\n", mcf_scheme_get(s)->name,
                  e[0], e[1], e[2], p[0], p[1]);
}

static void test_order_second(void **state)
{
    (void)state;
    const mcf_scheme second[] = {MCF_DESBRUN2, MCF_ROS2, MCF_RICHARDSON};
    for (size_t i = 0; i < sizeof second / sizeof *second; i++) {
        double p[2];
        orders(second[i], p);
        /* issue 2: >= 1.8 in the asymptotic regime */
        assert_true(p[0] >= 1.8 && p[1] >= 1.8);
    }
}

static void test_order_first(void **state)
{
    (void)state;
    const mcf_scheme first[] = {MCF_EULER, MCF_TAYLOR2, MCF_DESBRUN, MCF_NEUMANN2};
    for (size_t i = 0; i < sizeof first / sizeof *first; i++) {
        double p[2];
        orders(first[i], p);
        /* issue 2: first order, observed between 0.8 and 1.3 */
        assert_true(p[0] >= 0.8 && p[0] <= 1.3 && p[1] >= 0.8 && p[1] <= 1.3);
    }
}

/* The radius law R(t) = sqrt(R0^2 - 4t) on a fine icosphere (10,242
 * vertices). The discrete sphere shrinks at a slightly different rate
 * (spatial error O(h^2), h ~ 0.03), so the tolerance is 0.5% of R at
 * t = 0.1 (R = 0.775): measured ~0.1%. */
static void test_sphere_law(void **state)
{
    tl_long("the radius law on a 10,242-vertex sphere");
    (void)state;
    const mcf_scheme ss[] = {MCF_DESBRUN2, MCF_DESBRUN, MCF_ROS2, MCF_RICHARDSON, MCF_ARC, MCF_HUISKEN2};
    for (size_t i = 0; i < sizeof ss / sizeof *ss; i++) {
        mcf_mesh *m = sphere(5);
        int n = mcf_scheme_get(ss[i])->is_explicit ? 2000 : 100;
        run(m, ss[i], 0.1 / n, n, 0);
        double R, spread, exact = sqrt(1.0 - 0.4);
        radius(m, &R, &spread);
        print_message("sphere %-9s R(0.1) = %.6f exact %.6f rel %.2e spread %.1e\n",
                      mcf_scheme_get(ss[i])->name, R, exact, fabs(R - exact) / exact, spread);
        assert_true(fabs(R - exact) / exact < 5e-3);
        /* stays round: the radius varies by < 1% of R over the vertices */
        assert_true(spread < 1e-2 * R);
        mcf_mesh_free(m);
    }
}

/* MATH.md erratum 1: at dt = 1.5/lambda_max neumann2 amplifies the top
 * mode by |1 - 1.5 + 2.25| = 1.75 per step; euler (|1 - 1.5| = 0.5) and
 * taylor2 (|1 - 1.5 + 1.125| = 0.625) damp it. The radius spread of the
 * perturbation is measured against the same scheme's run without noise,
 * so the icosphere's own slight non-roundness does not mask it. */
static void test_neumann2_unstable(void **state)
{
    (void)state;
    const mcf_scheme ss[] = {MCF_NEUMANN2, MCF_EULER, MCF_TAYLOR2};
    double spread[3];
    for (int i = 0; i < 3; i++) {
        mcf_mesh *clean = sphere(4), *m = sphere(4);
        assert_int_equal(mcf_mesh_add_noise(m, 1e-3, 42, NULL), MCF_OK);
        double lam;
        assert_int_equal(mcf_lambda_max(m, MCF_LAPLACIAN_COTAN, MCF_MASS_BARYCENTRIC, &lam, NULL), MCF_OK);
        run(m, ss[i], 1.5 / lam, 10, 0);
        run(clean, ss[i], 1.5 / lam, 10, 0);
        const double *X = mcf_mesh_positions(m), *Y = mcf_mesh_positions(clean);
        double lo = INFINITY, hi = -INFINITY;
        for (int v = 0; v < mcf_mesh_nvertices(m); v++) {
            double dr = sqrt(X[3 * v] * X[3 * v] + X[3 * v + 1] * X[3 * v + 1] + X[3 * v + 2] * X[3 * v + 2]) -
                        sqrt(Y[3 * v] * Y[3 * v] + Y[3 * v + 1] * Y[3 * v + 1] + Y[3 * v + 2] * Y[3 * v + 2]);
            lo = fmin(lo, dr);
            hi = fmax(hi, dr);
        }
        spread[i] = hi - lo;
        print_message("dt = 1.5/lambda (lambda %.1f): %-8s perturbation radius spread %.3e\n", lam,
                      mcf_scheme_get(ss[i])->name, spread[i]);
        mcf_mesh_free(m);
        mcf_mesh_free(clean);
    }
    /* "many times": 1.75^10 / 0.625^10 ~ 3e4 for the top mode; ask 100x */
    assert_true(spread[0] > 100 * spread[1]);
    assert_true(spread[0] > 100 * spread[2]);
}

/* The fully implicit step solves (M(X+) + dt L(X+)) X+ = M(X+) X^k: the
 * Picard result satisfies it to the iteration tolerance, and differs from
 * the semi-implicit step by O(dt^2) (both are first order). */
static void test_implicit_fixed_point(void **state)
{
    (void)state;
    const double dt = 1e-3;
    mcf_mesh *m = sphere(3);
    assert_int_equal(mcf_mesh_add_noise(m, 0.1, 5, NULL), MCF_OK);
    mcf_mesh *x0 = mcf_mesh_dup(m, NULL), *be = mcf_mesh_dup(m, NULL);
    mcf_flow_params p;
    mcf_flow_stats st;
    mcf_error err = {0};
    mcf_flow_params_init(&p);
    p.scheme = MCF_IMPLICIT;
    p.dt = dt;
    p.iterations = 1;
    p.normalize = 0;
    assert_int_equal(mcf_flow_run(m, &p, &st, &err), MCF_OK);
    assert_true(st.picard_iterations >= 2);
    run(be, MCF_DESBRUN, dt, 1, 0);
    mcf_operator op = {0};
    assert_int_equal(mcf_operator_build(m, MCF_LAPLACIAN_COTAN, MCF_MASS_BARYCENTRIC, &op, NULL), MCF_OK);
    const double *X = mcf_mesh_positions(m), *X0 = mcf_mesh_positions(x0);
    double res = 0, scale = 0;
    for (int i = 0; i < op.n; i++)
        for (int d = 0; d < 3; d++) {
            double r = op.mass[i] * (X[3 * i + d] - X0[3 * i + d]);
            for (int t = op.rowptr[i]; t < op.rowptr[i + 1]; t++)
                r += dt * op.val[t] * X[3 * op.col[t] + d];
            res += r * r;
            scale += pow(op.mass[i] * X[3 * i + d], 2);
        }
    /* the Picard tolerance 1e-10 bounds the last update; the residual is
     * of that order relative to |M X| */
    print_message("implicit: %d Picard iterations, relative residual %.2e, |implicit - desbrun| %.2e\n",
                  st.picard_iterations, sqrt(res / scale), merr(m, be));
    assert_true(sqrt(res / scale) < 1e-8);
    assert_true(merr(m, be) > 0.0 && merr(m, be) < 1e-3);
    mcf_operator_free(&op);
    mcf_mesh_free(m);
    mcf_mesh_free(x0);
    mcf_mesh_free(be);
}

/* Stanford bunny with 5 holes: fixed boundary vertices do not move (to
 * the bit), user-fixed vertices neither, and everything else does; for an
 * implicit scheme (boundary from the matrix pattern) and an explicit one
 * (boundary found without a pattern: odd_edges, then the edge counts).
 * bunny.drc is in the repository; stanford-bunny.obj, the same scan with
 * 1,113 unreferenced vertices more, is a large mesh of $MCF_MESHES. */
static void fixed_vertices_run(const char *file, int unreferenced,
                               mcf_scheme scheme, double dt)
{
    mcf_mesh *m = tl_load(file);
    int n = mcf_mesh_nvertices(m);
    double *X0 = malloc(3 * sizeof(double) * n);
    memcpy(X0, mcf_mesh_positions(m), 3 * sizeof(double) * n);
    int32_t fixed_user[2] = {100, 2000};
    mcf_flow_params p;
    mcf_error err = {0};
    mcf_flow_params_init(&p);
    p.fixed = fixed_user;
    p.nfixed = 2;
    p.iterations = 3;
    p.scheme = scheme;
    p.dt = dt;
    assert_int_equal(mcf_flow_run(m, &p, NULL, &err), MCF_OK);
    const double *X = mcf_mesh_positions(m);
    /* count directed edges: an undirected edge used once is boundary */
    int moved_boundary = 0, nboundary = 0, moved = 0;
    unsigned char *isb = calloc((size_t)n, 1);
    /* boundary vertices from the uniform operator: an edge in one face
     * has weight -1/2, an interior edge -1 */
    mcf_operator op = {0};
    assert_int_equal(mcf_operator_build(m, MCF_LAPLACIAN_UNIFORM, MCF_MASS_BARYCENTRIC, &op, NULL), MCF_OK);
    for (int i = 0; i < n; i++)
        for (int t = op.rowptr[i]; t < op.rowptr[i + 1]; t++)
            /* uniform weight 1/2 per face: -0.5 means one face (boundary) */
            if (op.col[t] != i && op.val[t] > -0.75)
                isb[i] = 1;
    for (int i = 0; i < n; i++) {
        int same = memcmp(X + 3 * i, X0 + 3 * i, 3 * sizeof(double)) == 0;
        if (isb[i]) {
            nboundary++;
            moved_boundary += !same;
        } else {
            moved += !same;
        }
    }
    /* 223 boundary edges in closed loops: 223 boundary vertices */
    assert_int_equal(nboundary, 223);
    assert_int_equal(moved_boundary, 0);
    assert_memory_equal(X + 3 * 100, X0 + 3 * 100, 3 * sizeof(double));
    assert_memory_equal(X + 3 * 2000, X0 + 3 * 2000, 3 * sizeof(double));
    /* all referenced interior vertices move: 35,947 - 1,113 unreferenced
     * - 223 boundary - 2 user-fixed (stanford-bunny.obj) */
    assert_int_equal(moved, n - unreferenced - 223 - 2);
    free(isb);
    free(X0);
    mcf_operator_free(&op);
    mcf_mesh_free(m);
}

static void test_fixed_vertices(void **state)
{
    (void)state;
    fixed_vertices_run("bunny.drc", 0, MCF_DESBRUN2, 1e-3);
    /* euler needs dt below 2/lambda_max; 1e-7 (normalized) is well below
     * for this scan (lambda_max ~ 1e6 at unit area) */
    fixed_vertices_run("bunny.drc", 0, MCF_EULER, 1e-7);
}

static void test_fixed_vertices_scan(void **state)
{
    (void)state;
    fixed_vertices_run("stanford-bunny.obj", 1113, MCF_DESBRUN2, 1e-3);
    fixed_vertices_run("stanford-bunny.obj", 1113, MCF_EULER, 1e-7);
}

/* Zero-area triangles (a vertex collapsed onto its neighbour, and a
 * triangle with a repeated index) give finite results for every scheme. */
static void test_degenerate_no_nan(void **state)
{
    (void)state;
    for (int s = 0; s < MCF_NSCHEMES; s++) {
        mcf_mesh *ico = sphere(3);
        int n = mcf_mesh_nvertices(ico), nf = mcf_mesh_nfaces(ico);
        double *X = malloc(3 * sizeof(double) * n);
        int32_t *F = malloc(3 * sizeof(int32_t) * (nf + 1));
        memcpy(X, mcf_mesh_positions(ico), 3 * sizeof(double) * n);
        memcpy(F, mcf_mesh_faces(ico), 3 * sizeof(int32_t) * nf);
        memcpy(X + 3 * F[1], X + 3 * F[0], 3 * sizeof(double)); /* collapse an edge */
        F[3 * nf] = F[3]; F[3 * nf + 1] = F[3]; F[3 * nf + 2] = F[4]; /* repeated index */
        mcf_mesh *m = mcf_mesh_new(n, X, nf + 1, F, NULL);
        assert_non_null(m);
        mcf_flow_params p;
        mcf_error err = {0};
        mcf_flow_params_init(&p);
        p.scheme = (mcf_scheme)s;
        /* the filters take no dt (taubin, fairing: 5 steps; fairing_feature
         * chooses its own iterations) */
        p.iterations = s == MCF_FAIRING_FEATURE ? 0 : 5;
        int filter = s == MCF_TAUBIN || s == MCF_FAIRING || s == MCF_FAIRING_EXPLICIT || s == MCF_FAIRING_FEATURE;
        p.dt_auto = mcf_scheme_get(p.scheme)->is_explicit && !filter;
        p.dt = filter && s != MCF_TAUBIN ? 0.0 : 1e-4;
        mcf_status rc = mcf_flow_run(m, &p, NULL, &err);
        if (rc != MCF_OK)
            fail_msg("%s on a degenerate mesh: %s", mcf_scheme_get(p.scheme)->name, err.msg);
        const double *Y = mcf_mesh_positions(m);
        for (int i = 0; i < 3 * n; i++)
            assert_true(isfinite(Y[i]));
        mcf_mesh_free(m);
        mcf_mesh_free(ico);
        free(X);
        free(F);
    }
}

/* Adaptive stepping on a noisy sphere (fast transient, then slow decay):
 * each adaptive run meets its tolerance at T and needs fewer steps than the
 * fixed-step run of the same scheme with equal or better accuracy. */
static void test_adaptive(void **state)
{
    tl_long("adaptive against fixed steps on a noisy sphere");
    (void)state;
    const double T = 0.01, tol = 1e-5;
    mcf_mesh *base = sphere(3);
    assert_int_equal(mcf_mesh_add_noise(base, 0.3, 3, NULL), MCF_OK);
    mcf_mesh *ref = mcf_mesh_dup(base, NULL);
    run(ref, MCF_DESBRUN2, T / 8192, 8192, 1);
    const mcf_scheme ss[] = {MCF_DESBRUN2, MCF_ROS2, MCF_RICHARDSON, MCF_DESBRUN};
    for (size_t i = 0; i < sizeof ss / sizeof *ss; i++) {
        mcf_mesh *m = mcf_mesh_dup(base, NULL);
        mcf_flow_params p;
        mcf_flow_stats st;
        mcf_error err = {0};
        mcf_flow_params_init(&p);
        p.scheme = ss[i];
        p.adaptive = 1;
        p.tol = tol;
        p.time = T;
        p.dt = 1e-6;
        assert_int_equal(mcf_flow_run(m, &p, &st, &err), MCF_OK);
        double ea = merr(m, ref);
        int attempts = st.steps + st.rejected;
        tl_assert_near(st.t_final, T, 1e-12, "adaptive final time");
        /* fixed steps: double until the error is at most the adaptive one */
        int nfix = 1;
        double ef = INFINITY;
        while (ef > ea && nfix <= 8192) {
            nfix *= 2;
            mcf_mesh *f = mcf_mesh_dup(base, NULL);
            run(f, ss[i], T / nfix, nfix, 1);
            ef = merr(f, ref);
            mcf_mesh_free(f);
        }
        print_message("adaptive %-10s tol %.0e: error %.2e in %d steps (+%d rejected); fixed needs %d steps (error %.2e)\n",
                      mcf_scheme_get(ss[i])->name, tol, ea, st.steps, st.rejected, nfix, ef);
        /* "meets its tolerance": desbrun2 and ros2 control the error per
         * unit step, so their global error at T is about tol; the others control
         * the local error per step of their first-order companion, so the
         * local errors sum to at most steps * tol. The flow itself
         * amplifies a radius error by R0 / R(T): the unit-area sphere has
         * R0^2 = 1/(4 pi), and R(T)^2 = R0^2 - 4T gives a factor 1.42.
         * desbrun2 gets 2x on top: the Milne estimate's leading constant
         * assumes a smooth third derivative, which the noisy start lacks. */
        double amp = sqrt(1.0 / (4 * M_PI)) / sqrt(1.0 / (4 * M_PI) - 4 * T);
        int per_unit = ss[i] == MCF_DESBRUN2 || ss[i] == MCF_ROS2;
        assert_true(ea <= amp * (per_unit ? 2 * tol : st.steps * tol));
        /* ros2 per unit step (issue 30) follows tol (measured 0.2 tol) at
         * a cost: its estimate grows faster than h^2 on the noisy start and
         * one attempt in three is rejected, 3262 steps + 1487 rejected
         * where 2048 fixed steps are less accurate and 4096 more: bound
         * 1.5x the fixed run found (measured 1.16x) */
        assert_true(attempts < (ss[i] == MCF_ROS2 ? 1.5 * nfix : nfix));
        mcf_flow_stats_free(&st);
        mcf_mesh_free(m);
    }
    mcf_mesh_free(ref);
    mcf_mesh_free(base);
}

static int cancel_after_3(void *ctx, int step, double t, double dt, double energy)
{
    (void)t; (void)dt;
    int *calls = ctx;
    (*calls)++;
    assert_true(energy > 0.0);
    return step >= 3;
}

static void test_cancel_and_progress(void **state)
{
    (void)state;
    mcf_mesh *m = sphere(3);
    mcf_flow_params p;
    mcf_flow_stats st;
    mcf_error err = {0};
    int calls = 0;
    mcf_flow_params_init(&p);
    p.iterations = 10;
    p.progress = cancel_after_3;
    p.progress_ctx = &calls;
    p.log_steps = 1;
    assert_int_equal(mcf_flow_run(m, &p, &st, &err), MCF_ECANCELED);
    assert_int_equal(calls, 3);
    assert_int_equal(st.steps, 3);
    assert_int_equal(st.nlog, 3);
    assert_non_null(strstr(err.msg, "canceled"));
    mcf_flow_stats_free(&st);
    /* a cancel flag set before the run stops it before the first step */
    /* The flag is a C11 atomic end to end (issue 9: a volatile int
     * written under a lock and read without one was a data race). */
    _Static_assert(_Generic(p.cancel, const mcf_cancel_flag *: 1, default: 0) &&
                       _Generic((mcf_cancel_flag *)0, atomic_int *: 1, default: 0),
                   "mcf_flow_params.cancel points to an atomic_int");
    mcf_cancel_flag flag = 1;
    p.progress = NULL;
    p.cancel = &flag;
    const double x0 = mcf_mesh_positions(m)[0];
    assert_int_equal(mcf_flow_run(m, &p, &st, &err), MCF_ECANCELED);
    assert_int_equal(st.steps, 0);
    assert_true(mcf_mesh_positions(m)[0] == x0);
    mcf_flow_stats_free(&st);
    mcf_mesh_free(m);
}

/* euler beyond its stability limit fails clearly, the mesh keeps the last
 * finite state; dt=auto is stable. */
static void test_explicit_limits(void **state)
{
    (void)state;
    mcf_mesh *m = sphere(4);
    assert_int_equal(mcf_mesh_add_noise(m, 0.05, 1, NULL), MCF_OK);
    mcf_flow_params p;
    mcf_flow_stats st;
    mcf_error err = {0};
    mcf_flow_params_init(&p);
    p.scheme = MCF_EULER;
    p.dt = 1.0; /* normalized units: 50 times the extinction time */
    p.iterations = 10;
    mcf_status rc = mcf_flow_run(m, &p, &st, &err);
    assert_int_equal(rc, MCF_ENUMERIC);
    assert_non_null(strstr(err.msg, "stability"));
    const double *X = mcf_mesh_positions(m);
    for (int i = 0; i < 3 * mcf_mesh_nvertices(m); i++)
        assert_true(isfinite(X[i]));
    mcf_flow_stats_free(&st);
    p.dt_auto = 1;
    p.iterations = 50;
    assert_int_equal(mcf_flow_run(m, &p, &st, &err), MCF_OK);
    assert_true(st.lambda_max > 0 && fabs(st.dt_first - 0.9 / st.lambda_max) < 1e-12 / st.lambda_max);
    mcf_flow_stats_free(&st);
    mcf_mesh_free(m);
}

/* Regressions: a stable explicit step may flip sliver triangles (for dt >
 * 1/lambda the top mode changes sign each step), and a step that unfolds
 * a face the noise had folded turns it by ~180 degrees. Neither is an
 * instability: euler at dt=auto on the clean Stanford scan, euler at
 * 0.25/lambda on a noisy spot, and adaptive desbrun2 on that noisy spot
 * all complete. */
static void test_no_false_instability(void **state)
{
    (void)state;
    mcf_flow_params p;
    mcf_flow_stats st;
    mcf_error err = {0};
    mcf_mesh *bunny = tl_load("stanford-bunny.obj");
    mcf_flow_params_init(&p);
    p.scheme = MCF_EULER;
    p.dt_auto = 1;
    p.iterations = 10;
    if (mcf_flow_run(bunny, &p, &st, &err) != MCF_OK)
        fail_msg("euler dt=auto on stanford-bunny: %s", err.msg);
    mcf_flow_stats_free(&st);
    mcf_mesh_free(bunny);

    mcf_mesh *spot = tl_load("spot.obj");
    assert_int_equal(mcf_mesh_add_noise(spot, 0.2, 11, NULL), MCF_OK);
    mcf_mesh *spot2 = mcf_mesh_dup(spot, NULL);
    double lam;
    assert_int_equal(mcf_lambda_max(spot, MCF_LAPLACIAN_COTAN, MCF_MASS_BARYCENTRIC, &lam, NULL), MCF_OK);
    mcf_flow_params_init(&p);
    p.scheme = MCF_EULER;
    p.normalize = 0;
    p.dt = 0.25 / lam;
    p.iterations = 60;
    if (mcf_flow_run(spot, &p, &st, &err) != MCF_OK)
        fail_msg("euler at 0.25/lambda on a noisy spot: %s", err.msg);
    mcf_flow_stats_free(&st);

    mcf_flow_params_init(&p);
    p.adaptive = 1;
    p.tol = 1e-4;
    p.time = 1e-4;
    p.dt = 1e-7;
    if (mcf_flow_run(spot2, &p, &st, &err) != MCF_OK)
        fail_msg("adaptive desbrun2 on a noisy spot: %s", err.msg);
    print_message("adaptive desbrun2 on noisy spot: %d steps, %d rejected\n", st.steps, st.rejected);
    mcf_flow_stats_free(&st);
    mcf_mesh_free(spot);
    mcf_mesh_free(spot2);
}


/* Parameter checks name the field. */
static void test_params_check(void **state)
{
    (void)state;
    mcf_flow_params p;
    mcf_error err = {0};
    mcf_flow_params_init(&p);
    p.dt = -1;
    assert_int_equal(mcf_flow_params_check(&p, 10, &err), MCF_EINVAL);
    assert_non_null(strstr(err.msg, "dt"));
    mcf_flow_params_init(&p);
    p.scheme = MCF_EULER;
    p.adaptive = 1;
    assert_int_equal(mcf_flow_params_check(&p, 10, &err), MCF_EINVAL);
    assert_non_null(strstr(err.msg, "adaptive"));
    mcf_flow_params_init(&p);
    int32_t bad = 10;
    p.fixed = &bad;
    p.nfixed = 1;
    assert_int_equal(mcf_flow_params_check(&p, 10, &err), MCF_EINVAL);
    assert_non_null(strstr(err.msg, "fixed_vertices"));
    mcf_flow_params_init(&p);
    p.dt_auto = 1; /* desbrun2 is implicit */
    assert_int_equal(mcf_flow_params_check(&p, 10, &err), MCF_EINVAL);
    mcf_scheme s;
    assert_int_equal(mcf_scheme_from_name("desbrun2", &s), MCF_OK);
    assert_int_equal(s, MCF_DESBRUN2);
    assert_int_equal(mcf_scheme_from_name("nope", &s), MCF_EINVAL);
}

/* The surface's area and signed volume about the origin, summed in long
 * double here (the core's sums are its own, in double). */
static double area_volume_ref(const double *X, const int32_t *F, int nf, double *vol)
{
    long double A = 0, V = 0;
    for (int f = 0; f < nf; f++) {
        const double *a = X + 3 * F[3 * f], *b = X + 3 * F[3 * f + 1], *c = X + 3 * F[3 * f + 2];
        long double u[3], v[3], n[3];
        for (int d = 0; d < 3; d++) {
            u[d] = (long double)b[d] - a[d];
            v[d] = (long double)c[d] - a[d];
        }
        n[0] = u[1] * v[2] - u[2] * v[1];
        n[1] = u[2] * v[0] - u[0] * v[2];
        n[2] = u[0] * v[1] - u[1] * v[0];
        A += 0.5L * sqrtl(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        V += (a[0] * ((long double)b[1] * c[2] - (long double)b[2] * c[1]) +
              a[1] * ((long double)b[2] * c[0] - (long double)b[0] * c[2]) +
              a[2] * ((long double)b[0] * c[1] - (long double)b[1] * c[0])) / 6.0L;
    }
    *vol = (double)V;
    return (double)A;
}

/* What progress_energy's callback saw. */
typedef struct {
    const mcf_mesh *m;          /* an MCF run's mesh (its working copy), or
                                   NULL (a fairing filter's: not in m) */
    const mcf_flow_stats *st;
    double a0;                  /* the input's area (normalize's unit) */
    int normalize;
    int calls, nan, logged;
    double worst_area, worst_volume; /* relative gaps to area_volume_ref */
} energy_watch;

static int watch_energy(void *ctx, int step, double t, double dt, double energy)
{
    energy_watch *w = ctx;
    (void)t, (void)dt;
    w->calls++;
    if (isnan(energy)) {
        w->nan++;
        return 0;
    }
    /* the log's entry of this step, to the bit */
    assert_non_null(w->st->log);
    assert_true(w->st->nlog >= step);
    assert_true(energy == w->st->log[step - 1].area);
    w->logged++;
    if (w->m) {
        double V, A = area_volume_ref(mcf_mesh_positions(w->m), mcf_mesh_faces(w->m),
                                      mcf_mesh_nfaces(w->m), &V);
        /* working units (x - c) / sqrt(a0) with normalize: area x a0 */
        A *= w->normalize ? w->a0 : 1.0;
        w->worst_area = fmax(w->worst_area, fabs(energy - A) / A);
        if (!w->normalize)
            w->worst_volume = fmax(w->worst_volume, fabs(w->st->log[step - 1].volume - V) / fabs(V));
    }
    return 0;
}

/* The progress callback's energy is the step log's area (input units)
 * when the run keeps a log, and NaN without one: the core then makes no
 * pass over the faces for it (a diagnostic the daemon's unmeasured jobs
 * do not pay; 10% of a 7M scan's default request). Checked against the
 * mesh's own area and volume, summed here, after every step of an MCF
 * run (its working copy is the mesh), with and without normalize:
 * relative 1e-12 covers double sums over 1,280 faces of terms of one
 * sign (about 1e-14) and the rounding of 1/sqrt(area) squared. The
 * fairing filters log through the same sum (fairing_hook): their energy
 * is checked against the log. */
static void test_progress_energy(void **state)
{
    (void)state;
    const mcf_scheme schemes[] = {MCF_DESBRUN2, MCF_DESBRUN2, MCF_FAIRING, MCF_FAIRING_EXPLICIT};
    for (int i = 0; i < 4; i++)
        for (int log = 0; log < 2; log++) {
            mcf_mesh *m = sphere(3);
            assert_int_equal(mcf_mesh_add_noise(m, 0.2, 11, NULL), MCF_OK);
            mcf_flow_params p;
            mcf_flow_stats st;
            mcf_error err = {0};
            double v0;
            energy_watch w = {0};
            int fairing = schemes[i] != MCF_DESBRUN2;
            mcf_flow_params_init(&p);
            p.scheme = schemes[i];
            p.iterations = 4;
            if (!fairing) {
                p.dt = 1e-3;
                p.normalize = i; /* off, then on */
            }
            p.log_steps = log;
            p.progress = watch_energy;
            p.progress_ctx = &w;
            w.m = fairing ? NULL : m;
            w.st = &st;
            w.normalize = p.normalize;
            w.a0 = area_volume_ref(mcf_mesh_positions(m), mcf_mesh_faces(m), mcf_mesh_nfaces(m), &v0);
            if (mcf_flow_run(m, &p, &st, &err) != MCF_OK)
                fail_msg("%s: %s", mcf_scheme_get(p.scheme)->name, err.msg);
            assert_int_equal(w.calls, 4);
            assert_int_equal(st.steps, 4);
            if (!log) {
                assert_int_equal(w.nan, 4);
                assert_null(st.log);
            } else {
                assert_int_equal(w.logged, 4);
                if (!fairing && (w.worst_area > 1e-12 || w.worst_volume > 1e-12))
                    fail_msg("desbrun2 normalize %d: energy off the area by %.3g, the log's "
                             "volume off by %.3g (relative, tolerance 1e-12)",
                             p.normalize, w.worst_area, w.worst_volume);
            }
            mcf_flow_stats_free(&st);
            mcf_mesh_free(m);
        }
}

/* rescale=volume keeps the enclosed volume; normalize round-trips the
 * position/scale of the input (a far-away, large mesh smooths the same). */
static void test_rescale_and_normalize(void **state)
{
    (void)state;
    mcf_mesh *m = sphere(3);
    double v0 = mcf_mesh_volume(m);
    mcf_flow_params p;
    mcf_error err = {0};
    mcf_flow_params_init(&p);
    p.rescale = MCF_RESCALE_VOLUME;
    p.dt = 1e-3;
    p.iterations = 10;
    assert_int_equal(mcf_flow_run(m, &p, NULL, &err), MCF_OK);
    tl_assert_near(mcf_mesh_volume(m) / v0, 1.0, 1e-12, "volume ratio with rescale=volume");

    /* the same flow on a copy scaled by 100 and moved by 1e3 gives the
     * same shape, scaled and moved: normalize makes dt dimensionless */
    mcf_mesh *a = sphere(3), *b = sphere(3);
    assert_int_equal(mcf_mesh_add_noise(a, 0.1, 9, NULL), MCF_OK);
    double *Xb = mcf_mesh_positions_mut(b);
    const double *Xa = mcf_mesh_positions(a);
    int n = mcf_mesh_nvertices(a);
    for (int i = 0; i < 3 * n; i++)
        Xb[i] = 100.0 * Xa[i] + 1e3;
    p.rescale = MCF_RESCALE_NONE;
    assert_int_equal(mcf_flow_run(a, &p, NULL, &err), MCF_OK);
    assert_int_equal(mcf_flow_run(b, &p, NULL, &err), MCF_OK);
    double maxd = 0;
    for (int i = 0; i < 3 * n; i++)
        maxd = fmax(maxd, fabs((Xb[i] - 1e3) / 100.0 - Xa[i]));
    /* 1e-9: rounding of coordinates ~1e3 (eps 2e-13) amplified by the
     * solves' condition numbers */
    assert_true(maxd < 1e-9);
    mcf_mesh_free(a);
    mcf_mesh_free(b);
    mcf_mesh_free(m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_order_second),
        cmocka_unit_test(test_order_first),
        cmocka_unit_test(test_sphere_law),
        cmocka_unit_test(test_neumann2_unstable),
        cmocka_unit_test(test_implicit_fixed_point),
        cmocka_unit_test(test_fixed_vertices),
        cmocka_unit_test(test_fixed_vertices_scan),
        cmocka_unit_test(test_degenerate_no_nan),
        cmocka_unit_test(test_adaptive),
        cmocka_unit_test(test_cancel_and_progress),
        cmocka_unit_test(test_progress_energy),
        cmocka_unit_test(test_explicit_limits),
        cmocka_unit_test(test_no_false_instability),
        cmocka_unit_test(test_params_check),
        cmocka_unit_test(test_rescale_and_normalize),
    };
    return cmocka_run_group_tests_name("core_flow", tests, setup_reference, teardown_reference);
}
