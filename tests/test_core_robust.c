/* SPDX-License-Identifier: MIT */
/*
 * test_core_robust.c - the default request's robust stages
 * (docs/fairing.md, "Spikes"):
 *  - mcf__spikes against what it must find and where it must put a spike,
 *    computed here independently: on a flat grid the spikes and only they,
 *    each back on the plane with its position along the plane kept; on
 *    clean meshes with corners and creases and under Gaussian noise, none;
 *  - end to end: the repository's meshes with 1% outliers of 3-5 mean
 *    edges on Gaussian noise of 0.1 along the normals (issue 31's `out`
 *    model), the default request's error against the input's and against
 *    the uniform Taubin oracle (Open3D's filter_smooth_taubin's weights at
 *    its best pass count, chosen knowing the clean mesh).
 * Runs in about 5 s.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_internal.h" /* mcf__spikes, mcf__graph_build */
#include "testlib.h"

#define PI_D 3.14159265358979323846

/* splitmix64 in [0, 1), and a standard Gaussian from two of them. */
static double uniform01(uint64_t *r)
{
    uint64_t z = (*r += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    z ^= z >> 31;
    return (double)(z >> 11) * (1.0 / 9007199254740992.0);
}

static double gauss01(uint64_t *r)
{
    double a = uniform01(r);
    return sqrt(-2.0 * log(1.0 - a)) * cos(2.0 * PI_D * uniform01(r));
}

/* mcf__spikes on X (the mesh m's faces, nothing fixed but the vertices of
 * degree < 3 that it skips anyway); returns the count. */
static int run_spikes(const mcf_mesh *m, double *X, double hbar, const unsigned char *fixed)
{
    mcf__graph g;
    int nv = mcf_mesh_nvertices(m);
    unsigned char *none = calloc((size_t)nv, 1);
    assert_non_null(none);
    assert_int_equal(mcf__graph_build(mcf_mesh_faces(m), mcf_mesh_nfaces(m), nv, &g, NULL), MCF_OK);
    int n = mcf__spikes(&g, mcf_mesh_faces(m), mcf_mesh_nfaces(m), fixed ? fixed : none, hbar, X);
    mcf__graph_free(&g);
    free(none);
    return n;
}

/* A flat n x n grid of unit squares split along one diagonal, z = 0. */
static mcf_mesh *flat_grid(int n)
{
    int nv = n * n, nf = 2 * (n - 1) * (n - 1), f = 0;
    double *X = calloc(3 * (size_t)nv, sizeof(double));
    int32_t *F = malloc(3 * sizeof(int32_t) * (size_t)nf);
    assert_non_null(X);
    assert_non_null(F);
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            X[3 * (j * n + i)] = i;
            X[3 * (j * n + i) + 1] = j;
        }
    for (int j = 0; j + 1 < n; j++)
        for (int i = 0; i + 1 < n; i++) {
            int32_t a = j * n + i, b = a + 1, c = a + n, d = c + 1, t[6] = {a, b, d, a, d, c};
            memcpy(F + 3 * f, t, sizeof t);
            f += 2;
        }
    mcf_mesh *m = mcf_mesh_new(nv, X, nf, F, NULL);
    assert_non_null(m);
    free(X);
    free(F);
    return m;
}

/* A flat 15 x 15 grid (mean edge (2 + sqrt 2) / 3 = 1.14) with five
 * spikes of 3-5 units up and down, two of them neighbours: exactly those
 * five are found; each comes back to z = 0 exactly (its ring's centroid
 * is on the plane and the normal there is the plane's: the reference),
 * with its x and y as they were; no other vertex moves (bit for bit). */
static void test_spikes_flat_grid(void **state)
{
    enum { N = 15 };
    static const int at[5] = {3 * N + 3, 7 * N + 7, 7 * N + 8, 11 * N + 4, 10 * N + 11};
    static const double up[5] = {3.0, -4.0, 5.0, 3.5, -4.5};
    (void)state;
    mcf_mesh *m = flat_grid(N);
    double X[3 * N * N], X0[3 * N * N];
    memcpy(X0, mcf_mesh_positions(m), sizeof X0);
    for (int s = 0; s < 5; s++)
        X0[3 * at[s] + 2] = up[s];
    memcpy(X, X0, sizeof X);
    assert_int_equal(run_spikes(m, X, (2.0 + sqrt(2.0)) / 3.0, NULL), 5);
    for (int i = 0; i < N * N; i++) {
        int spike = 0;
        for (int s = 0; s < 5; s++)
            spike |= at[s] == i;
        if (!spike) {
            assert_memory_equal(X + 3 * i, X0 + 3 * i, 3 * sizeof(double));
            continue;
        }
        /* 1e-12: a centroid of six unit-grid points and one projection,
         * a few roundings of numbers of size 10 */
        tl_assert_near(X[3 * i], X0[3 * i], 1e-12, "a spike's x");
        tl_assert_near(X[3 * i + 1], X0[3 * i + 1], 1e-12, "a spike's y");
        tl_assert_near(X[3 * i + 2], 0.0, 1e-12, "a spike's height");
    }
    mcf_mesh_free(m);
}

/* The same grid bent into a cylinder of radius 6 with Gaussian noise of
 * 0.1 mean edges along the normals and 1% spikes of 3-5 mean edges
 * (random sign): exactly the spikes found; each repaired one within 0.3
 * mean edges of its clean place (measured 0.06-0.19: its ring's centroid
 * carries the average of 6 noise draws, 0.04, and the cylinder's sag, 4
 * of 6 neighbours h^2 / (2 r) = 0.1 below, 0.06; the normal it moves
 * along, averaged over the ring, tilts by the noise over about two
 * edges, 0.05 rad, times a spike of up to 5: 0.25), the others
 * untouched. */
static void test_spikes_noisy_cylinder(void **state)
{
    enum { N = 30 };
    (void)state;
    mcf_mesh *flat = flat_grid(N);
    double *X = malloc(3 * sizeof(double) * N * N), *C = malloc(3 * sizeof(double) * N * N);
    unsigned char *truth = calloc(N * N, 1);
    double h = (2.0 + sqrt(2.0)) / 3.0, r = 6.0; /* the flat grid's mean edge */
    uint64_t rng = 11;
    int nspike = 0;
    assert_non_null(X);
    assert_non_null(C);
    assert_non_null(truth);
    /* x along the axis, the grid's y around it: z = r cos(y/r) - r */
    for (int i = 0; i < N * N; i++) {
        const double *p = mcf_mesh_positions(flat) + 3 * i;
        C[3 * i] = p[0];
        C[3 * i + 1] = r * sin(p[1] / r);
        C[3 * i + 2] = r * cos(p[1] / r) - r;
    }
    for (int i = 0; i < N * N; i++) {
        int ix = i % N, iy = i / N, inner = ix > 1 && ix < N - 2 && iy > 1 && iy < N - 2;
        double n[3] = {0.0, C[3 * i + 1] / r, (C[3 * i + 2] + r) / r}, a = 0.1 * h * gauss01(&rng);
        if (inner && uniform01(&rng) < 0.01) {
            a += (3.0 + 2.0 * uniform01(&rng)) * h * (uniform01(&rng) < 0.5 ? -1.0 : 1.0);
            truth[i] = 1;
            nspike++;
        }
        for (int e = 0; e < 3; e++)
            X[3 * i + e] = C[3 * i + e] + a * n[e];
    }
    assert_true(nspike >= 4);
    mcf_mesh *m = mcf_mesh_new(N * N, C, mcf_mesh_nfaces(flat), mcf_mesh_faces(flat), NULL);
    assert_non_null(m);
    double *X0 = malloc(3 * sizeof(double) * N * N);
    assert_non_null(X0);
    memcpy(X0, X, 3 * sizeof(double) * N * N);
    int found = run_spikes(m, X, h, NULL);
    print_message("cylinder: %d spikes, %d found\n", nspike, found);
    assert_int_equal(found, nspike);
    for (int i = 0; i < N * N; i++) {
        if (!truth[i]) {
            assert_memory_equal(X + 3 * i, X0 + 3 * i, 3 * sizeof(double));
            continue;
        }
        double d[3];
        mcf__sub3(X + 3 * i, C + 3 * i, d);
        if (!(sqrt(mcf__dot3(d, d)) < 0.3 * h))
            fail_msg("spike %d repaired %.3f mean edges from its clean place", i, sqrt(mcf__dot3(d, d)) / h);
    }
    free(X);
    free(X0);
    free(C);
    free(truth);
    mcf_mesh_free(m);
    mcf_mesh_free(flat);
}

/* No spike where there is none: clean meshes with sharp corners and
 * creases (car.drc, a CAD part of 920 vertices; a coarse icosphere, whose
 * 12 degree-5 vertices stand out of their rings) and an icosphere with
 * Gaussian noise of 0.5 mean edges along the normals (seeds 1-3). */
static void test_spikes_none(void **state)
{
    (void)state;
    mcf_mesh *ico = mcf_mesh_new_icosphere(1, 1.0, NULL), *fine = mcf_mesh_new_icosphere(4, 1.0, NULL);
    assert_non_null(ico);
    assert_non_null(fine);
    mcf_mesh *list[2] = {ico, tl_mesh_in_repo("car.drc") ? tl_load("car.drc") : NULL};
    for (int q = 0; q < 2; q++) {
        if (!list[q])
            continue;
        mcf_mesh_info info;
        int nv = mcf_mesh_nvertices(list[q]);
        double *X = malloc(3 * sizeof(double) * (size_t)nv);
        assert_non_null(X);
        assert_int_equal(mcf_mesh_inspect(list[q], &info, NULL), MCF_OK);
        memcpy(X, mcf_mesh_positions(list[q]), 3 * sizeof(double) * (size_t)nv);
        assert_int_equal(run_spikes(list[q], X, info.mean_edge, NULL), 0);
        free(X);
        mcf_mesh_free(list[q]);
    }
    for (int seed = 1; seed <= 3; seed++) {
        mcf_mesh *m = mcf_mesh_dup(fine, NULL);
        mcf_flow_params p;
        mcf_mesh_info info;
        mcf_flow_params_init(&p);
        assert_int_equal(mcf_mesh_inspect(fine, &info, NULL), MCF_OK);
        assert_int_equal(mcf_flow_add_noise(m, &p, 0.5, (uint64_t)seed, NULL), MCF_OK);
        int nv = mcf_mesh_nvertices(m);
        double *X = malloc(3 * sizeof(double) * (size_t)nv);
        assert_non_null(X);
        memcpy(X, mcf_mesh_positions(m), 3 * sizeof(double) * (size_t)nv);
        assert_int_equal(run_spikes(m, X, info.mean_edge, NULL), 0);
        free(X);
        mcf_mesh_free(m);
    }
    mcf_mesh_free(fine);
}

/* ------------------------------------------------------- end to end */

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double rms(const mcf_mesh *m, const mcf_mesh *clean)
{
    mcf_compare_result r;
    assert_int_equal(mcf_compare(m, clean, &r, NULL), MCF_OK);
    return r.rms_m;
}

/* The uniform Taubin oracle (lambda 0.5, mu -0.53, Open3D's
 * filter_smooth_taubin): the best error over the pass counts, one pass at
 * a time, stopping 20 passes past the best once 5% worse. */
static double taubin_oracle(const mcf_mesh *noisy, const mcf_mesh *clean)
{
    mcf_mesh *x = mcf_mesh_dup(noisy, NULL);
    mcf_flow_params p;
    double best = rms(x, clean);
    int kbest = 0;
    assert_non_null(x);
    mcf_flow_params_init(&p);
    p.scheme = MCF_TAUBIN;
    p.laplacian = MCF_LAPLACIAN_UNIFORM;
    p.iterations = 1;
    for (int k = 1; k <= 500; k++) {
        assert_int_equal(mcf_flow_run(x, &p, NULL, NULL), MCF_OK);
        double e = rms(x, clean);
        if (e < best) {
            best = e;
            kbest = k;
        }
        if (k > 2 * kbest + 20 && e > 1.05 * best)
            break;
    }
    mcf_mesh_free(x);
    return best;
}

/* issue 31's `out`: Gaussian noise of 0.1 mean edges along the normals
 * (mcf_flow_add_noise: the vertices a run moves), then 1% of those
 * vertices moved 3-5 mean edges along their clean normal, random sign.
 * *nout gets their count. */
static mcf_mesh *with_outliers(const mcf_mesh *clean, int seed, int *nout)
{
    mcf_mesh *m = mcf_mesh_dup(clean, NULL);
    mcf_flow_params p;
    mcf_mesh_info info;
    int nv = mcf_mesh_nvertices(clean);
    double *X = malloc(3 * sizeof(double) * (size_t)nv), *N = malloc(3 * sizeof(double) * (size_t)nv);
    uint64_t r = 977u * (uint64_t)seed;
    assert_non_null(m);
    assert_non_null(X);
    assert_non_null(N);
    mcf_flow_params_init(&p);
    assert_int_equal(mcf_mesh_inspect(clean, &info, NULL), MCF_OK);
    assert_int_equal(mcf_flow_add_noise(m, &p, 0.1, (uint64_t)seed, NULL), MCF_OK);
    memcpy(X, mcf_mesh_positions(m), 3 * sizeof(double) * (size_t)nv);
    mcf__vertex_normals(mcf_mesh_positions(clean), mcf_mesh_faces(clean), mcf_mesh_nfaces(clean), nv, N);
    *nout = 0;
    for (int i = 0; i < nv; i++) {
        if (!memcmp(X + 3 * i, mcf_mesh_positions(clean) + 3 * (size_t)i, 3 * sizeof(double)) ||
            !(uniform01(&r) < 0.01))
            continue;
        double a = (3.0 + 2.0 * uniform01(&r)) * info.mean_edge * (uniform01(&r) < 0.5 ? -1.0 : 1.0);
        for (int e = 0; e < 3; e++)
            X[3 * i + e] += a * N[3 * i + e];
        (*nout)++;
    }
    mcf_mesh *out = mcf_mesh_new(nv, X, mcf_mesh_nfaces(clean), mcf_mesh_faces(clean), NULL);
    assert_non_null(out);
    free(X);
    free(N);
    mcf_mesh_free(m);
    return out;
}

/* The default request on the repository's meshes with outliers (seeds 1
 * and 2, 8 cases): the median of its error over the input's at most
 * OUT_BOUND, over the uniform Taubin oracle's at most OUT_TAUBIN_BOUND,
 * every case below OUT_WORST of the input's, and at least 85% of the
 * outliers counted in flow.spikes_repaired. Measured (2026-11-28):
 * error / input 0.068-0.516, median 0.26; / Taubin 0.20-0.94, median
 * 0.37; 140 of 150 outliers repaired (missed: clusters of neighbouring
 * outliers that hide each other, knot1 seed 1 three, and car.drc's,
 * a coarse CAD part whose local edges are 3-9 mean edges, where a 3-edge
 * outlier is barely one: car seed 1 0.516). Before the spike stage the
 * default returned these inputs unchanged (1.00). The bounds are issue
 * 31's (median 0.55 of the input's; 1.25x Open3D's best, the uniform
 * Taubin oracle here) with a margin for a change elsewhere; the runs
 * are deterministic. */
#define OUT_BOUND 0.40
#define OUT_TAUBIN_BOUND 0.8
#define OUT_WORST 0.6
static void test_outliers_end_to_end(void **state)
{
    static const char *const names[] = {"knot1.obj", "bunny_npm_closed.obj", "sphere_cgal.obj", "car.drc"};
    double rin[8], rtb[8];
    int nr = 0, nout_all = 0, nrep_all = 0;
    (void)state;
    for (int q = 0; q < 4; q++)
        tl_need_mesh(names[q]);
    for (int q = 0; q < 4; q++) {
        mcf_mesh *clean = tl_load(names[q]);
        for (int seed = 1; seed <= 2; seed++) {
            int nout;
            mcf_mesh *m = with_outliers(clean, seed, &nout);
            api_params ap;
            mcf_flow_stats st;
            mcf_error err = {0};
            double in = rms(m, clean), tb = taubin_oracle(m, clean);
            api_params_init(&ap);
            assert_int_equal(api_params_finish(&ap, mcf_mesh_nvertices(m), NULL, &err), MCF_OK);
            if (mcf_flow_run(m, &ap.flow, &st, &err) != MCF_OK)
                fail_msg("%s: %s", names[q], err.msg);
            double e = rms(m, clean);
            print_message("%-20s seed %d: %d outliers, %d repaired, K=%d, error/input %.3f, /Taubin %.3f\n",
                          names[q], seed, nout, st.spikes_repaired, st.steps, e / in, e / tb);
            assert_true(e <= OUT_WORST * in);
            rin[nr] = e / in;
            rtb[nr++] = e / tb;
            nout_all += nout;
            nrep_all += st.spikes_repaired;
            mcf_flow_stats_free(&st);
            api_params_free(&ap);
            mcf_mesh_free(m);
        }
        mcf_mesh_free(clean);
    }
    qsort(rin, (size_t)nr, sizeof *rin, cmp_double);
    qsort(rtb, (size_t)nr, sizeof *rtb, cmp_double);
    double min = 0.5 * (rin[nr / 2 - 1] + rin[nr / 2]), mtb = 0.5 * (rtb[nr / 2 - 1] + rtb[nr / 2]);
    print_message("median error / input %.3f, / Taubin %.3f; %d of %d outliers repaired\n", min, mtb, nrep_all,
                  nout_all);
    assert_true(min <= OUT_BOUND);
    assert_true(mtb <= OUT_TAUBIN_BOUND);
    assert_true(nrep_all >= (int)ceil(0.85 * nout_all));
}

/* A named scheme stays as it was: `fairing` named repairs nothing. */
static void test_named_untouched(void **state)
{
    (void)state;
    tl_need_mesh("knot1.obj");
    mcf_mesh *clean = tl_load("knot1.obj");
    int nout;
    mcf_mesh *m = with_outliers(clean, 1, &nout);
    api_params ap;
    mcf_flow_stats st;
    mcf_error err = {0};
    api_params_init(&ap);
    assert_int_equal(api_params_set(&ap, "scheme", "fairing", NULL, &err), MCF_OK);
    assert_int_equal(api_params_finish(&ap, mcf_mesh_nvertices(m), NULL, &err), MCF_OK);
    assert_int_equal(mcf_flow_run(m, &ap.flow, &st, &err), MCF_OK);
    assert_int_equal(st.spikes_repaired, 0);
    mcf_flow_stats_free(&st);
    api_params_free(&ap);
    mcf_mesh_free(m);
    mcf_mesh_free(clean);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_spikes_flat_grid),
        cmocka_unit_test(test_spikes_noisy_cylinder),
        cmocka_unit_test(test_spikes_none),
        cmocka_unit_test(test_outliers_end_to_end),
        cmocka_unit_test(test_named_untouched),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
