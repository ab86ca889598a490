/* SPDX-License-Identifier: MIT */
/*
 * test_core_mesh.c - the mesh object of libmcf: construction and its
 * refusals, icospheres, mcf_mesh_inspect on hand-made cases and on the
 * real meshes of tests/data/meshes and $MCF_MESHES (counts from
 * SOURCES.md), area and
 * volume convergence, deterministic noise and mcf_compare.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"
#include "mcf_internal.h"

static const double PI = 3.14159265358979323846;

/* The unit cube [0,1]^3 with outward faces; integer coordinates make
 * translations by small integers exact. */
static const double cube_X[8 * 3] = {
    0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0,
    0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1};
static const int32_t cube_F[12 * 3] = {
    0, 2, 1, 0, 3, 2,   /* z = 0, normal -z */
    4, 5, 6, 4, 6, 7,   /* z = 1, +z */
    0, 1, 5, 0, 5, 4,   /* y = 0, -y */
    3, 6, 2, 3, 7, 6,   /* y = 1, +y */
    0, 4, 7, 0, 7, 3,   /* x = 0, -x */
    1, 2, 6, 1, 6, 5};  /* x = 1, +x */

static mcf_mesh *must_new(int nv, const double *X, int nf, const int32_t *F)
{
    mcf_error err = {MCF_OK, ""};
    mcf_mesh *m = mcf_mesh_new(nv, X, nf, F, &err);
    if (!m)
        fail_msg("mcf_mesh_new: %s", err.msg);
    return m;
}

static mcf_mesh_info must_inspect(const mcf_mesh *m)
{
    mcf_mesh_info info;
    mcf_error err = {MCF_OK, ""};
    memset(&info, 0xff, sizeof info);
    assert_int_equal(mcf_mesh_inspect(m, &info, &err), MCF_OK);
    return info;
}

/* ------------------------------------------------------------ lifecycle */

static void test_new_copies_input(void **state)
{
    double X[8 * 3];
    int32_t F[12 * 3];
    mcf_mesh *m, *d;
    mcf_error err = {MCF_OK, ""};
    (void)state;

    memcpy(X, cube_X, sizeof X);
    memcpy(F, cube_F, sizeof F);
    m = must_new(8, X, 12, F);
    X[0] = 99;
    F[0] = 5;
    assert_int_equal(mcf_mesh_nvertices(m), 8);
    assert_int_equal(mcf_mesh_nfaces(m), 12);
    assert_memory_equal(mcf_mesh_positions(m), cube_X, sizeof cube_X);
    assert_memory_equal(mcf_mesh_faces(m), cube_F, sizeof cube_F);
    assert_ptr_equal(mcf_mesh_positions_mut(m), mcf_mesh_positions(m));

    d = mcf_mesh_dup(m, &err);
    assert_non_null(d);
    mcf_mesh_positions_mut(d)[0] = -1;
    assert_true(mcf_mesh_positions(m)[0] == 0);
    assert_memory_equal(mcf_mesh_faces(d), cube_F, sizeof cube_F);
    mcf_mesh_free(d);
    mcf_mesh_free(m);
    mcf_mesh_free(NULL);
}

static void expect_refusal(int nv, const double *X, int nf, const int32_t *F,
                           const char *want1, const char *want2)
{
    mcf_error err = {MCF_OK, ""};
    mcf_mesh *m = mcf_mesh_new(nv, X, nf, F, &err);
    assert_null(m);
    assert_int_equal(err.status, MCF_EMESH);
    if (!strstr(err.msg, want1) || (want2 && !strstr(err.msg, want2)))
        fail_msg("message \"%s\" lacks \"%s\"/\"%s\"", err.msg, want1,
                 want2 ? want2 : "");
    /* Also without an error buffer. */
    assert_null(mcf_mesh_new(nv, X, nf, F, NULL));
}

static void test_new_refusals(void **state)
{
    double X[8 * 3];
    int32_t F[12 * 3];
    (void)state;

    memcpy(X, cube_X, sizeof X);
    memcpy(F, cube_F, sizeof F);
    X[3 * 5 + 1] = NAN;
    expect_refusal(8, X, 12, F, "vertex 5", "coordinate y is");
    X[3 * 5 + 1] = 1;
    X[3 * 6 + 2] = -INFINITY;
    expect_refusal(8, X, 12, F, "vertex 6", "coordinate z is -inf");
    X[3 * 6 + 2] = 1;

    F[3 * 4 + 2] = 8; /* one past the end */
    expect_refusal(8, X, 12, F, "face 4", "index 8 out of range [0, 8)");
    F[3 * 4 + 2] = 5;
    F[3 * 9 + 0] = -1;
    F[3 * 10 + 1] = 100; /* the first offender is named */
    expect_refusal(8, X, 12, F, "face 9", "index -1");
    F[3 * 9 + 0] = cube_F[3 * 9];
    F[3 * 10 + 1] = cube_F[3 * 10 + 1];

    expect_refusal(0, X, 12, F, "0 vertices", NULL);
    expect_refusal(8, X, 0, F, "0 faces", NULL);
    expect_refusal(-3, X, 12, F, "-3 vertices", NULL);

    /* The corrected arrays are accepted. */
    mcf_mesh_free(must_new(8, X, 12, F));
}

/* ------------------------------------------------------------ icosphere */

static void test_icosphere_counts(void **state)
{
    mcf_error err = {MCF_OK, ""};
    int level;
    (void)state;

    for (level = 0; level <= 5; level++) {
        double r = 1.5;
        mcf_mesh *m = mcf_mesh_new_icosphere(level, r, &err);
        mcf_mesh_info I;
        const double *X;
        int i, nv = 10 * (1 << (2 * level)) + 2;
        assert_non_null(m);
        I = must_inspect(m);
        assert_int_equal(I.nv, nv);
        assert_int_equal(I.nf, 20 * (1 << (2 * level)));
        assert_int_equal(I.ne, 30 * (1 << (2 * level)));
        assert_int_equal(I.euler, 2);
        assert_int_equal(I.genus, 0);
        assert_int_equal(I.components, 1);
        assert_true(I.closed && I.manifold);
        assert_int_equal(I.boundary_edges, 0);
        assert_int_equal(I.boundary_loops, 0);
        assert_int_equal(I.nonmanifold_edges, 0);
        assert_int_equal(I.nonmanifold_vertices, 0);
        assert_int_equal(I.inconsistent_orientation, 0);
        assert_int_equal(I.degenerate_faces, 0);
        assert_int_equal(I.duplicate_faces, 0);
        assert_int_equal(I.unreferenced, 0);
        /* Outward faces: positive volume. */
        assert_true(I.volume > 0);
        X = mcf_mesh_positions(m);
        for (i = 0; i < nv; i++) {
            double len = sqrt(X[3 * i] * X[3 * i] + X[3 * i + 1] * X[3 * i + 1] +
                              X[3 * i + 2] * X[3 * i + 2]);
            /* Projection is one scaling: a few ulps of the radius. */
            tl_assert_near(len, r, 4e-15 * r, "icosphere vertex radius");
        }
        for (i = 0; i < 3; i++)
            tl_assert_near(I.bbox_max[i], -I.bbox_min[i], 1e-15,
                           "icosphere bbox symmetric");
        mcf_mesh_free(m);
    }
    assert_null(mcf_mesh_new_icosphere(11, 1, &err));
    assert_int_equal(err.status, MCF_EINVAL);
    assert_null(mcf_mesh_new_icosphere(-1, 1, &err));
    assert_null(mcf_mesh_new_icosphere(2, 0, &err));
    assert_null(mcf_mesh_new_icosphere(2, NAN, &err));
}

/* Area and volume approach 4 pi r^2 and 4/3 pi r^3 from below (inscribed
 * polyhedra) with an error that falls by about 4 per level (O(h^2)). */
static void test_icosphere_converges(void **state)
{
    double r = 2.0, A = 4 * PI * r * r, V = 4.0 / 3.0 * PI * r * r * r;
    double prev_ea = 0, prev_ev = 0;
    int level;
    (void)state;

    for (level = 1; level <= 6; level++) {
        mcf_mesh *m = mcf_mesh_new_icosphere(level, r, NULL);
        double a = mcf_mesh_area(m), v = mcf_mesh_volume(m);
        double ea = (A - a) / A, ev = (V - v) / V;
        mcf_mesh_info I = must_inspect(m);
        assert_true(ea > 0 && ev > 0);
        /* inspect and the direct functions sum the same terms. */
        tl_assert_near(I.area, a, 1e-12 * A, "inspect area");
        tl_assert_near(I.volume, v, 1e-12 * V, "inspect volume");
        if (level > 1) {
            /* O(h^2): the ratio tends to 4; 3.5..4.5 allows the
             * pre-asymptotic levels. */
            assert_true(prev_ea / ea > 3.5 && prev_ea / ea < 4.5);
            assert_true(prev_ev / ev > 3.5 && prev_ev / ev < 4.5);
        }
        prev_ea = ea;
        prev_ev = ev;
        mcf_mesh_free(m);
    }
    /* Level 6 (40,962 vertices): measured 7.5e-5 (area), 1.35e-4
     * (volume) relative; bound at 2x. */
    assert_true(prev_ea < 1.5e-4);
    assert_true(prev_ev < 2.7e-4);
}

/* ------------------------------------------------------ inspect by hand */

static void test_inspect_cube(void **state)
{
    mcf_mesh *m = must_new(8, cube_X, 12, cube_F);
    mcf_mesh_info I = must_inspect(m);
    int k;
    (void)state;

    assert_int_equal(I.ne, 18);
    assert_int_equal(I.euler, 2);
    assert_int_equal(I.genus, 0);
    assert_true(I.closed && I.manifold);
    assert_int_equal(I.inconsistent_orientation, 0);
    /* Integer data: area and volume are exact sums of halves/sixths. */
    tl_assert_near(I.area, 6, 1e-15, "cube area");
    tl_assert_near(I.volume, 1, 1e-15, "cube volume");
    tl_assert_near(mcf_mesh_area(m), 6, 1e-15, "cube area");
    tl_assert_near(mcf_mesh_volume(m), 1, 1e-15, "cube volume");
    {
        /* The unit cube's area centroid is its centre; without its
         * bottom (area 5: the top at z = 1, four sides at z = 1/2) it
         * rises to z = 3/5. */
        double c[3];
        mcf_mesh *open = must_new(8, cube_X, 10, cube_F + 6);
        tl_assert_near(mcf_mesh_area_centroid(m, c), 6, 1e-15, "cube area");
        for (k = 0; k < 3; k++)
            tl_assert_near(c[k], 0.5, 1e-15, "cube centroid");
        tl_assert_near(mcf_mesh_area_centroid(open, c), 5, 1e-15, "open area");
        tl_assert_near(c[0], 0.5, 1e-15, "open cube centroid x");
        tl_assert_near(c[1], 0.5, 1e-15, "open cube centroid y");
        tl_assert_near(c[2], 0.6, 1e-15, "open cube centroid z");
        mcf_mesh_free(open);
    }
    tl_assert_near(I.min_edge, 1, 0, "cube min edge");
    tl_assert_near(I.max_edge, sqrt(2), 0, "cube max edge");
    /* 12 unit edges and 6 face diagonals. */
    tl_assert_near(I.mean_edge, (12 + 6 * sqrt(2)) / 18, 1e-15, "mean edge");
    for (k = 0; k < 3; k++) {
        assert_true(I.bbox_min[k] == 0);
        assert_true(I.bbox_max[k] == 1);
    }
    mcf_mesh_free(m);
}

static void test_inspect_defects(void **state)
{
    /* Vertices: a square 0-3 in z = 0, an apex 4, a far point 5 (bowtie
     * partner 6, 7), an unreferenced 8. */
    static const double X[9 * 3] = {
        0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0.5, 0.5, 1,
        2, 0, 0, 3, 0, 0, 2, 1, 0, 9, 9, 9};
    mcf_mesh *m;
    mcf_mesh_info I;
    (void)state;

    {   /* One triangle: 3 boundary edges, 1 loop, a disk (chi 1, genus 0). */
        static const int32_t F[] = {0, 1, 2};
        m = must_new(9, X, 1, F);
        I = must_inspect(m);
        assert_int_equal(I.ne, 3);
        assert_int_equal(I.boundary_edges, 3);
        assert_int_equal(I.boundary_loops, 1);
        assert_int_equal(I.unreferenced, 6);
        assert_int_equal(I.euler, 1);
        assert_int_equal(I.genus, 0);
        assert_false(I.closed);
        assert_true(I.manifold);
        assert_int_equal(I.components, 1);
        tl_assert_near(I.area, 0.5, 1e-16, "triangle area");
        mcf_mesh_free(m);
    }
    {   /* Bowtie: two triangles sharing vertex 1 only. */
        static const int32_t F[] = {0, 1, 2, 1, 6, 7};
        m = must_new(9, X, 2, F);
        I = must_inspect(m);
        assert_int_equal(I.nonmanifold_vertices, 1);
        assert_int_equal(I.nonmanifold_edges, 0);
        assert_false(I.manifold);
        assert_int_equal(I.genus, -1);
        /* The two boundary triangles touch at 1: one connected curve. */
        assert_int_equal(I.boundary_loops, 1);
        assert_int_equal(I.components, 1);
        mcf_mesh_free(m);
    }
    {   /* Two separate triangles: 2 components, genus -1. */
        static const int32_t F[] = {0, 1, 2, 5, 6, 7};
        m = must_new(9, X, 2, F);
        I = must_inspect(m);
        assert_int_equal(I.components, 2);
        assert_int_equal(I.boundary_loops, 2);
        assert_true(I.manifold);
        assert_int_equal(I.genus, -1);
        mcf_mesh_free(m);
    }
    {   /* Three faces on edge 0-1: one non-manifold edge; the fans at 0 and
         * 1 stay connected through it, so no non-manifold vertex. */
        static const int32_t F[] = {0, 1, 2, 1, 0, 3, 0, 1, 4};
        m = must_new(9, X, 3, F);
        I = must_inspect(m);
        assert_int_equal(I.nonmanifold_edges, 1);
        assert_int_equal(I.nonmanifold_vertices, 0);
        assert_int_equal(I.boundary_edges, 6);
        assert_false(I.manifold);
        mcf_mesh_free(m);
    }
    {   /* Inconsistent orientation: both faces run 0 -> 2. */
        static const int32_t F[] = {0, 1, 2, 0, 2, 3};
        static const int32_t G[] = {0, 1, 2, 2, 0, 3};
        m = must_new(9, X, 2, F);
        I = must_inspect(m);
        assert_int_equal(I.inconsistent_orientation, 0);
        mcf_mesh_free(m);
        m = must_new(9, X, 2, G);
        I = must_inspect(m);
        assert_int_equal(I.inconsistent_orientation, 1);
        mcf_mesh_free(m);
    }
    {   /* Degenerate (repeated index; collinear 0, 5, 6) and duplicate
         * faces (same vertex set, any order). */
        static const int32_t F[] = {0, 1, 2, 2, 1, 0, 1, 2, 0,
                                    0, 0, 3, 0, 5, 6, 0, 1, 3};
        m = must_new(9, X, 6, F);
        I = must_inspect(m);
        assert_int_equal(I.degenerate_faces, 2);
        assert_int_equal(I.duplicate_faces, 2);
        mcf_mesh_free(m);
    }
    {   /* A square pyramid without its base: one 4-edge hole. */
        static const int32_t F[] = {0, 1, 4, 1, 2, 4, 2, 3, 4, 3, 0, 4};
        m = must_new(9, X, 4, F);
        I = must_inspect(m);
        assert_int_equal(I.ne, 8);
        assert_int_equal(I.boundary_edges, 4);
        assert_int_equal(I.boundary_loops, 1);
        assert_int_equal(I.euler, 1);
        assert_int_equal(I.genus, 0);
        mcf_mesh_free(m);
    }
}

/* ----------------------------------------------- inspect on real meshes */

/* -1: not stated in SOURCES.md, not checked. */
typedef struct {
    const char *file;
    int nv, nf, unref, bedges, loops, nme, nmv, dup, comps, genus, euler;
} expect_counts;

static void check_counts(const expect_counts *e)
{
    mcf_mesh *m = tl_load(e->file);
    mcf_mesh_info I = must_inspect(m);
#define CHECK(field, want)                                                  \
    do {                                                                    \
        if ((want) >= 0 && I.field != (want))                               \
            fail_msg("%s: %s = %d, SOURCES.md says %d", e->file, #field,    \
                     I.field, (want));                                      \
    } while (0)
    CHECK(nv, e->nv);
    CHECK(nf, e->nf);
    CHECK(unreferenced, e->unref);
    CHECK(boundary_edges, e->bedges);
    CHECK(boundary_loops, e->loops);
    CHECK(nonmanifold_edges, e->nme);
    CHECK(nonmanifold_vertices, e->nmv);
    CHECK(duplicate_faces, e->dup);
    CHECK(components, e->comps);
    CHECK(euler, e->euler);
    /* genus -1 in the table means "non-manifold": inspect must say -1. */
    if (I.genus != e->genus)
        fail_msg("%s: genus %d, expected %d", e->file, I.genus, e->genus);
    if (I.closed != (e->bedges == 0))
        fail_msg("%s: closed = %d", e->file, I.closed);
    if (I.manifold != (e->nme == 0 && e->nmv == 0))
        fail_msg("%s: manifold = %d", e->file, I.manifold);
    /* The test meshes are all consistently oriented scans/models with no
     * collapsed triangle (SOURCES.md lists degenerates only for the .drc). */
    if (e->nme == 0 && I.inconsistent_orientation != 0)
        fail_msg("%s: %d inconsistently oriented edges", e->file,
                 I.inconsistent_orientation);
    assert_true(I.min_edge > 0 && I.min_edge <= I.mean_edge &&
                I.mean_edge <= I.max_edge);
    assert_true(I.area > 0);
#undef CHECK
    mcf_mesh_free(m);
}

/* The entries of t whose mesh is in the repository (scans 0), or the large
 * scans of $MCF_MESHES (scans 1: the test is skipped when one is missing). */
static void check_table(const expect_counts *t, size_t n, int scans)
{
    size_t i;
    for (i = 0; i < n; i++)
        if (tl_mesh_in_repo(t[i].file) != scans)
            check_counts(&t[i]);
}

static const expect_counts sources_closed[] = {
    /* file                 nv     nf    unref bE lp nmE nmV dup comp g  chi */
    {"sphere_cgal.obj", 812, 1620, 0, 0, 0, 0, 0, 0, 1, 0, 2},
    {"bunny_npm_closed.obj", 1839, 3674, 0, 0, 0, 0, 0, 0, 1, 0, 2},
    {"spot.obj", 2930, 5856, 0, 0, 0, 0, 0, 0, 1, 0, 2},
    {"knot1.obj", 3200, 6400, 0, 0, 0, 0, 0, 0, 1, 1, 0},
    {"fertility.obj", 4494, 9000, 0, 0, 0, 0, 0, 0, 1, 4, -6},
    {"armadillo.obj", 43243, 86482, 0, 0, 0, 0, 0, 0, 1, 0, 2},
};

static const expect_counts sources_open[] = {
    /* stanford-bunny: genus 0 with 5 holes: chi = 2 - 0 - 5 = -3. */
    {"stanford-bunny.obj", 35947, 69451, 1113, 223, 5, 0, 0, 0, 1, 0, -3},
    {"snowden.obj", 54559, 109259, 0, 43, 7, 88, -1, -1, 4, -1, -1},
    {"dragon_vrip_res2.obj", 100250, 202520, 43, 0, 0, 2534, 16, 1489,
     7, -1, -1},
    {"test_nm.obj", 114, 170, 17, -1, 3, -1, 2, -1, -1, -1, -1},
    /* bunny.drc: the Stanford bunny without its unreferenced vertices */
    {"bunny.drc", 34834, 69451, 0, 223, 5, 0, 0, 0, 1, 0, -3},
};

#define NELEM(a) (sizeof(a) / sizeof((a)[0]))

static void test_inspect_sources_closed(void **state)
{
    (void)state;
    check_table(sources_closed, NELEM(sources_closed), 0);
}

static void test_inspect_sources_open(void **state)
{
    (void)state;
    check_table(sources_open, NELEM(sources_open), 0);
}

static void test_inspect_sources_scans(void **state)
{
    (void)state;
    check_table(sources_closed, NELEM(sources_closed), 1);
    check_table(sources_open, NELEM(sources_open), 1);
}

/* ---------------------------------------------------------------- noise */

static void test_noise_deterministic(void **state)
{
    mcf_mesh *a = mcf_mesh_new_icosphere(3, 1, NULL);
    mcf_mesh *b = mcf_mesh_dup(a, NULL);
    mcf_mesh *c = mcf_mesh_dup(a, NULL);
    mcf_mesh *z = mcf_mesh_dup(a, NULL);
    mcf_error err = {MCF_OK, ""};
    size_t n = 3 * (size_t)mcf_mesh_nvertices(a) * sizeof(double);
    /* Vertex 0 of the level-3 icosphere after noise (rho 0.1, seed 42),
     * recorded on x86-64 Linux/glibc: the generator uses only integer
     * arithmetic, IEEE +-*÷, sqrt and frexp, so these bits must be the same
     * on every IEEE-754 platform. */
    static const double golden[3] = {-0x1.0f2ca2a5385f1p-1,
                                     0x1.b6c4f28eb9a09p-1, 0x0p+0};
    (void)state;

    assert_int_equal(mcf_mesh_add_noise(a, 0.1, 42, &err), MCF_OK);
    assert_int_equal(mcf_mesh_add_noise(b, 0.1, 42, &err), MCF_OK);
    assert_int_equal(mcf_mesh_add_noise(c, 0.1, 43, &err), MCF_OK);
    assert_int_equal(mcf_mesh_add_noise(z, 0.0, 42, &err), MCF_OK);
    assert_memory_equal(mcf_mesh_positions(a), mcf_mesh_positions(b), n);
    assert_memory_not_equal(mcf_mesh_positions(a), mcf_mesh_positions(c), n);
    {
        mcf_mesh *ref = mcf_mesh_new_icosphere(3, 1, NULL);
        assert_memory_equal(mcf_mesh_positions(z), mcf_mesh_positions(ref), n);
        mcf_mesh_free(ref);
    }
    if (memcmp(mcf_mesh_positions(a), golden, sizeof golden) != 0)
        fail_msg("noise vertex 0 = (%a, %a, %a), recorded (%a, %a, %a)",
                 mcf_mesh_positions(a)[0], mcf_mesh_positions(a)[1],
                 mcf_mesh_positions(a)[2], golden[0], golden[1], golden[2]);
    assert_int_equal(mcf_mesh_add_noise(a, -1, 1, &err), MCF_EINVAL);
    assert_int_equal(mcf_mesh_add_noise(a, NAN, 1, &err), MCF_EINVAL);
    mcf_mesh_free(a);
    mcf_mesh_free(b);
    mcf_mesh_free(c);
    mcf_mesh_free(z);
}

static void test_noise_sigma(void **state)
{
    mcf_mesh *m = mcf_mesh_new_icosphere(5, 1, NULL);
    int nv = mcf_mesh_nvertices(m), i;
    double *X0 = malloc(3 * (size_t)nv * sizeof *X0);
    double *N = malloc(3 * (size_t)nv * sizeof *N);
    double rho = 0.2, sigma, sum = 0, sq = 0, mean, sd, off = 0;
    mcf_mesh_info I = must_inspect(m);
    const double *X;
    (void)state;

    assert_non_null(X0);
    assert_non_null(N);
    memcpy(X0, mcf_mesh_positions(m), 3 * (size_t)nv * sizeof *X0);
    assert_int_equal(mcf_curvature(m, N, NULL, NULL, NULL, NULL), MCF_OK);
    /* Closed manifold: every edge has two faces, so the per-face-side mean
     * the noise uses equals inspect's unique-edge mean. */
    sigma = rho * I.mean_edge;
    assert_int_equal(mcf_mesh_add_noise(m, rho, 7, NULL), MCF_OK);
    X = mcf_mesh_positions(m);
    for (i = 0; i < nv; i++) {
        double d[3], t, r[3];
        d[0] = X[3 * i] - X0[3 * i];
        d[1] = X[3 * i + 1] - X0[3 * i + 1];
        d[2] = X[3 * i + 2] - X0[3 * i + 2];
        t = d[0] * N[3 * i] + d[1] * N[3 * i + 1] + d[2] * N[3 * i + 2];
        r[0] = d[0] - t * N[3 * i];
        r[1] = d[1] - t * N[3 * i + 1];
        r[2] = d[2] - t * N[3 * i + 2];
        off = fmax(off, sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]));
        sum += t;
        sq += t * t;
    }
    mean = sum / nv;
    sd = sqrt((sq - nv * mean * mean) / (nv - 1));
    /* Displacement is along the normal up to the rounding of x + z n on
     * coordinates of size 1 (ulp 2.2e-16): 1e-14 is ~50 ulps. */
    assert_true(off < 1e-14);
    /* The sample sd of n = 10,242 normals has relative standard error
     * 1/sqrt(2n) = 0.7%; 3% is over 4 standard errors. The mean has
     * standard error sigma/sqrt(n) = 0.01 sigma; allow 0.05 sigma. */
    tl_assert_near(sd, sigma, 0.03 * sigma, "noise sample sd");
    tl_assert_near(mean, 0, 0.05 * sigma, "noise sample mean");
    free(X0);
    free(N);
    mcf_mesh_free(m);
}

/* -------------------------------------------------------------- compare */

static void test_compare_identical(void **state)
{
    mcf_mesh *a = tl_load("bunny_npm_closed.obj");
    mcf_mesh *b = mcf_mesh_dup(a, NULL);
    mcf_compare_result r;
    (void)state;

    assert_int_equal(mcf_compare(a, b, &r, NULL), MCF_OK);
    assert_true(r.rms_m == 0 && r.rms_rel == 0 && r.frobenius == 0 &&
                r.max_err == 0 && r.normal_angle_deg == 0);
    assert_int_equal(r.inverted_faces, 0);
    mcf_mesh_free(a);
    mcf_mesh_free(b);
}

static void test_compare_translated(void **state)
{
    mcf_mesh *a = must_new(8, cube_X, 12, cube_F);
    mcf_mesh *b = mcf_mesh_dup(a, NULL);
    mcf_compare_result r;
    double *X = mcf_mesh_positions_mut(b);
    int i;
    (void)state;

    /* Shift by (3, 0, 4): integers, so every difference is exactly the
     * shift and its length exactly 5. */
    for (i = 0; i < 8; i++) {
        X[3 * i] += 3;
        X[3 * i + 2] += 4;
    }
    assert_int_equal(mcf_compare(b, a, &r, NULL), MCF_OK);
    tl_assert_near(r.max_err, 5, 0, "max_err");
    /* sqrt(8 * 25): one rounding in the sum-free case, 2 ulps allowed. */
    tl_assert_near(r.frobenius, 5 * sqrt(8), 4e-15 * 5 * sqrt(8), "frobenius");
    /* Every vertex moved by 5: the mass-weighted mean of 25 is 25 up to
     * the rounding of the mass sum. */
    tl_assert_near(r.rms_m, 5, 1e-14, "rms_m");
    tl_assert_near(r.rms_m, r.frobenius / sqrt(8), 1e-14,
                   "rms = frobenius / sqrt(n) for a uniform shift");
    tl_assert_near(r.rms_rel, 5 / sqrt(6), 1e-14, "rms_rel (area 6)");
    tl_assert_near(r.normal_angle_deg, 0, 0, "translation keeps normals");
    assert_int_equal(r.inverted_faces, 0);
    mcf_mesh_free(a);
    mcf_mesh_free(b);
}

static void test_compare_inverted(void **state)
{
    /* Tetrahedron; moving the apex (0,0,1) to (0,0,-1) flips the two faces
     * in coordinate planes by 180 degrees and turns the slanted face by
     * acos(-1/3); the base keeps its normal. */
    static const double X[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    static const int32_t F[] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
    mcf_mesh *a = must_new(4, X, 4, F);
    mcf_mesh *b = mcf_mesh_dup(a, NULL);
    mcf_compare_result r;
    mcf_error err = {MCF_OK, ""};
    double want = (180 + 180 + acos(-1.0 / 3) * 180 / PI + 0) / 4;
    (void)state;

    mcf_mesh_positions_mut(b)[11] = -1;
    assert_int_equal(mcf_compare(b, a, &r, NULL), MCF_OK);
    assert_int_equal(r.inverted_faces, 3);
    tl_assert_near(r.normal_angle_deg, want, 1e-12, "mean normal angle");
    tl_assert_near(r.max_err, 2, 0, "apex moved by 2");
    tl_assert_near(r.frobenius, 2, 0, "one vertex moved");

    {   /* Different connectivity is refused. */
        static const int32_t G[] = {0, 1, 2, 0, 1, 3, 0, 3, 2, 1, 2, 3};
        mcf_mesh *c = must_new(4, X, 4, G);
        mcf_mesh *d = must_new(8, cube_X, 12, cube_F);
        assert_int_equal(mcf_compare(c, a, &r, &err), MCF_EINVAL);
        assert_non_null(strstr(err.msg, "face 0"));
        assert_int_equal(mcf_compare(d, a, &r, &err), MCF_EINVAL);
        mcf_mesh_free(c);
        mcf_mesh_free(d);
    }
    mcf_mesh_free(a);
    mcf_mesh_free(b);
}

/* ------------------------------------------------------------ radix sort */

typedef struct {
    uint64_t k;
    uint32_t v;
} key_pos;

static int key_pos_cmp(const void *pa, const void *pb)
{
    const key_pos *a = pa, *b = pb;
    if (a->k != b->k)
        return a->k < b->k ? -1 : 1;
    return (a->v > b->v) - (a->v < b->v);
}

static int double_cmp(const void *pa, const void *pb)
{
    double a = *(const double *)pa, b = *(const double *)pb;
    return (a > b) - (a < b);
}

/* Reference model: mcf__radix_sort_u64 against qsort on (key, position).
 * The radix sort is stable, so with the positions as payload both orders
 * agree exactly; keys of the shapes inspection sorts (edge keys u << 32 |
 * v, packed face keys), all-equal ones and random 64-bit ones, at sizes
 * 0, 1, 2, 1000 and 100,003. Doubles through mcf__double_key sort as a
 * comparison sorts them and come back bit for bit (-0 as +0). */
static void test_radix_sort(void **state)
{
    static const size_t sizes[] = {0, 1, 2, 1000, 100003};
    uint64_t x = 88172645463325252ull;
    (void)state;
    for (size_t si = 0; si < sizeof sizes / sizeof sizes[0]; si++) {
        size_t n = sizes[si];
        for (int shape = 0; shape < 4; shape++) {
            uint64_t *k = malloc((2 * n + 1) * sizeof *k);
            uint32_t *v = malloc((2 * n + 1) * sizeof *v);
            key_pos *ref = malloc((n + 1) * sizeof *ref);
            assert_true(k && v && ref);
            for (size_t i = 0; i < n; i++) {
                uint64_t a, b;
                x ^= x << 13; x ^= x >> 7; x ^= x << 17; /* xorshift64 */
                a = x % 5000;
                b = (x >> 20) % 5000;
                k[i] = shape == 0 ? (a < b ? a << 32 | b : b << 32 | a)
                     : shape == 1 ? a << 42 | b << 21 | (x >> 40) % 3
                     : shape == 2 ? 42 : x;
                v[i] = (uint32_t)i;
                ref[i].k = k[i];
                ref[i].v = (uint32_t)i;
            }
            qsort(ref, n, sizeof *ref, key_pos_cmp);
            mcf__radix_sort_u64(k, v, n, k + n, v + n);
            for (size_t i = 0; i < n; i++)
                if (k[i] != ref[i].k || v[i] != ref[i].v)
                    fail_msg("n %zu shape %d: position %zu differs", n, shape, i);
            free(k);
            free(v);
            free(ref);
        }
    }
    {
        enum { N = 20000 };
        double *d = malloc(N * sizeof *d), *e = malloc(N * sizeof *e);
        uint64_t *u = malloc(2 * N * sizeof *u);
        assert_true(d && e && u);
        for (int i = 0; i < N; i++) {
            x ^= x << 13; x ^= x >> 7; x ^= x << 17;
            /* signs, zeros of both signs, tiny, huge, subnormal */
            d[i] = i % 7 == 0 ? (i % 14 ? 0.0 : -0.0)
                 : ldexp((double)(x >> 11) / 9007199254740992.0 - 0.5,
                         (int)(x % 600) - 300);
            if (i % 101 == 0)
                d[i] = (x & 1 ? -1 : 1) * 4.9e-324;
            u[i] = mcf__double_key(d[i]);
        }
        mcf__radix_sort_u64(u, NULL, N, u + N, NULL);
        memcpy(e, d, N * sizeof *e);
        qsort(e, N, sizeof *e, double_cmp);
        for (int i = 0; i < N; i++) {
            double y = mcf__key_double(u[i]), z = e[i] == 0 ? 0.0 : e[i];
            assert_memory_equal(&y, &z, sizeof y);
        }
        free(d);
        free(e);
        free(u);
    }
}

/* Reference model: mcf__median against the middle of a qsort'ed copy
 * (the middle value, or the mean of the two middle ones), bit for bit,
 * at sizes 0-40, 1000, 1001 and 100,003, on random values, few distinct
 * values (ties across the pivot), sorted, reversed, all equal and an
 * organ pipe (orders that defeat a naive pivot). */
static void test_median_select(void **state)
{
    static const size_t sizes[] = {1000, 1001, 100003};
    uint64_t x = 2463534242ull;
    (void)state;
    for (size_t si = 0; si < 41 + sizeof sizes / sizeof sizes[0]; si++) {
        size_t n = si < 41 ? si : sizes[si - 41];
        double *a = malloc((n + 1) * sizeof *a), *b = malloc((n + 1) * sizeof *b);
        assert_true(a && b);
        for (int shape = 0; shape < 6; shape++) {
            for (size_t i = 0; i < n; i++) {
                x ^= x << 13; x ^= x >> 7; x ^= x << 17;
                a[i] = shape == 0 ? ldexp((double)(x >> 11), -53) - 0.25
                     : shape == 1 ? (double)(x % 5)
                     : shape == 2 ? (double)i
                     : shape == 3 ? (double)(n - i)
                     : shape == 4 ? 7.0
                     : (double)(i < n / 2 ? i : n - i);
            }
            memcpy(b, a, n * sizeof *a);
            qsort(b, n, sizeof *b, double_cmp);
            double ref = n == 0 ? 0.0 : n % 2 ? b[n / 2] : 0.5 * (b[n / 2 - 1] + b[n / 2]);
            double got = mcf__median(a, n);
            if (memcmp(&got, &ref, sizeof got) != 0)
                fail_msg("n %zu shape %d: median %.17g, the sort's %.17g", n, shape, got, ref);
            /* a permutation of the input: sorted, the same values */
            qsort(a, n, sizeof *a, double_cmp);
            assert_true(n == 0 || memcmp(a, b, n * sizeof *a) == 0);
        }
        free(a);
        free(b);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_new_copies_input),
        cmocka_unit_test(test_new_refusals),
        cmocka_unit_test(test_icosphere_counts),
        cmocka_unit_test(test_icosphere_converges),
        cmocka_unit_test(test_inspect_cube),
        cmocka_unit_test(test_inspect_defects),
        cmocka_unit_test(test_inspect_sources_closed),
        cmocka_unit_test(test_inspect_sources_open),
        cmocka_unit_test(test_inspect_sources_scans),
        cmocka_unit_test(test_noise_deterministic),
        cmocka_unit_test(test_noise_sigma),
        cmocka_unit_test(test_compare_identical),
        cmocka_unit_test(test_compare_translated),
        cmocka_unit_test(test_compare_inverted),
        cmocka_unit_test(test_radix_sort),
        cmocka_unit_test(test_median_select),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
