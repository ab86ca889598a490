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
 *  - one viewpoint's noise: mcf__noise_levels' reading against the
 *    injected noise and an independent eigensolver, and the default
 *    request against Taubin's oracles; clean meshes come back unchanged;
 *  - noise correlated over a few edges on a plated part (issue 31's
 *    `corr`): the plated share by hand and against numpy, the coarse
 *    reading against the injected level, blade.obj end to end.
 * Runs in about 9 s (with $MCF_MESHES; snowden.obj 1.5 s of it).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_fairing_ctx.h" /* mcf__fair_plated_share, mcf__fair_coarse_level */
#include "mcf_internal.h"    /* mcf__spikes, mcf__graph_build */
#include "testlib.h"

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

/* On a flat grid X0 (z = 0) with spikes at at[0..n): each spike of X is
 * back at z = 0 with its x and y kept, and no other vertex moved (bit for
 * bit). 1e-12: a centroid of six unit-grid points and one projection, a
 * few roundings of numbers of size 10. */
static void assert_flattened(const double *X, const double *X0, int nv, const int *at, int n)
{
    for (int i = 0; i < nv; i++) {
        int spike = 0;
        for (int s = 0; s < n; s++)
            spike |= at[s] == i;
        if (!spike) {
            assert_memory_equal(X + 3 * i, X0 + 3 * i, 3 * sizeof(double));
            continue;
        }
        tl_assert_near(X[3 * i], X0[3 * i], 1e-12, "a spike's x");
        tl_assert_near(X[3 * i + 1], X0[3 * i + 1], 1e-12, "a spike's y");
        tl_assert_near(X[3 * i + 2], 0.0, 1e-12, "a spike's height");
    }
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
    assert_flattened(X, X0, N * N, at, 5);
    mcf_mesh_free(m);
}

/* Faces of X (m's faces) whose normal has no positive z: on a flat grid
 * in the plane z = 0, every face of the clean grid faces +z. */
static int faces_not_up(const mcf_mesh *m, const double *X)
{
    int bad = 0;
    for (int f = 0; f < mcf_mesh_nfaces(m); f++) {
        const int32_t *t = mcf_mesh_faces(m) + 3 * f;
        double e1[3], e2[3], n[3];
        mcf__sub3(X + 3 * (size_t)t[1], X + 3 * (size_t)t[0], e1);
        mcf__sub3(X + 3 * (size_t)t[2], X + 3 * (size_t)t[0], e2);
        mcf__cross3(e1, e2, n);
        bad += !(n[2] > 0.0);
    }
    return bad;
}

/* A spike thrown off along a direction 35 degrees from the normal (x
 * 2.8, z 4 units on the 15 x 15 grid): moved back along the normal alone
 * it would land 2.8 units along the grid from its place, past its ring,
 * folding faces (the repair's first position: asserted below through
 * the same grid with a smaller tilt, which stays along the normal). A
 * repair that folds a face takes the ring's centroid instead: the
 * vertex's own grid point (its six neighbours (i +- 1, j), (i, j +- 1),
 * (i + 1, j + 1), (i - 1, j - 1) average to it), and no face of the
 * result faces down. */
static void test_spikes_fold_centroid(void **state)
{
    enum { N = 15, AT = 7 * N + 7 };
    (void)state;
    mcf_mesh *m = flat_grid(N);
    double X[3 * N * N], X0[3 * N * N];
    for (int tilt = 0; tilt < 2; tilt++) {
        double dx = tilt ? 2.8 : 0.3;
        memcpy(X0, mcf_mesh_positions(m), sizeof X0);
        X0[3 * AT] += dx;
        X0[3 * AT + 2] = 4.0;
        memcpy(X, X0, sizeof X);
        assert_int_equal(run_spikes(m, X, (2.0 + sqrt(2.0)) / 3.0, NULL), 1);
        /* 1e-12: sums of six grid coordinates below 15 and one projection */
        tl_assert_near(X[3 * AT], 7.0 + (tilt ? 0.0 : dx), 1e-12, "the spike's x");
        tl_assert_near(X[3 * AT + 1], 7.0, 1e-12, "the spike's y");
        tl_assert_near(X[3 * AT + 2], 0.0, 1e-12, "the spike's height");
        assert_int_equal(faces_not_up(m, X), 0);
        for (int i = 0; i < N * N; i++)
            if (i != AT)
                assert_memory_equal(X + 3 * i, X0 + 3 * i, 3 * sizeof(double));
    }
    mcf_mesh_free(m);
}

/* A needle lying in the surface (mcf_spikes.c, SPIKE_OFF; clean
 * snowden.obj has one on its base's rim): a vertex of the 15 x 15 grid
 * moved 3.0 units along the grid, past its ring (its faces fold), and
 * 0.3 up: its Laplacian is 3 units long, but it is 0.3 off its
 * neighbours' plane z = 0, below the threshold of one mean edge (1.14):
 * no spike, nothing moves (bit for bit). Before SPIKE_OFF the Laplacian's
 * length made it one, and SPIKE_CENTROID took it to its ring's centroid,
 * 3 units away. */
static void test_spikes_needle(void **state)
{
    enum { N = 15, AT = 7 * N + 7 };
    (void)state;
    mcf_mesh *m = flat_grid(N);
    double X[3 * N * N], X0[3 * N * N];
    memcpy(X0, mcf_mesh_positions(m), sizeof X0);
    X0[3 * AT] += 3.0;
    X0[3 * AT + 2] = 0.3;
    memcpy(X, X0, sizeof X);
    assert_int_equal(run_spikes(m, X, (2.0 + sqrt(2.0)) / 3.0, NULL), 0);
    assert_memory_equal(X, X0, sizeof X);
    mcf_mesh_free(m);
}

/* Two spikes side by side, both 4 units up on the 15 x 15 grid
 * (neighbours along x): each one's neighbours, but for the other spike,
 * are raised by the other's pull only (4/5 over their rings without it,
 * SPIKE_LOO) or not at all, so each is 10 times its neighbours' median;
 * over the rings with it, the pull of both (0.67 and 1.33 on a ring of
 * six) made the median 1.0 and the ratio 4.0, not above SPIKE_RING: the
 * pair hid each other in every pass (blade.obj's trailing edge, issue
 * 31's `out` at 0.1 h). Both come back to z = 0 exactly, x and y kept
 * (as in test_spikes_flat_grid), nothing else moves. */
static void test_spikes_pair(void **state)
{
    enum { N = 15, A = 7 * N + 7, B = 7 * N + 8 };
    (void)state;
    mcf_mesh *m = flat_grid(N);
    double X[3 * N * N], X0[3 * N * N];
    memcpy(X0, mcf_mesh_positions(m), sizeof X0);
    X0[3 * A + 2] = X0[3 * B + 2] = 4.0;
    memcpy(X, X0, sizeof X);
    assert_int_equal(run_spikes(m, X, (2.0 + sqrt(2.0)) / 3.0, NULL), 2);
    assert_flattened(X, X0, N * N, (const int[]){A, B}, 2);
    mcf_mesh_free(m);
}

/* A thin plate's rim, as blade.obj's trailing edge: a strip of 15 x 15
 * vertices folded around x = 6.4 (section k: x = k, z = 0.3 on the top
 * for k < 7; the rim x = 6.4, z = 0 at k = 7; x = 14 - k, z = -0.3
 * below), 2 units between sections along y (long thin triangles); the
 * strip's border fixed. A spike on the rim thrown 4 units along (1, 0, 1)
 * / sqrt 2, 45 degrees off the rim's normal (1, 0, 0) (on blade the
 * normals of the rim's vertices turn that much within a tenth of an
 * edge): moved along the ring's normal onto its plane it keeps its
 * 2.83 units up, off the plate (the repair before SPIKE_SURFACE); the
 * closest point of the faces around it (SPIKE_SURFACE) is within the
 * rim's faces' size of its clean place. Asserted: found, back within 0.5
 * units (the rim faces' diagonal in the section, sqrt(0.4^2 + 0.3^2)) of
 * its clean place, computed here from the construction; nothing else
 * moves. Measured (2026-11-29): 0.267; before SPIKE_SURFACE 2.841. */
static void test_spikes_rim(void **state)
{
    enum { N = 15, AT = 7 * N + 7 };
    (void)state;
    double C[3 * N * N], X[3 * N * N], X0[3 * N * N];
    unsigned char fixed[N * N];
    for (int j = 0; j < N; j++)
        for (int k = 0; k < N; k++) {
            double *p = C + 3 * (j * N + k);
            p[0] = k < 7 ? k : k == 7 ? 6.4 : 14 - k;
            p[1] = 2.0 * j;
            p[2] = k < 7 ? 0.3 : k == 7 ? 0.0 : -0.3;
            fixed[j * N + k] = j == 0 || k == 0 || j == N - 1 || k == N - 1;
        }
    mcf_mesh *grid = flat_grid(N);
    mcf_mesh *m = mcf_mesh_new(N * N, C, mcf_mesh_nfaces(grid), mcf_mesh_faces(grid), NULL);
    assert_non_null(m);
    memcpy(X0, C, sizeof X0);
    X0[3 * AT] += 4.0 / sqrt(2.0);
    X0[3 * AT + 2] += 4.0 / sqrt(2.0);
    memcpy(X, X0, sizeof X);
    assert_int_equal(run_spikes(m, X, mcf__mean_edge(X0, mcf_mesh_faces(m), mcf_mesh_nfaces(m)), fixed), 1);
    double d[3];
    mcf__sub3(X + 3 * AT, C + 3 * AT, d);
    print_message("rim spike: repaired %.3f units from its clean place\n", sqrt(mcf__dot3(d, d)));
    assert_true(sqrt(mcf__dot3(d, d)) < 0.5);
    for (int i = 0; i < N * N; i++)
        if (i != AT)
            assert_memory_equal(X + 3 * i, X0 + 3 * i, 3 * sizeof(double));
    mcf_mesh_free(m);
    mcf_mesh_free(grid);
}

/* mcf__flat_share against a count by hand: the 15 x 15 grid (every
 * vertex free) with one vertex raised 1e-3 units: that vertex's ring and
 * the rings of its six neighbours (which hold it) leave the plane, the
 * other 218 lie in it exactly: 218 / 225 at a tolerance of 1e-6 units;
 * at 1e-2 (above the raise) all 225. */
static void test_flat_share(void **state)
{
    enum { N = 15, AT = 7 * N + 7 };
    (void)state;
    mcf_mesh *m = flat_grid(N);
    double X[3 * N * N], Nrm[3 * N * N];
    unsigned char none[N * N] = {0};
    mcf__graph g;
    memcpy(X, mcf_mesh_positions(m), sizeof X);
    X[3 * AT + 2] = 1e-3;
    mcf__vertex_normals(X, mcf_mesh_faces(m), mcf_mesh_nfaces(m), N * N, Nrm);
    assert_int_equal(mcf__graph_build(mcf_mesh_faces(m), mcf_mesh_nfaces(m), N * N, &g, NULL), MCF_OK);
    assert_true(mcf__flat_share(&g, X, Nrm, none, 1e-6) == 218.0 / 225.0);
    assert_true(mcf__flat_share(&g, X, Nrm, none, 1e-2) == 1.0);
    mcf__graph_free(&g);
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
        double n[3] = {0.0, C[3 * i + 1] / r, (C[3 * i + 2] + r) / r}, a = 0.1 * h * tl_gauss01(&rng);
        if (inner && tl_uniform01(&rng) < 0.01) {
            a += (3.0 + 2.0 * tl_uniform01(&rng)) * h * (tl_uniform01(&rng) < 0.5 ? -1.0 : 1.0);
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

static int cmp_ll(const void *a, const void *b)
{
    long long x = *(const long long *)a, y = *(const long long *)b;
    return (x > y) - (x < y);
}

/* ------------------------------------------- one viewpoint's reading */

/* The vertex adjacency of F, built here independently of mcf_graph.c:
 * every face's three edges both ways, sorted, duplicates dropped; *ptr
 * (nv + 1) and *adj are malloc'd. */
static void adjacency(const int32_t *F, int nf, int nv, int **ptr, int **adj)
{
    long long *e = malloc(6 * sizeof(long long) * (size_t)nf);
    int *p = calloc((size_t)nv + 1, sizeof(int)), *a = malloc(6 * sizeof(int) * (size_t)nf);
    size_t ne = 0, k = 0;
    assert_non_null(e);
    assert_non_null(p);
    assert_non_null(a);
    for (int f = 0; f < nf; f++)
        for (int c = 0; c < 3; c++) {
            long long u = F[3 * f + c], v = F[3 * f + (c + 1) % 3];
            e[ne++] = u * nv + v;
            e[ne++] = v * nv + u;
        }
    qsort(e, ne, sizeof *e, cmp_ll);
    for (size_t q = 0; q < ne; q++)
        if (q == 0 || e[q] != e[q - 1]) {
            a[k++] = (int)(e[q] % nv);
            p[e[q] / nv + 1]++;
        }
    for (int i = 0; i < nv; i++)
        p[i + 1] += p[i];
    free(e);
    *ptr = p;
    *adj = a;
}

/* The eigenvalues of the symmetric 3 x 3 matrix A by cyclic Jacobi
 * rotations (Golub and Van Loan 8.5), into lam; A is overwritten. */
static void jacobi3(double A[3][3], double lam[3])
{
    for (int sweep = 0; sweep < 50; sweep++) {
        double off = A[0][1] * A[0][1] + A[0][2] * A[0][2] + A[1][2] * A[1][2];
        if (off <= 1e-30 * (A[0][0] * A[0][0] + A[1][1] * A[1][1] + A[2][2] * A[2][2]))
            break;
        for (int p = 0; p < 2; p++)
            for (int q = p + 1; q < 3; q++) {
                if (A[p][q] == 0.0)
                    continue;
                double th = (A[q][q] - A[p][p]) / (2.0 * A[p][q]);
                double t = (th >= 0 ? 1.0 : -1.0) / (fabs(th) + sqrt(th * th + 1.0));
                double c = 1.0 / sqrt(t * t + 1.0), s = t * c;
                for (int k = 0; k < 3; k++) { /* A <- A J */
                    double akp = A[k][p], akq = A[k][q];
                    A[k][p] = c * akp - s * akq;
                    A[k][q] = s * akp + c * akq;
                }
                for (int k = 0; k < 3; k++) { /* A <- J' A */
                    double apk = A[p][k], aqk = A[q][k];
                    A[p][k] = c * apk - s * aqk;
                    A[q][k] = s * apk + c * aqk;
                }
            }
    }
    for (int k = 0; k < 3; k++)
        lam[k] = A[k][k];
}

/* The direction statistic of mcf__noise_shape computed here from its
 * definition: E = (I - Avg)^2 X over the 1-rings (adjacency()), the
 * vertices of degree >= 3 whose |E_i| is at most 4 times the median of
 * those |E_i|, the largest eigenvalue (jacobi3) of the sum of their
 * E_i E_i' over its trace. */
static double share_reference(const double *X, const int32_t *F, int nf, int nv)
{
    int *ptr, *adj;
    adjacency(F, nf, nv, &ptr, &adj);
    double *A = malloc(3 * sizeof(double) * (size_t)nv), *E = malloc(3 * sizeof(double) * (size_t)nv);
    double *len = malloc(sizeof(double) * (size_t)nv), *srt = malloc(sizeof(double) * (size_t)nv);
    assert_non_null(A);
    assert_non_null(E);
    assert_non_null(len);
    assert_non_null(srt);
    for (int pass = 0; pass < 2; pass++) { /* A = (I - Avg) X, then E = (I - Avg) A */
        const double *in = pass ? A : X;
        double *out = pass ? E : A;
        for (int i = 0; i < nv; i++)
            for (int c = 0; c < 3; c++) {
                double s = 0.0;
                for (int t = ptr[i]; t < ptr[i + 1]; t++)
                    s += in[3 * (size_t)adj[t] + c];
                out[3 * (size_t)i + c] = in[3 * (size_t)i + c] - (ptr[i + 1] > ptr[i] ? s / (ptr[i + 1] - ptr[i]) : in[3 * (size_t)i + c]);
            }
    }
    int k = 0;
    for (int i = 0; i < nv; i++) {
        const double *v = E + 3 * (size_t)i;
        len[i] = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        if (ptr[i + 1] - ptr[i] >= 3)
            srt[k++] = len[i];
    }
    qsort(srt, (size_t)k, sizeof *srt, cmp_double);
    double med = k % 2 ? srt[k / 2] : 0.5 * (srt[k / 2 - 1] + srt[k / 2]), M[3][3] = {{0}}, lam[3];
    for (int i = 0; i < nv; i++)
        if (ptr[i + 1] - ptr[i] >= 3 && len[i] <= 4.0 * med)
            for (int a = 0; a < 3; a++)
                for (int b = 0; b < 3; b++)
                    M[a][b] += E[3 * (size_t)i + a] * E[3 * (size_t)i + b];
    double trace = M[0][0] + M[1][1] + M[2][2];
    jacobi3(M, lam);
    free(A);
    free(E);
    free(len);
    free(srt);
    free(ptr);
    free(adj);
    return fmax(lam[0], fmax(lam[1], lam[2])) / trace;
}

/* Area-weighted unit vertex normals of X, computed here (the sum of the
 * faces' cross products around each vertex). */
static void normals_reference(const double *X, const int32_t *F, int nf, int nv, double *N)
{
    memset(N, 0, 3 * sizeof(double) * (size_t)nv);
    for (int f = 0; f < nf; f++) {
        const double *a = X + 3 * (size_t)F[3 * f], *b = X + 3 * (size_t)F[3 * f + 1], *c = X + 3 * (size_t)F[3 * f + 2];
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
        for (int q = 0; q < 3; q++)
            for (int d = 0; d < 3; d++)
                N[3 * (size_t)F[3 * f + q] + d] += n[d];
    }
    for (int i = 0; i < nv; i++) {
        double *n = N + 3 * (size_t)i, l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        for (int d = 0; d < 3; d++)
            n[d] = l > 0.0 ? n[d] / l : 0.0;
    }
}

/* mcf__noise_levels' shape on one viewpoint's noise (issue 31's `view`:
 * x_i + rho h g_i u, one unit vector u per case) on the repository's
 * closed meshes at 0.25 and 0.5 h, against what is computed here: the
 * direction statistic equals share_reference's within VIEW_SHARE_TOL and
 * is above the default's switch (0.7) on this noise, below it on the clean
 * mesh and under Gaussian noise of 0.5 h along the normals; the RMS
 * reading is at least the switch's 1.15 times the median one (the scale
 * mixture s |u . n_i| g_i); the deviation along u reads rho h, its part
 * along the clean normals n_i (whose RMS over the vertices is rho h
 * sqrt(mean (u . n_i)^2)) and in the tangent planes (rho h sqrt(mean (1 -
 * (u . n_i)^2) / 2) per direction) their truths, within VIEW_TOL.
 * Measured 2026-11-28: the deviation along u 0.955-1.062 of rho h, the
 * part along the normals 0.958-1.059 of its truth, the RMS over the
 * median reading 1.23-1.33, the share 0.86-1.00 (0.33-0.40 clean or
 * under normal noise).
 * VIEW_TOL: the reading is a mean of squares over n = 812-3200 vertices,
 * relative standard error 1 / sqrt(2 n) = 1.3-2.5% for independent
 * values, about twice that for these (each high-pass value sums a
 * 2-ring, so neighbours' values correlate), plus the surface's own
 * high-pass along u on the coarse bunny (+6% there, the worst case): 0.12
 * is about 2.5 standard errors on the smallest mesh. VIEW_SHARE_TOL: the
 * core's statistic is the same sums in the same order; its eigenvalue
 * (closed form) differs from Jacobi's here only by rounding. */
#define VIEW_TOL 0.12
#define VIEW_SHARE_TOL 1e-9
static void test_view_reading(void **state)
{
    static const char *const names[] = {"sphere_cgal.obj", "bunny_npm_closed.obj", "knot1.obj"};
    static const double rhos[] = {0.25, 0.5};
    (void)state;
    for (int q = 0; q < 3; q++)
        tl_need_mesh(names[q]);
    for (int q = 0; q < 3; q++) {
        mcf_mesh *clean = tl_load(names[q]);
        mcf_mesh_info info;
        int nv = mcf_mesh_nvertices(clean), nf = mcf_mesh_nfaces(clean);
        const int32_t *F = mcf_mesh_faces(clean);
        const double *X0 = mcf_mesh_positions(clean);
        double *X = malloc(3 * sizeof(double) * (size_t)nv), *N = malloc(3 * sizeof(double) * (size_t)nv);
        assert_non_null(X);
        assert_non_null(N);
        assert_int_equal(mcf_mesh_inspect(clean, &info, NULL), MCF_OK);
        normals_reference(X0, F, nf, nv, N);
        for (int r = 0; r < 3; r++) { /* 0.25, 0.5: view; 2: clean, then normal 0.5 */
            for (int kind = 0; kind < (r < 2 ? 1 : 2); kind++) {
                uint64_t rng = 1000u * (uint64_t)q + 10u * (uint64_t)r + (uint64_t)kind + 1u;
                double rho = r < 2 ? rhos[r] : 0.5 * kind, u[3], ul = 0.0, un2 = 0.0, h = info.mean_edge;
                int counted = 0;
                for (int d = 0; d < 3; d++) {
                    u[d] = tl_gauss01(&rng);
                    ul += u[d] * u[d];
                }
                for (int d = 0; d < 3; d++)
                    u[d] /= sqrt(ul);
                memcpy(X, X0, 3 * sizeof(double) * (size_t)nv);
                for (int i = 0; i < nv; i++) {
                    double g = rho * info.mean_edge * tl_gauss01(&rng), un = u[0] * N[3 * i] + u[1] * N[3 * i + 1] + u[2] * N[3 * i + 2];
                    const double *dir = r < 2 ? u : N + 3 * (size_t)i;
                    for (int d = 0; d < 3; d++)
                        X[3 * (size_t)i + d] += g * dir[d];
                    un2 += un * un;
                    counted++;
                }
                double truth = rho * h * sqrt(un2 / counted), truth_t = rho * h * sqrt(0.5 * (1.0 - un2 / counted));
                double s_med = 0.0, s_t = 0.0;
                mcf__noise_shape shape = {0};
                mcf_error err = {0};
                assert_int_equal(mcf__noise_levels(NULL, X, F, nf, nv, NULL, &s_med, &s_t, &shape, NULL, &err), MCF_OK);
                double ref = share_reference(X, F, nf, nv);
                print_message("%-20s %s %.2f: share %.4f (reference %.4f), rms / median reading %.3f; along u %.3f "
                              "of rho h, normal part %.3f, tangential %.3f of the truth\n",
                              names[q], r < 2 ? "view" : kind ? "normal" : "clean", rho, shape.direction_share, ref,
                              shape.sigma_rms / s_med, rho > 0.0 ? shape.sigma_dir / (rho * h) : 0.0,
                              rho > 0.0 ? shape.sigma_view / truth : 0.0, rho > 0.0 ? shape.sigma_view_t / truth_t : 0.0);
                assert_true(fabs(shape.direction_share - ref) <= VIEW_SHARE_TOL);
                if (r < 2) {
                    assert_true(shape.direction_share >= 0.7);
                    assert_true(shape.sigma_rms >= 1.15 * s_med);
                    assert_true(fabs(shape.sigma_dir / (rho * h) - 1.0) <= VIEW_TOL);
                    assert_true(fabs(shape.sigma_view / truth - 1.0) <= VIEW_TOL);
                    assert_true(fabs(shape.sigma_view_t / truth_t - 1.0) <= VIEW_TOL);
                } else {
                    assert_true(shape.direction_share < 0.7);
                }
            }
        }
        free(X);
        free(N);
        mcf_mesh_free(clean);
    }
}

/* The uniform Taubin oracle (lambda 0.5, mu -0.53, Open3D's
 * filter_smooth_taubin): the best error over the pass counts, one pass at
 * a time, stopping 20 passes past the best once 5% worse. */
static double taubin_oracle_lap(const mcf_mesh *noisy, const mcf_mesh *clean, mcf_laplacian lap)
{
    mcf_mesh *x = mcf_mesh_dup(noisy, NULL);
    mcf_flow_params p;
    double best = rms(x, clean);
    int kbest = 0;
    assert_non_null(x);
    mcf_flow_params_init(&p);
    p.scheme = MCF_TAUBIN;
    p.laplacian = lap;
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

static double taubin_oracle(const mcf_mesh *noisy, const mcf_mesh *clean)
{
    return taubin_oracle_lap(noisy, clean, MCF_LAPLACIAN_UNIFORM);
}

/* issue 31's `out`: Gaussian noise of 0.1 mean edges along the normals
 * (mcf_flow_add_noise: the vertices a run moves), then 1% of those
 * vertices moved 3-5 mean edges along their clean normal, random sign.
 * *nout gets their count. */
static mcf_mesh *with_outliers_rho(const mcf_mesh *clean, double rho, int seed, int *nout)
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
    assert_int_equal(mcf_flow_add_noise(m, &p, rho, (uint64_t)seed, NULL), MCF_OK);
    memcpy(X, mcf_mesh_positions(m), 3 * sizeof(double) * (size_t)nv);
    mcf__vertex_normals(mcf_mesh_positions(clean), mcf_mesh_faces(clean), mcf_mesh_nfaces(clean), nv, N);
    *nout = 0;
    for (int i = 0; i < nv; i++) {
        if (!memcmp(X + 3 * i, mcf_mesh_positions(clean) + 3 * (size_t)i, 3 * sizeof(double)) ||
            !(tl_uniform01(&r) < 0.01))
            continue;
        double a = (3.0 + 2.0 * tl_uniform01(&r)) * info.mean_edge * (tl_uniform01(&r) < 0.5 ? -1.0 : 1.0);
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

static void run_default(mcf_mesh *m, mcf_flow_stats *st);

static mcf_mesh *with_outliers(const mcf_mesh *clean, int seed, int *nout)
{
    return with_outliers_rho(clean, 0.1, seed, nout);
}

/* The `folds` warning with outliers tells the truth: before, the spike
 * stage's repair (along the ring's normal) folded faces that the fold
 * guard, comparing with the repaired mesh, did not see, while
 * flow.folded_faces counts against the request's input: the warning with
 * faces folded by the run (couplingdown_sub2.obj at `out` 0.25 h: 110,
 * 105 of them facing against the clean mesh; fertility.obj 8; here
 * bunny_npm_closed.obj seed 1: 1). Now the repair takes the centroid where
 * that leaves fewer faces backwards, and the guard judges against the
 * request's input too. On the repository's organic meshes at `out`
 * 0.25 h (seeds 1-2): no `folds` warning, flow.folded_faces at most
 * FOLDS_LEFT (what the spike repair itself folds, which the guard cannot
 * take back: measured 0), and no more faces against the clean mesh than
 * the input had (measured 0-4 -> 0-2). car.drc is left out: a coarse CAD
 * part with long thin triangles, where seed 1 still counts 3 folded faces
 * (the warning; 449 -> 444 faces against the clean mesh). About 1 s. */
#define FOLDS_LEFT 1
static void test_outliers_folds(void **state)
{
    static const char *const names[] = {"knot1.obj", "bunny_npm_closed.obj", "sphere_cgal.obj"};
    (void)state;
    for (int q = 0; q < 3; q++)
        tl_need_mesh(names[q]);
    for (int q = 0; q < 3; q++) {
        mcf_mesh *clean = tl_load(names[q]);
        for (int seed = 1; seed <= 2; seed++) {
            int nout;
            mcf_mesh *m = with_outliers_rho(clean, 0.25, seed, &nout);
            mcf_flow_stats st;
            int f0 = tl_flips_against(m, clean);
            double in = rms(m, clean);
            run_default(m, &st);
            int f1 = tl_flips_against(m, clean);
            print_message("%-20s seed %d: out 0.25: folded_faces %d (warning %d), faces against the clean mesh %d -> "
                          "%d, error/input %.3f\n",
                          names[q], seed, st.folded_faces, !!(st.warnings & MCF_WARN_FOLDS), f0, f1, rms(m, clean) / in);
            assert_false(st.warnings & MCF_WARN_FOLDS);
            assert_true(st.folded_faces <= FOLDS_LEFT);
            assert_true(f1 <= f0);
            mcf_flow_stats_free(&st);
            mcf_mesh_free(m);
        }
        mcf_mesh_free(clean);
    }
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

/* issue 31's `view` on a repository mesh: Gaussian noise of rho mean
 * edges along one unit vector *u drawn from the seed, on the vertices a
 * run moves (mcf_flow_add_noise's: those it changes). */
static mcf_mesh *with_view_noise(const mcf_mesh *clean, double rho, int seed, double u[3])
{
    mcf_mesh *m = mcf_mesh_dup(clean, NULL);
    mcf_flow_params p;
    mcf_mesh_info info;
    int nv = mcf_mesh_nvertices(clean);
    double *X = malloc(3 * sizeof(double) * (size_t)nv), l = 0.0;
    uint64_t r = 7919u * (uint64_t)seed;
    assert_non_null(m);
    assert_non_null(X);
    mcf_flow_params_init(&p);
    assert_int_equal(mcf_mesh_inspect(clean, &info, NULL), MCF_OK);
    assert_int_equal(mcf_flow_add_noise(m, &p, 0.1, (uint64_t)seed, NULL), MCF_OK); /* which move */
    for (int d = 0; d < 3; d++) {
        u[d] = tl_gauss01(&r);
        l += u[d] * u[d];
    }
    for (int d = 0; d < 3; d++)
        u[d] /= sqrt(l);
    memcpy(X, mcf_mesh_positions(clean), 3 * sizeof(double) * (size_t)nv);
    for (int i = 0; i < nv; i++) {
        double g = rho * info.mean_edge * tl_gauss01(&r);
        if (memcmp(mcf_mesh_positions(m) + 3 * (size_t)i, X + 3 * (size_t)i, 3 * sizeof(double)))
            for (int d = 0; d < 3; d++)
                X[3 * (size_t)i + d] += g * u[d];
    }
    mcf_mesh *out = mcf_mesh_new(nv, X, mcf_mesh_nfaces(clean), mcf_mesh_faces(clean), NULL);
    assert_non_null(out);
    free(X);
    mcf_mesh_free(m);
    return out;
}

/* The default request through api_params (nothing set) on m in place. */
static void run_default(mcf_mesh *m, mcf_flow_stats *st)
{
    api_params ap;
    mcf_error err = {0};
    api_params_init(&ap);
    assert_int_equal(api_params_finish(&ap, mcf_mesh_nvertices(m), NULL, &err), MCF_OK);
    if (mcf_flow_run(m, &ap.flow, st, &err) != MCF_OK)
        fail_msg("%s", err.msg);
    api_params_free(&ap);
}

/* One viewpoint's noise end to end (issue 31: "one viewpoint median <=
 * 1.0x Taubin's oracle", make quality's taubin_best: the product's Taubin,
 * cotan weights, at its best pass count): sphere_cgal, bunny_npm_closed
 * and knot1 at 0.25 and 0.5 mean edges, seed 1. The default's error over
 * that oracle's at most VIEW_COTAN_WORST in every case and
 * VIEW_COTAN_MEDIAN for the median; over the uniform Taubin oracle
 * (Open3D's weights, which move vertices along the surface too and so
 * take more of this noise's tangential part) a median at most
 * VIEW_UNIFORM_MEDIAN; the metrics say one_direction and the direction
 * read is the injected one within VIEW_DIR_COS. Measured (2026-11-28):
 * error / cotan Taubin 0.29-0.78, median 0.57; / uniform Taubin
 * 0.73-1.04, median 0.97; |u . read| >= 0.9999. Before (the median
 * reading along the normals) make quality had 1.06-1.18 against the
 * cotan oracle on these meshes. The bounds: issue 31's 1.0 for the
 * median less 0.2, 0.9 for each case; the uniform oracle's median the
 * measured 0.97 plus 0.13; the runs are deterministic. About 2 s. */
#define VIEW_COTAN_WORST 0.9
#define VIEW_COTAN_MEDIAN 0.8
#define VIEW_UNIFORM_MEDIAN 1.1
#define VIEW_DIR_COS 0.99
static void test_view_end_to_end(void **state)
{
    static const char *const names[] = {"sphere_cgal.obj", "bunny_npm_closed.obj", "knot1.obj"};
    static const double rhos[] = {0.25, 0.5};
    double rtb[6], rtc[6];
    int nr = 0;
    (void)state;
    for (int q = 0; q < 3; q++)
        tl_need_mesh(names[q]);
    for (int q = 0; q < 3; q++) {
        mcf_mesh *clean = tl_load(names[q]);
        for (int r = 0; r < 2; r++) {
            double u[3];
            mcf_mesh *m = with_view_noise(clean, rhos[r], 1, u);
            mcf_flow_stats st;
            double in = rms(m, clean), tb = taubin_oracle(m, clean), tc = taubin_oracle_lap(m, clean, MCF_LAPLACIAN_COTAN);
            run_default(m, &st);
            double e = rms(m, clean), c = fabs(mcf__dot3(u, st.noise_direction));
            print_message("%-20s view %.2f: noise %.3f (kind %d), direction . u %.4f, K=%d, error/input %.3f, "
                          "/Taubin %.3f, /cotan Taubin %.3f\n",
                          names[q], rhos[r], st.noise, st.noise_kind, c, st.steps, e / in, e / tb, e / tc);
            assert_int_equal(st.noise_kind, MCF_NOISE_ONE_DIRECTION);
            assert_true(c >= VIEW_DIR_COS);
            assert_true(e <= VIEW_COTAN_WORST * tc);
            rtc[nr] = e / tc;
            rtb[nr++] = e / tb;
            mcf_flow_stats_free(&st);
            mcf_mesh_free(m);
        }
        mcf_mesh_free(clean);
    }
    qsort(rtb, (size_t)nr, sizeof *rtb, cmp_double);
    qsort(rtc, (size_t)nr, sizeof *rtc, cmp_double);
    double med = 0.5 * (rtb[nr / 2 - 1] + rtb[nr / 2]), medc = 0.5 * (rtc[nr / 2 - 1] + rtc[nr / 2]);
    print_message("median error / cotan Taubin %.3f, / uniform Taubin %.3f\n", medc, med);
    assert_true(medc <= VIEW_COTAN_MEDIAN);
    assert_true(med <= VIEW_UNIFORM_MEDIAN);
}

/* One viewpoint's noise on a thin part: blade.obj (8,231 vertices, a
 * turbine blade 0.65 thick under 10:1 triangles, its normals +-z but at
 * its rims) at 0.1, 0.25 and 0.5 mean edges, seed 4 (u = (-0.09, 0.95,
 * -0.28), mostly along the plate: seeds 1-3 draw |u_z| of 0.70-0.91,
 * whose noise is mostly along the normals there). The normal part's
 * deviation is the same nearly everywhere, so the RMS reading equals the
 * median one and only the direction's reading against the normal one
 * tells the noise (mcf_fairing.c VIEW_DIR); with it the feature stage
 * stays out (it moves along the normals only). Asserted: the metrics say
 * one_direction, the direction read is the injected one within
 * VIEW_DIR_COS, and the error against the clean mesh (mcf_compare) is
 * at most VIEW_COTAN_WORST of the cotan Taubin oracle's (chosen knowing
 * the clean mesh) in each case. Measured (2026-11-29): 0.136, 0.126,
 * 0.126 of the input's error, 0.141, 0.131, 0.132 of the oracle's;
 * before, read as noise along the normals: 0.960 of the input's error at
 * 0.1 h (0.992 of the oracle's; the test failed there). About 4 s. */
static void test_view_thin_plate(void **state)
{
    static const double rhos[] = {0.1, 0.25, 0.5};
    (void)state;
    tl_need_mesh("blade.obj");
    mcf_mesh *clean = tl_load("blade.obj");
    for (int r = 0; r < 3; r++) {
        double u[3];
        mcf_mesh *m = with_view_noise(clean, rhos[r], 4, u);
        mcf_flow_stats st;
        double in = rms(m, clean), tc = taubin_oracle_lap(m, clean, MCF_LAPLACIAN_COTAN);
        run_default(m, &st);
        double e = rms(m, clean), c = fabs(mcf__dot3(u, st.noise_direction));
        print_message("blade.obj view %.2f u (%.2f %.2f %.2f): noise %.3f (kind %d), direction . u %.4f, filter %d, error/input %.3f, "
                      "/cotan Taubin %.3f\n",
                      rhos[r], u[0], u[1], u[2], st.noise, st.noise_kind, c, st.filter, e / in, e / tc);
        assert_int_equal(st.noise_kind, MCF_NOISE_ONE_DIRECTION);
        assert_true(c >= VIEW_DIR_COS);
        assert_true(e <= VIEW_COTAN_WORST * tc);
        mcf_flow_stats_free(&st);
        mcf_mesh_free(m);
    }
    mcf_mesh_free(clean);
}

/* ------------------------------- correlated noise on plated parts */

/* The plated share (mcf__fair_plated_share) by hand on the 60 x 60 flat
 * grid (index j * 60 + i, column i) with normals set here: columns 0-29
 * face +z, column i >= 30 is turned about y by (i - 29) STEP degrees.
 * STEP 10: the first seed (vertex 0) grows over columns 0-29 (1,800
 * vertices) and stops at column 30 (10 degrees off); every later column
 * is a region of its own, 60 vertices, under 2% of 3,600 (72): share
 * 1,800 / 3,600. STEP 7: column 30 (7 degrees) joins the first region,
 * then columns pair up (31 with 32: 14 and 21 degrees, 7 apart; 33, at
 * 28, is 14 off 31), every pair 120 >= 72 vertices, and column 59 is
 * left alone (60): share 3,540 / 3,600. With column
 * 0 fixed (STEP 10): 1,740 of 3,540 free, a column's 60 under 2% (70.8). */
static void test_plated_share(void **state)
{
    enum { N = 60 };
    (void)state;
    mcf_mesh *m = flat_grid(N);
    mcf__graph g;
    double *Nrm = malloc(3 * sizeof(double) * N * N);
    int *lab = malloc(sizeof(int) * N * N), *stack = malloc(sizeof(int) * N * N);
    unsigned char col0[N * N] = {0};
    assert_non_null(Nrm);
    assert_non_null(lab);
    assert_non_null(stack);
    assert_int_equal(mcf__graph_build(mcf_mesh_faces(m), mcf_mesh_nfaces(m), N * N, &g, NULL), MCF_OK);
    for (int step = 7; step <= 10; step += 3) {
        for (int i = 0; i < N * N; i++) {
            double a = i % N >= 30 ? (i % N - 29) * step * MCF_PI / 180.0 : 0.0;
            Nrm[3 * i] = sin(a);
            Nrm[3 * i + 1] = 0.0;
            Nrm[3 * i + 2] = cos(a);
            col0[i] = i % N == 0;
        }
        assert_true(mcf__fair_plated_share(&g, Nrm, NULL, lab, stack) == (step == 10 ? 0.5 : 3540.0 / 3600.0));
        if (step == 10)
            assert_true(mcf__fair_plated_share(&g, Nrm, col0, lab, stack) == 1740.0 / 3540.0);
    }
    mcf__graph_free(&g);
    free(Nrm);
    free(lab);
    free(stack);
    mcf_mesh_free(m);
}

/* The vertices on a boundary edge (used by one face) or with no edge,
 * found here from the faces' sorted edge keys: the fixed set of a default
 * run (boundary fixed) and of plated.py. */
static unsigned char *boundary_reference(const int32_t *F, int nf, int nv)
{
    long long *key = malloc(sizeof(long long) * 3 * (size_t)nf);
    unsigned char *fixed = malloc((size_t)nv), *used = calloc((size_t)nv, 1);
    assert_non_null(key);
    assert_non_null(fixed);
    assert_non_null(used);
    for (int f = 0; f < nf; f++)
        for (int k = 0; k < 3; k++) {
            long long a = F[3 * f + k], b = F[3 * f + (k + 1) % 3];
            key[3 * f + k] = a < b ? a * nv + b : b * nv + a;
            used[a] = 1;
        }
    qsort(key, 3 * (size_t)nf, sizeof *key, cmp_ll);
    for (int i = 0; i < nv; i++)
        fixed[i] = !used[i];
    for (size_t q = 0; q < 3 * (size_t)nf;) {
        size_t r = q;
        while (r < 3 * (size_t)nf && key[r] == key[q])
            r++;
        if (r - q == 1)
            fixed[key[q] / nv] = fixed[key[q] % nv] = 1;
        q = r;
    }
    free(key);
    free(used);
    return fixed;
}

/* issue 31's `corr` along the clean normals N on the free vertices: unit
 * draws (tl_gauss01, seed) smoothed by 9 closed 1-ring averages over the
 * adjacency (ptr, adj), rescaled to unit RMS over the free vertices, times
 * rho h; white (no smoothing) when passes is 0. Into X (clean in). */
static void add_corr_noise(double *X, const double *N, const int *ptr, const int *adj, const unsigned char *fixed,
                           int nv, double rho_h, int passes, uint64_t seed)
{
    double *z = malloc(sizeof(double) * (size_t)nv), *t = malloc(sizeof(double) * (size_t)nv), ss = 0.0;
    int m = 0;
    assert_non_null(z);
    assert_non_null(t);
    for (int i = 0; i < nv; i++)
        z[i] = tl_gauss01(&seed);
    for (int p = 0; p < passes; p++) {
        for (int i = 0; i < nv; i++) {
            double a = z[i];
            for (int k = ptr[i]; k < ptr[i + 1]; k++)
                a += z[adj[k]];
            t[i] = a / (1 + ptr[i + 1] - ptr[i]);
        }
        memcpy(z, t, sizeof(double) * (size_t)nv);
    }
    for (int i = 0; i < nv; i++)
        if (!fixed[i]) {
            ss += z[i] * z[i];
            m++;
        }
    for (int i = 0; i < nv; i++)
        for (int d = 0; d < 3; d++)
            X[3 * (size_t)i + d] += fixed[i] ? 0.0 : rho_h * z[i] / sqrt(ss / m) * N[3 * (size_t)i + d];
    free(z);
    free(t);
}

/* A clean shared mesh with what a `corr` draw on it needs: its free
 * vertices (boundary_reference), neighbours, vertex normals, mean edge h,
 * and X, a copy of its positions to draw into (corr_draw). */
typedef struct {
    mcf_mesh *clean;
    int nv, nf, *ptr, *adj;
    const int32_t *F;
    double *X, *N, h;
    unsigned char *fixed;
} corr_fixture;

static void corr_fixture_load(corr_fixture *f, const char *name)
{
    mcf_mesh_info info;
    f->clean = tl_load(name);
    f->nv = mcf_mesh_nvertices(f->clean);
    f->nf = mcf_mesh_nfaces(f->clean);
    f->F = mcf_mesh_faces(f->clean);
    f->X = malloc(3 * sizeof(double) * (size_t)f->nv);
    f->N = malloc(3 * sizeof(double) * (size_t)f->nv);
    assert_non_null(f->X);
    assert_non_null(f->N);
    f->fixed = boundary_reference(f->F, f->nf, f->nv);
    assert_int_equal(mcf_mesh_inspect(f->clean, &info, NULL), MCF_OK);
    f->h = info.mean_edge;
    adjacency(f->F, f->nf, f->nv, &f->ptr, &f->adj);
    normals_reference(mcf_mesh_positions(f->clean), f->F, f->nf, f->nv, f->N);
}

/* X = the clean positions plus add_corr_noise's draw (sigma, passes, seed);
 * sigma 0: the clean positions. */
static void corr_draw(corr_fixture *f, double sigma, int passes, uint64_t seed)
{
    memcpy(f->X, mcf_mesh_positions(f->clean), 3 * sizeof(double) * (size_t)f->nv);
    if (sigma > 0.0)
        add_corr_noise(f->X, f->N, f->ptr, f->adj, f->fixed, f->nv, sigma, passes, seed);
}

static void corr_fixture_free(corr_fixture *f)
{
    free(f->ptr);
    free(f->adj);
    free(f->fixed);
    free(f->X);
    free(f->N);
    mcf_mesh_free(f->clean);
}

/* mcf__fair_coarse_level on blade.obj (a plated part) and spot.obj (an
 * organic one), clean and with noise of 0.1 h drawn here: the plated share
 * against numpy (lab/results/quality/issue31-corr/plated.py, an
 * independent implementation: 7,316 of 7,991 free vertices on the clean
 * blade, 0 of 2,930 on spot, exactly: the same regions whatever the
 * order of a region's growth); on blade under `corr` noise the level
 * within CORR_LEVEL_TOL of the injected 0.1 h (measured 2026-11-29: seeds
 * 1-3 0.95-1.05 of it: the median's and the calibration's draws); under
 * white noise of 0.1 h along the normals (which the fine reading sees and
 * which is taken out) and on the clean blade at most CORR_LEVEL_WHITE h
 * (measured 0.00-0.03); on spot none, the share 0 whatever the noise. */
#define CORR_LEVEL_TOL 0.1
#define CORR_LEVEL_WHITE 0.04
static void test_coarse_level(void **state)
{
    static const char *const names[] = {"blade.obj", "spot.obj"};
    (void)state;
    for (int q = 0; q < 2; q++)
        tl_need_mesh(names[q]);
    for (int q = 0; q < 2; q++) {
        corr_fixture f;
        mcf__graph g;
        corr_fixture_load(&f, names[q]);
        assert_int_equal(mcf__graph_build(f.F, f.nf, f.nv, &g, NULL), MCF_OK);
        const int32_t *F = f.F;
        int nv = f.nv, nf = f.nf;
        double *X = f.X, h = f.h;
        const unsigned char *fixed = f.fixed;
        for (int kind = 0; kind < 5; kind++) { /* clean, corr seeds 1-3, white */
            double plated = -1.0, level = -1.0, s_white = 0.0;
            mcf_error err = {0};
            corr_draw(&f, kind > 0 ? 0.1 * h : 0.0, kind < 4 ? 9 : 0, (uint64_t)(kind < 4 ? kind : 1));
            assert_int_equal(mcf__noise_levels(&g, X, F, nf, nv, fixed, &s_white, NULL, NULL, NULL, &err), MCF_OK);
            assert_int_equal(mcf__fair_coarse_level(&g, X, F, nf, nv, fixed, s_white, &plated, &level, &err), MCF_OK);
            print_message("%-10s %s: plated %.6f, fine reading %.4f h, coarse level %.4f h\n", names[q],
                          kind == 0 ? "clean" : kind < 4 ? "corr 0.1" : "white 0.1", plated, s_white / h, level / h);
            if (q == 1) {
                assert_true(plated == 0.0);
                assert_true(level == 0.0);
                continue;
            }
            if (kind == 0)
                assert_true(plated == 7316.0 / 7991.0);
            assert_true(plated >= 0.5);
            if (kind > 0 && kind < 4)
                tl_assert_near(level / h, 0.1, 0.1 * CORR_LEVEL_TOL, "the correlated noise's level");
            else
                assert_true(level <= CORR_LEVEL_WHITE * h);
        }
        mcf__graph_free(&g);
        corr_fixture_free(&f);
    }
}

/* End to end: the default request on blade.obj with `corr` noise of 0.1 h
 * (seed 1, drawn here) reads the level CORR_LEVEL_TOL near the truth (the
 * metrics say `correlated`, nothing in the tangent planes) and comes back with at most CORR_BLADE_ERROR of the input's error (make
 * quality's case, with its own draws: 0.882 measured, the BNF oracle 0.700,
 * issue 31's worst 1.4 of it 0.98; before: 1.000, the input); told 0.1
 * the default reaches 0.885 (lab/results/quality/issue31-cad-quant3). */
#define CORR_BLADE_ERROR 0.95
static void test_corr_blade(void **state)
{
    (void)state;
    tl_need_mesh("blade.obj");
    corr_fixture f;
    mcf_flow_stats st;
    corr_fixture_load(&f, "blade.obj");
    corr_draw(&f, 0.1 * f.h, 9, 1);
    mcf_mesh *m = mcf_mesh_new(f.nv, f.X, f.nf, f.F, NULL);
    assert_non_null(m);
    double in = rms(m, f.clean);
    run_default(m, &st);
    double e = rms(m, f.clean);
    print_message("blade.obj corr 0.1: noise read %.4f, K=%d, filter %d, error/input %.4f\n", st.noise, st.steps,
                  st.filter, e / in);
    tl_assert_near(st.noise, 0.1, 0.1 * CORR_LEVEL_TOL, "the level read");
    assert_int_equal(st.noise_kind, MCF_NOISE_CORRELATED);
    assert_true(st.noise_tangential == 0.0);
    assert_true(e <= CORR_BLADE_ERROR * in);
    mcf_flow_stats_free(&st);
    mcf_mesh_free(m);
    corr_fixture_free(&f);
}

/* No harm (issue 31: "a clean mesh moved <= 0.1x the error of 0.1 h
 * noise"): the default request on the repository's clean meshes moves
 * them by at most CLEAN_BOUND times the error Gaussian noise of 0.1 mean
 * edges along the normals would be (mcf_flow_add_noise, seed 1), and says
 * it read no noise where the surface's high-pass is not white (WHITE_GAP).
 * Measured (2026-11-28): sphere_cgal, bunny_npm_closed, knot1 and car
 * 0 (to 1e-14); bunny_npm_closed moved 0.23 before the test that there is
 * noise at all. CLEAN_BOUND: issue 31's 0.1 halved, a margin for a change
 * elsewhere. */
#define CLEAN_BOUND 0.05
/* Exact positions (mcf_fairing.c, FLAT_SHARE): car.drc quantized to a
 * grid of 0.5 mean edges (70% of its free vertices then have their ring
 * exactly in their plane) and turned about an oblique axis, so that its
 * coordinates sit on no grid along the axes (a grid is read as noise of
 * its own: test_core_lattice.c) while its flat rings stay flat (1e-6 h:
 * a rotation's roundings are 1e-16 of the coordinates), comes back as it
 * came, bit for bit, with no noise read and no spike repaired; with
 * Gaussian noise of 0.1 h along the normals no ring is flat and the
 * noise is read (0.10 h measured). */
static void test_exact_positions(void **state)
{
    (void)state;
    tl_need_mesh("car.drc");
    mcf_mesh *clean = tl_load("car.drc"), *q = mcf_mesh_dup(clean, NULL), *n = mcf_mesh_dup(clean, NULL);
    mcf_mesh_info info;
    mcf_flow_params p;
    mcf_flow_stats st;
    assert_non_null(q);
    assert_non_null(n);
    assert_int_equal(mcf_mesh_inspect(clean, &info, NULL), MCF_OK);
    int nv = mcf_mesh_nvertices(clean);
    double step = 0.5 * info.mean_edge, *X = mcf_mesh_positions_mut(q);
    for (int i = 0; i < 3 * nv; i++)
        X[i] = step * floor(X[i] / step + 0.5);
    /* the rotation by 0.7 rad about (1, 2, 2) / 3 (Rodrigues) */
    const double u[3] = {1.0 / 3.0, 2.0 / 3.0, 2.0 / 3.0}, c = cos(0.7), sn = sin(0.7);
    for (int i = 0; i < nv; i++) {
        double x[3], ux[3], ud;
        memcpy(x, X + 3 * i, sizeof x);
        mcf__cross3(u, x, ux);
        ud = mcf__dot3(u, x);
        for (int d = 0; d < 3; d++)
            X[3 * i + d] = x[d] * c + ux[d] * sn + u[d] * ud * (1.0 - c);
    }
    mcf_mesh *q0 = mcf_mesh_dup(q, NULL);
    assert_non_null(q0);
    run_default(q, &st);
    print_message("car.drc quantized 0.5 h: noise read %.4f, spikes %d, K=%d\n", st.noise, st.spikes_repaired, st.steps);
    assert_memory_equal(mcf_mesh_positions(q), mcf_mesh_positions(q0), 3 * sizeof(double) * (size_t)nv);
    assert_true(st.noise == 0.0);
    assert_int_equal(st.spikes_repaired, 0);
    mcf_flow_stats_free(&st);
    mcf_flow_params_init(&p);
    assert_int_equal(mcf_flow_add_noise(n, &p, 0.1, 1, NULL), MCF_OK);
    run_default(n, &st);
    print_message("car.drc normal 0.1 h: noise read %.4f\n", st.noise);
    assert_true(st.noise > 0.05);
    mcf_flow_stats_free(&st);
    mcf_mesh_free(q);
    mcf_mesh_free(q0);
    mcf_mesh_free(n);
    mcf_mesh_free(clean);
}

/* The default request on clean mesh NAME: how far it moves it, over the
 * error of Gaussian noise of 0.1 h along the normals (seed 1); its
 * statistics into st (the caller frees them). */
static double clean_moved(const char *name, mcf_flow_stats *st)
{
    mcf_mesh *clean = tl_load(name), *m = mcf_mesh_dup(clean, NULL), *n = mcf_mesh_dup(clean, NULL);
    mcf_flow_params p;
    assert_non_null(m);
    assert_non_null(n);
    mcf_flow_params_init(&p);
    assert_int_equal(mcf_flow_add_noise(n, &p, 0.1, 1, NULL), MCF_OK);
    run_default(m, st);
    double moved = rms(m, clean) / rms(n, clean);
    print_message("%-20s clean: noise read %.4f, K=%d, spikes %d, moved %.3g of the error of 0.1 h noise\n", name,
                  st->noise, st->steps, st->spikes_repaired, moved);
    mcf_mesh_free(m);
    mcf_mesh_free(n);
    mcf_mesh_free(clean);
    return moved;
}

static void test_clean_untouched(void **state)
{
    static const char *const names[] = {"sphere_cgal.obj", "bunny_npm_closed.obj", "knot1.obj", "car.drc"};
    (void)state;
    for (int q = 0; q < 4; q++)
        tl_need_mesh(names[q]);
    for (int q = 0; q < 4; q++) {
        mcf_flow_stats st;
        assert_true(clean_moved(names[q], &st) <= CLEAN_BOUND);
        mcf_flow_stats_free(&st);
    }
}

/* A clean scan with a needle (mcf_spikes.c, SPIKE_OFF): snowden.obj (in
 * $MCF_MESHES; skipped by name without it) has the tip of a needle of
 * five thin faces on its base's rim, 5.3 mean edges from its ring's
 * centroid and 0.38 off their plane. The default request repairs no
 * spike there and moves the scan by at most CLEAN_BOUND of the error of
 * 0.1 h noise. Measured (2026-11-28): 0 spikes, moved 0 (the filter reads
 * no noise); before SPIKE_OFF the needle took its ring's centroid: 1
 * spike, moved 0.375 (make quality's noise and this test's alike). About
 * 1.5 s. */
static void test_clean_needle(void **state)
{
    mcf_flow_stats st;
    (void)state;
    tl_need_mesh("snowden.obj");
    double moved = clean_moved("snowden.obj", &st);
    assert_int_equal(st.spikes_repaired, 0);
    assert_true(moved <= CLEAN_BOUND);
    mcf_flow_stats_free(&st);
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

/* A sphere of irregular triangles: the icosphere of level 4 (2,562
 * vertices, radius 1) with every vertex moved in its tangent plane by
 * Gaussian noise of JITTER mean edges per direction and put back on the
 * sphere (seed 17), so its triangles read the tangential irregularity b of
 * a marching-cubes scan (0.15-0.2 mean edges, docs/fairing.md). */
#define JITTER 0.2
static mcf_mesh *jittered_sphere(void)
{
    mcf_mesh *ico = mcf_mesh_new_icosphere(4, 1.0, NULL);
    mcf_mesh_info info;
    assert_non_null(ico);
    assert_int_equal(mcf_mesh_inspect(ico, &info, NULL), MCF_OK);
    int nv = mcf_mesh_nvertices(ico);
    double *X = malloc(3 * sizeof(double) * (size_t)nv);
    uint64_t r = 17;
    assert_non_null(X);
    memcpy(X, mcf_mesh_positions(ico), 3 * sizeof(double) * (size_t)nv);
    for (int i = 0; i < nv; i++) {
        double *x = X + 3 * (size_t)i, g[3], a, l;
        for (int d = 0; d < 3; d++)
            g[d] = JITTER * info.mean_edge * tl_gauss01(&r);
        a = mcf__dot3(g, x); /* x is its own unit normal */
        for (int d = 0; d < 3; d++)
            x[d] += g[d] - a * x[d];
        l = sqrt(mcf__dot3(x, x));
        for (int d = 0; d < 3; d++)
            x[d] /= l;
    }
    mcf_mesh *m = mcf_mesh_new(nv, X, mcf_mesh_nfaces(ico), mcf_mesh_faces(ico), NULL);
    assert_non_null(m);
    free(X);
    mcf_mesh_free(ico);
    return m;
}

/* clean plus isotropic Gaussian noise of rho mean edges per axis (seed) */
static mcf_mesh *with_iso_noise(const mcf_mesh *clean, double rho, uint64_t seed)
{
    mcf_mesh_info info;
    int nv = mcf_mesh_nvertices(clean);
    double *X = malloc(3 * sizeof(double) * (size_t)nv);
    uint64_t r = seed;
    assert_non_null(X);
    assert_int_equal(mcf_mesh_inspect(clean, &info, NULL), MCF_OK);
    memcpy(X, mcf_mesh_positions(clean), 3 * sizeof(double) * (size_t)nv);
    for (size_t q = 0; q < 3 * (size_t)nv; q++)
        X[q] += rho * info.mean_edge * tl_gauss01(&r);
    mcf_mesh *m = mcf_mesh_new(nv, X, mcf_mesh_nfaces(clean), mcf_mesh_faces(clean), NULL);
    assert_non_null(m);
    free(X);
    return m;
}

/* The tangential noise reading on irregular triangles (issue 27: the 435k
 * dragon's marching-cubes triangles read 0.2 mean edges in the tangent
 * planes under noise along the normals only, and the tangential step then
 * moved the vertices off the clean surface): on jittered_sphere, noise of
 * 0.25 and 0.5 mean edges along the normals reads no tangential noise
 * (noise_tangential TAN_NONE at most: the gate leaves exactly 0), and
 * isotropic noise of 0.25 and 0.5 reads its tangential deviation per
 * direction, which is rho, as the normal level read (the cap: isotropic
 * at most) within TAN_REL of rho; seeds 1 and 2. TAN_REL: the normal
 * level's own reading on this coarse sphere, 0.44 for 0.5 along the
 * normals and 0.35 under isotropic 0.5 (the noise tilts the normals);
 * 0.23 under isotropic 0.25. Before (the floor alone) the normal noise
 * read 0.140 in the tangent planes (0.25, seed 1) and the default came
 * back with 0.589 of the input's error: the test failed. The default's error
 * under the normal noise is at most TAN_ERR of the input's (measured
 * 0.14-0.16). About 4 s wall (2026-11-29, nice 10, load 7). */
#define TAN_NONE 1e-12
#define TAN_REL 0.35
#define TAN_ERR 0.3
static void test_tangential_reading(void **state)
{
    static const double rhos[] = {0.25, 0.5};
    mcf_mesh *clean = jittered_sphere();
    (void)state;
    for (int q = 0; q < 2; q++)
        for (uint64_t seed = 1; seed <= 2; seed++) {
            mcf_flow_params p;
            mcf_flow_stats st;
            mcf_mesh *m = mcf_mesh_dup(clean, NULL), *iso = with_iso_noise(clean, rhos[q], seed);
            assert_non_null(m);
            mcf_flow_params_init(&p);
            assert_int_equal(mcf_flow_add_noise(m, &p, rhos[q], seed, NULL), MCF_OK);
            double in = rms(m, clean);
            run_default(m, &st);
            double e = rms(m, clean);
            print_message("normal %.2f seed %d: noise %.3f tangential %.3f kind %d, error / input %.3f\n", rhos[q],
                          (int)seed, st.noise, st.noise_tangential, st.noise_kind, e / in);
            assert_true(st.noise_tangential <= TAN_NONE);
            assert_int_equal(st.noise_kind, MCF_NOISE_NORMAL);
            assert_true(e <= TAN_ERR * in);
            mcf_flow_stats_free(&st);
            in = rms(iso, clean);
            run_default(iso, &st);
            e = rms(iso, clean);
            print_message("iso    %.2f seed %d: noise %.3f tangential %.3f kind %d, error / input %.3f\n", rhos[q],
                          (int)seed, st.noise, st.noise_tangential, st.noise_kind, e / in);
            assert_int_equal(st.noise_kind, MCF_NOISE_ISOTROPIC);
            assert_true(st.noise_tangential == st.noise);
            assert_true(fabs(st.noise_tangential - rhos[q]) <= TAN_REL * rhos[q]);
            mcf_flow_stats_free(&st);
            mcf_mesh_free(m);
            mcf_mesh_free(iso);
        }
    mcf_mesh_free(clean);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_spikes_flat_grid),
        cmocka_unit_test(test_spikes_fold_centroid),
        cmocka_unit_test(test_spikes_needle),
        cmocka_unit_test(test_spikes_pair),
        cmocka_unit_test(test_spikes_rim),
        cmocka_unit_test(test_flat_share),
        cmocka_unit_test(test_spikes_noisy_cylinder),
        cmocka_unit_test(test_spikes_none),
        cmocka_unit_test(test_view_reading),
        cmocka_unit_test(test_outliers_end_to_end),
        cmocka_unit_test(test_outliers_folds),
        cmocka_unit_test(test_view_end_to_end),
        cmocka_unit_test(test_view_thin_plate),
        cmocka_unit_test(test_tangential_reading),
        cmocka_unit_test(test_plated_share),
        cmocka_unit_test(test_coarse_level),
        cmocka_unit_test(test_corr_blade),
        cmocka_unit_test(test_exact_positions),
        cmocka_unit_test(test_clean_untouched),
        cmocka_unit_test(test_clean_needle),
        cmocka_unit_test(test_named_untouched),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
