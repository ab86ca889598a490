/* SPDX-License-Identifier: MIT */
/*
 * test_core_flips.c - the default request's repair of the orientations
 * its output invents (core/mcf_flips.c, docs/fairing.md "Faces without
 * area"):
 *  - mcf__flips_repair on a flat grid with a collapsed edge, by hand: a
 *    face stood on edge is taken back to the input in 7 rounds (14 vertex
 *    moves), one facing along the field is kept; on a grid, by hand, an
 *    orientation along a tilted field but past 63 degrees from the
 *    input's flat faces within 3 rings is taken back, one within is kept;
 *  - on random grids with collapsed vertices and random outputs, against
 *    a reference model written here from the definition (which faces are
 *    judged, the field test, the input's own faces, the halving and the
 *    input rounds), to the bit; and the promise checked on the result: no
 *    judged face left facing away from the field;
 *  - a mesh without degenerate faces comes back untouched;
 *  - mcf__turned_repair (core/mcf_turned.c): a vertex slid past its
 *    neighbour on a flat grid comes back to its place with its height,
 *    no face down (counted from the face normals here); an output with
 *    no turned face comes back to the bit; end to end, car.drc with
 *    Gaussian noise of 0.5 mean edges comes back with fewer faces against
 *    the clean mesh than its input;
 *  - end to end: bunny.drc (the repository's 35k-vertex scan) quantized
 *    to a grid of 0.5 mean edges (issue 31's `quant` model): the default
 *    request returns no more faces facing against the clean mesh's than
 *    the input has (115 against the input's 25 without the repair), with
 *    its error below the input's.
 * Runs in about 2.5 s of CPU (the end-to-end cases).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "api.h"
#include "mcf_internal.h" /* mcf__flips_repair, mcf__turned_repair */
#include "testlib.h"

/* An n x n grid of unit squares in z = 0, each split along one diagonal,
 * facing +z; X (3 n^2) and F (6 (n-1)^2) are the caller's. */
static void grid(int n, double *X, int32_t *F)
{
    int f = 0;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            X[3 * (i * n + j)] = j;
            X[3 * (i * n + j) + 1] = i;
            X[3 * (i * n + j) + 2] = 0.0;
        }
    for (int i = 0; i + 1 < n; i++)
        for (int j = 0; j + 1 < n; j++) {
            int32_t a = i * n + j, b = a + 1, c = a + n + 1, d = a + n;
            int32_t t[6] = {a, b, c, a, c, d};
            memcpy(F + 3 * f, t, sizeof t);
            f += 2;
        }
}

/* The face normal from the second corner: (c - b) x (a - b), the same as
 * (b - a) x (c - a) in exact arithmetic. */
static void normal_at_b(const double *X, const int32_t *t, double *n)
{
    const double *a = X + 3 * t[0], *b = X + 3 * t[1], *c = X + 3 * t[2];
    double u[3] = {c[0] - b[0], c[1] - b[1], c[2] - b[2]}, v[3] = {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
    n[0] = u[1] * v[2] - u[2] * v[1];
    n[1] = u[2] * v[0] - u[0] * v[2];
    n[2] = u[0] * v[1] - u[1] * v[0];
}

static double dot(const double *a, const double *b)
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* Degenerate: |n| <= 1e-10 (|c - b|^2 + |a - b|^2). The test's faces are
 * exactly degenerate (coincident vertices: n = 0 in any formula) or far
 * from it (sine above 0.1), so the corner the test measures from does
 * not matter. */
static int degenerate(const double *X, const int32_t *t)
{
    double n[3], e = 0.0;
    normal_at_b(X, t, n);
    for (int k = 0; k < 3; k += 2)
        for (int d = 0; d < 3; d++)
            e += (X[3 * t[k] + d] - X[3 * t[1] + d]) * (X[3 * t[k] + d] - X[3 * t[1] + d]);
    return sqrt(dot(n, n)) <= 1e-10 * e;
}

/* w = the sum of Nin over the vertices at most 3 edges from a corner of
 * face t (each once): distances relaxed face by face, 3 sweeps. */
static void wide_ref(const int32_t *F, int nf, int nv, const double *Nin, const int32_t *t, double *w)
{
    int *dist = malloc(sizeof(int) * (size_t)nv);
    assert_non_null(dist);
    for (int i = 0; i < nv; i++)
        dist[i] = 1000;
    dist[t[0]] = dist[t[1]] = dist[t[2]] = 0;
    for (int r = 0; r < 3; r++) {
        for (int f = 0; f < nf; f++) {
            int has = 0;
            for (int k = 0; k < 3; k++)
                has |= dist[F[3 * f + k]] == r;
            for (int k = 0; k < 3 && has; k++)
                if (dist[F[3 * f + k]] > r + 1)
                    dist[F[3 * f + k]] = r + 1;
        }
    }
    w[0] = w[1] = w[2] = 0.0;
    for (int i = 0; i < nv; i++)
        for (int d = 0; d < 3 && dist[i] <= 3; d++)
            w[d] += Nin[3 * i + d];
    free(dist);
}

/* The definition (docs/fairing.md), one round at a time: a face judged is
 * degenerate in Xin and not all at Xin's positions; it is taken back
 * unless X gives it no normal (exactly 0) or a normal within 60 degrees
 * (grid: 41, cosine 0.75) of the sum of the three field vectors and
 * pointing along the sum of the input's face normals at its three
 * vertices, and on a grid within 63 degrees (cosine 0.45) of the sum of
 * the input's face normals at the vertices within 3 edges of its corners
 * (wide_ref; a zero sum: no test). On a grid, a face with a normal in Xin, not all at Xin's
 * positions, whose Xin normal points along that sum of field vectors
 * (dot > 0) and whose X normal against it (dot < 0) is taken back too.
 * Taken back: rounds 0-5 halve the displacement from Xin of its vertices,
 * later rounds put them at Xin; at most 64 rounds, none once no vertex
 * moves. Returns the faces judged bad in round 0; *moves the vertex
 * moves. */
static int reference(const int32_t *F, int nf, int nv, const double *Xin, const double *field, int grid, double *X,
                     int *moves)
{
    const double turn = grid ? 0.75 : 0.5;
    double *Nin = calloc(3 * (size_t)nv, sizeof(double));
    unsigned char *mark = calloc((size_t)nv, 1);
    int first = 0;
    assert_non_null(Nin);
    assert_non_null(mark);
    *moves = 0;
    for (int f = 0; f < nf; f++) {
        double n[3];
        normal_at_b(Xin, F + 3 * f, n);
        for (int k = 0; k < 3; k++)
            for (int d = 0; d < 3; d++)
                Nin[3 * F[3 * f + k] + d] += n[d];
    }
    for (int round = 0; round < 64; round++) {
        int bad = 0, moved = 0;
        for (int f = 0; f < nf; f++) {
            const int32_t *t = F + 3 * f;
            int at_in = 1;
            for (int k = 0; k < 3; k++)
                at_in &= memcmp(X + 3 * t[k], Xin + 3 * t[k], 3 * sizeof(double)) == 0;
            int deg = degenerate(Xin, t);
            if ((!deg && !grid) || at_in)
                continue;
            double n[3], n0[3], s[3] = {0, 0, 0}, g[3] = {0, 0, 0};
            normal_at_b(X, t, n);
            normal_at_b(Xin, t, n0);
            for (int k = 0; k < 3; k++)
                for (int d = 0; d < 3; d++) {
                    s[d] += field[3 * t[k] + d];
                    g[d] += Nin[3 * t[k] + d];
                }
            if (!deg && !(dot(n0, s) > 0.0 && dot(n, s) < 0.0))
                continue;
            double w[3] = {0, 0, 0};
            if (deg && grid)
                wide_ref(F, nf, nv, Nin, t, w);
            if (deg && (dot(n, n) == 0.0 || (dot(n, s) >= turn * sqrt(dot(n, n) * dot(s, s)) && dot(n, g) > 0.0 &&
                                             (dot(w, w) == 0.0 || dot(n, w) >= 0.45 * sqrt(dot(n, n) * dot(w, w))))))
                continue;
            bad++;
            mark[t[0]] = mark[t[1]] = mark[t[2]] = 1;
        }
        if (round == 0)
            first = bad;
        for (int i = 0; i < nv; i++)
            if (mark[i]) {
                mark[i] = 0;
                double to[3];
                for (int d = 0; d < 3; d++)
                    to[d] = round < 6 ? Xin[3 * i + d] + 0.5 * (X[3 * i + d] - Xin[3 * i + d]) : Xin[3 * i + d];
                if (memcmp(X + 3 * i, Xin + 3 * i, sizeof to) != 0 && memcmp(X + 3 * i, to, sizeof to) != 0) {
                    memcpy(X + 3 * i, to, sizeof to);
                    moved++;
                }
            }
        *moves += moved;
        if (bad == 0 || moved == 0)
            break;
    }
    free(Nin);
    free(mark);
    return first;
}

/* the normal field +z at the nv vertices (the grid's clean normals) */
static void field_up(double *field, int nv)
{
    for (int i = 0; i < nv; i++) {
        field[3 * i] = field[3 * i + 1] = 0.0;
        field[3 * i + 2] = 1.0;
    }
}

/* A 5 x 5 grid whose vertex 12 (2, 2) the input put on vertex 13 (3, 2):
 * faces 12-13-18 and 7-13-12 have no area (the other four around 12 keep
 * facing +z). Lifting 12 and lowering 13
 * stands them on edge (normal along -y or +y, 90 degrees from the field
 * +z): both are taken back, 6 halvings and one round to the input, 2
 * vertices each: 14 moves, and X is the input again. Moving 12 back
 * toward (2, 2) in the plane gives them their clean orientation: kept. */
static void test_flips_collapsed_edge(void **state)
{
    enum { n = 5, nv = n * n, nf = 2 * (n - 1) * (n - 1) };
    double Xc[3 * nv], Xin[3 * nv], X[3 * nv], field[3 * nv];
    int32_t F[3 * nf];
    int repaired, moves, weak = 0;
    (void)state;
    grid(n, Xc, F);
    memcpy(Xin, Xc, sizeof Xc);
    memcpy(Xin + 3 * 12, Xc + 3 * 13, 3 * sizeof(double));
    for (int f = 0; f < nf; f++)
        weak += degenerate(Xin, F + 3 * f);
    assert_int_equal(weak, 2); /* the two faces on edge 12-13 */
    field_up(field, nv);
    memcpy(X, Xin, sizeof X);
    X[3 * 12 + 2] = 0.25;
    X[3 * 13 + 2] = -0.25;
    assert_int_equal(mcf__flips_repair(X, Xin, field, F, nf, nv, 0, &repaired, &moves, NULL), MCF_OK);
    assert_int_equal(repaired, 2);
    assert_int_equal(moves, 14);
    assert_memory_equal(X, Xin, sizeof X);
    /* in the plane, 12 a quarter of the way back to (2, 2): kept */
    memcpy(X, Xin, sizeof X);
    X[3 * 12] = 2.75;
    assert_int_equal(mcf__flips_repair(X, Xin, field, F, nf, nv, 0, &repaired, &moves, NULL), MCF_OK);
    assert_int_equal(repaired, 0);
    assert_int_equal(moves, 0);
    assert_true(X[3 * 12] == 2.75);
    /* past 13 in the plane: the two faces face -z, taken back */
    X[3 * 12] = 3.25;
    assert_int_equal(mcf__flips_repair(X, Xin, field, F, nf, nv, 0, &repaired, &moves, NULL), MCF_OK);
    assert_int_equal(repaired, 2);
    assert_true(X[3 * 12] == 3.0);
}

/* The grid rules' cases: X is left as it is without a grid, then on a
 * grid `repaired` faces are taken back in `moves` moves (X repaired in
 * place). */
static void repaired_on_grid_only(double *X, const double *Xin, const double *field, const int32_t *F, int nf,
                                  int nv, int want_repaired, int want_moves)
{
    int repaired, moves;
    double *X0 = malloc(3 * sizeof(double) * (size_t)nv);
    assert_non_null(X0);
    memcpy(X0, X, 3 * sizeof(double) * (size_t)nv);
    assert_int_equal(mcf__flips_repair(X, Xin, field, F, nf, nv, 0, &repaired, &moves, NULL), MCF_OK);
    assert_int_equal(repaired, 0);
    assert_memory_equal(X, X0, 3 * sizeof(double) * (size_t)nv);
    free(X0);
    assert_int_equal(mcf__flips_repair(X, Xin, field, F, nf, nv, 1, &repaired, &moves, NULL), MCF_OK);
    assert_int_equal(repaired, want_repaired);
    assert_int_equal(moves, want_moves);
}

/* On a quantized input (grid): the collapsed edge of the test above, 12
 * lifted by 0.25 and moved a quarter of the way back to (2, 2): face
 * 12-13-18's normal (0.25, 0, 0.25) is 45 degrees off the field +z, face
 * 7-13-12's (0.25, -0.25, 0.25) 54.7 degrees (computed by hand: (13 -
 * 12) x (18 - 12) and (13 - 7) x (12 - 7)). Without a grid both are
 * within 60 degrees: kept. On a grid neither is within 41: taken back;
 * each halving toward 13 (the input point) keeps both angles, so 6
 * halvings and the input: 7 rounds, one vertex, 7 moves. */
static void test_flips_grid_angle(void **state)
{
    enum { n = 5, nv = n * n, nf = 2 * (n - 1) * (n - 1) };
    double Xc[3 * nv], Xin[3 * nv], X[3 * nv], field[3 * nv];
    int32_t F[3 * nf];
    (void)state;
    grid(n, Xc, F);
    memcpy(Xin, Xc, sizeof Xc);
    memcpy(Xin + 3 * 12, Xc + 3 * 13, 3 * sizeof(double));
    field_up(field, nv);
    memcpy(X, Xin, sizeof X);
    X[3 * 12] = 2.75;
    X[3 * 12 + 2] = 0.25;
    repaired_on_grid_only(X, Xin, field, F, nf, nv, 2, 7);
    assert_memory_equal(X, Xin, sizeof X);
}

/* On a quantized input (grid), a face the input had with an orientation:
 * the input put 12 at (2.875, 2, 0.25), so 12-13-18 stands nearly on
 * edge, normal (0.25, 0, 0.125) (by hand: (13 - 12) x (18 - 12)), and
 * 7-13-12 faces (0.25, -0.25, 0.125): both along the field +z. The output
 * moves 12 to (3.125, 2, 0.25), past 13's x: (0.25, 0, -0.125) and (0.25,
 * -0.25, -0.125), both against the field, though turned by only 37 and
 * 27 degrees against the input (the fold guard's 90 do not see them).
 * Without a grid they are not judged; on a grid both are taken back: one
 * halving puts 12 at x = 3, both normals' z exactly 0 (not against), one
 * round, one move. */
static void test_flips_grid_sliver(void **state)
{
    enum { n = 5, nv = n * n, nf = 2 * (n - 1) * (n - 1) };
    double Xin[3 * nv], X[3 * nv], X0[3 * nv], field[3 * nv];
    int32_t F[3 * nf];
    (void)state;
    grid(n, Xin, F);
    Xin[3 * 12] = 2.875;
    Xin[3 * 12 + 2] = 0.25;
    field_up(field, nv);
    memcpy(X, Xin, sizeof X);
    X[3 * 12] = 3.125;
    memcpy(X0, X, sizeof X);
    repaired_on_grid_only(X, Xin, field, F, nf, nv, 2, 1);
    assert_true(X[3 * 12] == 3.0 && X[3 * 12 + 1] == 2.0 && X[3 * 12 + 2] == 0.25);
    X0[3 * 12] = 3.0;
    assert_memory_equal(X, X0, sizeof X);
}

/* On a quantized input (grid), the input's broad normal: the collapsed
 * edge of test_flips_grid_angle, 12 moved to (2.75, 2, z), the field
 * tilted toward +x, f = (1, -0.5, 0.3) / |.|, at the two faces' corners
 * 7, 12, 13, 18 (a staircase's riser) and +z elsewhere. By hand,
 * 12-13-18's normal (13 - 12) x (18 - 12) is (z, 0, 0.25) and 7-13-12's
 * (13 - 7) x (12 - 7) is (z, -z, 0.25). z = 0.75: (0.75, 0, 0.25) and
 * (0.75, -0.75, 0.25) face f by cosines 0.901 and 0.951 (within 41
 * degrees: the field test keeps both) and +z, the input's flat grid
 * around them, by 0.316 and 0.229: 72 and 77 degrees, past 63; on a grid
 * both are taken back (halvings keep the angles: 7 rounds, one vertex, 7
 * moves, X the input again). The four faces around 12 with an area keep
 * facing along their field sums (the least cosine 0.28, 12-18-17), so
 * the grid's other rule takes none back. z = 0.25: (0.25, 0, 0.25) and
 * (0.25, -0.25, 0.25) face f by 0.794 and 0.898 and +z by 0.707 and
 * 0.577 (45 and 55 degrees): kept on a grid too. */
static void test_flips_grid_wide(void **state)
{
    enum { n = 5, nv = n * n, nf = 2 * (n - 1) * (n - 1) };
    double Xc[3 * nv], Xin[3 * nv], X[3 * nv], X0[3 * nv], field[3 * nv];
    int32_t F[3 * nf];
    int repaired, moves;
    (void)state;
    grid(n, Xc, F);
    memcpy(Xin, Xc, sizeof Xc);
    memcpy(Xin + 3 * 12, Xc + 3 * 13, 3 * sizeof(double));
    double l = sqrt(1.0 + 0.25 + 0.09);
    field_up(field, nv);
    for (int k = 0; k < 4; k++) {
        int i = (int[]){7, 12, 13, 18}[k];
        field[3 * i] = 1.0 / l;
        field[3 * i + 1] = -0.5 / l;
        field[3 * i + 2] = 0.3 / l;
    }
    memcpy(X, Xin, sizeof X);
    X[3 * 12] = 2.75;
    X[3 * 12 + 2] = 0.75;
    repaired_on_grid_only(X, Xin, field, F, nf, nv, 2, 7);
    assert_memory_equal(X, Xin, sizeof X);
    X[3 * 12] = 2.75;
    X[3 * 12 + 2] = 0.25;
    memcpy(X0, X, sizeof X);
    assert_int_equal(mcf__flips_repair(X, Xin, field, F, nf, nv, 1, &repaired, &moves, NULL), MCF_OK);
    assert_int_equal(repaired, 0);
    assert_int_equal(moves, 0);
    assert_memory_equal(X, X0, sizeof X);
}

/* Random 12 x 12 grids (seeds 1-20): a random set of vertices each put
 * on a neighbour's position or a whole 3 x 3 block on one point (faces
 * whose vertices the input had nowhere else: no input orientation to
 * follow), then an output moving every vertex by up to 0.4 in each
 * coordinate, and a field tilted from +z by up to 35 degrees per vertex
 * (65 on the odd seeds, which apply the grid's rules: past the 63 of the
 * input's broad normal, +z; with that rule left out of the reference the
 * test fails). mcf__flips_repair matches the reference to the bit
 * (positions, faces repaired, moves), and leaves no face degenerate in
 * the input facing away from the field or the input's faces. */
static void test_flips_reference(void **state)
{
    enum { n = 12, nv = n * n, nf = 2 * (n - 1) * (n - 1) };
    double Xc[3 * nv], Xin[3 * nv], X[3 * nv], R[3 * nv], field[3 * nv];
    int32_t F[3 * nf];
    int total = 0;
    (void)state;
    grid(n, Xc, F);
    for (uint64_t seed = 1; seed <= 20; seed++) {
        uint64_t r = seed;
        memcpy(Xin, Xc, sizeof Xc);
        if (seed % 4 == 0) { /* a block collapsed onto (5, 5) */
            for (int i = 4; i <= 6; i++)
                for (int j = 4; j <= 6; j++)
                    memcpy(Xin + 3 * (i * n + j), Xc + 3 * (5 * n + 5), 3 * sizeof(double));
        }
        for (int q = 0; q < 12; q++) { /* vertices onto a grid neighbour */
            int i = 1 + (int)(tl_uniform01(&r) * (n - 2)), j = 1 + (int)(tl_uniform01(&r) * (n - 2));
            int di = tl_uniform01(&r) < 0.5 ? 0 : 1, dj = 1 - di;
            memcpy(Xin + 3 * (i * n + j), Xin + 3 * ((i + di) * n + j + dj), 3 * sizeof(double));
        }
        for (int k = 0; k < 3 * nv; k++)
            X[k] = Xin[k] + 0.4 * (2.0 * tl_uniform01(&r) - 1.0);
        int gridded = seed % 2; /* odd seeds: a quantized input's rules */
        double tilt = gridded ? 1.5 : 0.5; /* up to 65 degrees: past the input's broad normal's 63 */
        for (int i = 0; i < nv; i++) {
            double a = tilt * (2.0 * tl_uniform01(&r) - 1.0), b = tilt * (2.0 * tl_uniform01(&r) - 1.0);
            double l = sqrt(a * a + b * b + 1.0);
            field[3 * i] = a / l;
            field[3 * i + 1] = b / l;
            field[3 * i + 2] = 1.0 / l;
        }
        memcpy(R, X, sizeof X);
        int rmoves, repaired, moves;
        int rrep = reference(F, nf, nv, Xin, field, gridded, R, &rmoves);
        assert_int_equal(mcf__flips_repair(X, Xin, field, F, nf, nv, gridded, &repaired, &moves, NULL), MCF_OK);
        assert_int_equal(repaired, rrep);
        assert_int_equal(moves, rmoves);
        assert_memory_equal(X, R, sizeof X);
        total += repaired;
        /* the promise: a face degenerate in the input ends at the input,
         * without a normal, or facing along the field */
        double *Nin = calloc(3 * nv, sizeof(double));
        assert_non_null(Nin);
        for (int f = 0; f < nf; f++) {
            double nn[3];
            normal_at_b(Xin, F + 3 * f, nn);
            for (int k = 0; k < 3; k++)
                for (int d = 0; d < 3; d++)
                    Nin[3 * F[3 * f + k] + d] += nn[d];
        }
        for (int f = 0; f < nf; f++) {
            const int32_t *t = F + 3 * f;
            double nn[3], n0[3], s[3] = {0, 0, 0}, g[3] = {0, 0, 0};
            normal_at_b(X, t, nn);
            normal_at_b(Xin, t, n0);
            for (int k = 0; k < 3; k++)
                for (int d = 0; d < 3; d++) {
                    s[d] += field[3 * t[k] + d];
                    g[d] += Nin[3 * t[k] + d];
                }
            int at_in = 1;
            for (int k = 0; k < 3; k++)
                at_in &= memcmp(X + 3 * t[k], Xin + 3 * t[k], 3 * sizeof(double)) == 0;
            if (!degenerate(Xin, t)) { /* on a grid: not turned against the field */
                assert_true(!gridded || at_in || !(dot(n0, s) > 0.0) || dot(nn, s) >= 0.0);
                continue;
            }
            double turn = gridded ? 0.75 : 0.5, w[3] = {0, 0, 0};
            if (gridded)
                wide_ref(F, nf, nv, Nin, t, w);
            assert_true(at_in || dot(nn, nn) == 0.0 ||
                        (dot(nn, s) >= turn * sqrt(dot(nn, nn) * dot(s, s)) && dot(nn, g) > 0.0 &&
                         (dot(w, w) == 0.0 || dot(nn, w) >= 0.45 * sqrt(dot(nn, nn) * dot(w, w)))));
        }
        free(Nin);
    }
    print_message("20 random grids: %d faces taken back\n", total);
    assert_true(total > 100); /* the test exercises the repair */
}

/* No face degenerate in the input: nothing judged, X untouched. */
static void test_flips_none(void **state)
{
    enum { n = 8, nv = n * n, nf = 2 * (n - 1) * (n - 1) };
    double Xin[3 * nv], X[3 * nv], X0[3 * nv], field[3 * nv];
    int32_t F[3 * nf];
    int repaired, moves;
    uint64_t r = 7;
    (void)state;
    grid(n, Xin, F);
    for (int k = 0; k < 3 * nv; k++) {
        X[k] = Xin[k] + 0.45 * (2.0 * tl_uniform01(&r) - 1.0);
        field[k] = k % 3 == 2 ? -1.0 : 0.0; /* a field that disagrees with every face */
    }
    memcpy(X0, X, sizeof X);
    assert_int_equal(mcf__flips_repair(X, Xin, field, F, nf, nv, 0, &repaired, &moves, NULL), MCF_OK);
    assert_int_equal(repaired, 0);
    assert_int_equal(moves, 0);
    assert_memory_equal(X, X0, sizeof X);
}

/* Faces of X (grid faces F) whose normal has no positive z: every face
 * of the flat grid faces +z. */
static int grid_faces_down(const double *X, const int32_t *F, int nf)
{
    int bad = 0;
    for (int f = 0; f < nf; f++) {
        double nn[3];
        normal_at_b(X, F + 3 * f, nn);
        bad += !(nn[2] > 0.0);
    }
    return bad;
}

/* mcf__turned_repair (core/mcf_turned.c) on the flat 15 x 15 grid: the
 * output raised one vertex 0.2 and slid it 1.4, 0.4 along the grid,
 * past the edge between its neighbours (8, 7) and (8, 8): faces around
 * it face down (counted here
 * from the face normals, independently of the repair's field). The repair
 * takes the slide back: no face down, the vertex within 0.05 of its grid
 * place and its height 0.2 kept to 0.01 (the field at it, averaged over
 * 16 rings of a flat grid, tilts by the vertex's own faces only: the
 * residual slide is about 0.2 times that tilt). The other vertices, where
 * the input has them, stay to the bit. A second call on the result moves
 * nothing: no face is turned against the field. */
static void test_turned_slide(void **state)
{
    enum { n = 15, nv = n * n, nf = 2 * (n - 1) * (n - 1), AT = 7 * n + 7 };
    double Xin[3 * nv], X[3 * nv];
    int32_t F[3 * nf];
    int moved;
    (void)state;
    grid(n, Xin, F);
    memcpy(X, Xin, sizeof X);
    X[3 * AT] += 1.4;
    X[3 * AT + 1] += 0.4;
    X[3 * AT + 2] = 0.2;
    assert_true(grid_faces_down(X, F, nf) > 0);
    assert_int_equal(mcf__turned_repair(X, Xin, F, nf, nv, &moved, NULL), MCF_OK);
    print_message("slid vertex: moved %d, now (%.4f, %.4f, %.4f) from (7, 7, 0.2)\n", moved, X[3 * AT],
                  X[3 * AT + 1], X[3 * AT + 2]);
    assert_int_equal(moved, 1);
    assert_int_equal(grid_faces_down(X, F, nf), 0);
    assert_true(hypot(X[3 * AT] - 7.0, X[3 * AT + 1] - 7.0) < 0.05);
    tl_assert_near(X[3 * AT + 2], 0.2, 0.01, "the slid vertex's height");
    for (int i = 0; i < nv; i++)
        if (i != AT)
            assert_memory_equal(X + 3 * i, Xin + 3 * i, 3 * sizeof(double));
    double X1[3 * nv];
    memcpy(X1, X, sizeof X);
    assert_int_equal(mcf__turned_repair(X, Xin, F, nf, nv, &moved, NULL), MCF_OK);
    assert_int_equal(moved, 0);
    assert_memory_equal(X, X1, sizeof X);
}

/* An output with no face turned against its smoothed field (the grid with
 * every vertex raised by a smooth bump of height 0.3 and slid by 0.1
 * along x: every face still faces up) comes back bit for bit, though its
 * vertices are off their input's places along the surface: the repair
 * judges faces, not slides. */
static void test_turned_none(void **state)
{
    enum { n = 12, nv = n * n, nf = 2 * (n - 1) * (n - 1) };
    double Xin[3 * nv], X[3 * nv], X0[3 * nv];
    int32_t F[3 * nf];
    int moved;
    (void)state;
    grid(n, Xin, F);
    for (int i = 0; i < nv; i++) {
        double x = Xin[3 * i], y = Xin[3 * i + 1];
        X[3 * i] = x + 0.1;
        X[3 * i + 1] = y;
        X[3 * i + 2] = 0.3 * sin(x / 3.0) * cos(y / 4.0);
    }
    memcpy(X0, X, sizeof X);
    assert_int_equal(grid_faces_down(X, F, nf), 0);
    assert_int_equal(mcf__turned_repair(X, Xin, F, nf, nv, &moved, NULL), MCF_OK);
    assert_int_equal(moved, 0);
    assert_memory_equal(X, X0, sizeof X);
}

/* Faces of X whose normal points against the clean mesh's same face. */
static int flips_against(const mcf_mesh *m, const mcf_mesh *clean)
{
    const double *X = mcf_mesh_positions(m), *C = mcf_mesh_positions(clean);
    const int32_t *F = mcf_mesh_faces(m);
    int n = 0;
    for (int f = 0; f < mcf_mesh_nfaces(m); f++) {
        double a[3], b[3];
        normal_at_b(X, F + 3 * f, a);
        normal_at_b(C, F + 3 * f, b);
        n += dot(a, b) < 0.0;
    }
    return n;
}

/* bunny.drc quantized: every vertex rounded to a grid of step 0.5 mean
 * edges (offset 0.31, 0.62, 0.17 of a step), issue 31's `quant` model at
 * 0.5 h. Measured 2026-11-28: faces against the clean mesh's 25 in the
 * input, 115 in the default's result without the repair (this test
 * linked against a core whose mcf__flips_repair returns at once), 25
 * with it (flips_repaired 194); error 0.880 of the input's (0.878
 * without). The bounds: no more faces than the input's; the error below
 * 0.95 of the input's (the repair costs 0.2%; the rest is margin for
 * other changes to the filter). The quantized mesh and the clean one are
 * then turned by 0.7 rad about (1, 2, 2) / 3 alike, so that the
 * coordinates sit on no grid along the axes (the error stays 0.879; the
 * input's faces without area get areas of rounding size and either sign,
 * so the counts read 46 -> 43, repaired 194, where unturned 25 -> 25): on
 * the axes the default reads the grid's noise instead (mcf_lattice.c;
 * 2026-11-29: faces 25 -> 4, error 0.669 of the input's, no face left to
 * repair; test_core_lattice.c), and this test is the repair's. */
static void turn(mcf_mesh *m)
{
    const double u[3] = {1.0 / 3.0, 2.0 / 3.0, 2.0 / 3.0}, c = cos(0.7), sn = sin(0.7);
    double *X = mcf_mesh_positions_mut(m);
    for (int i = 0; i < mcf_mesh_nvertices(m); i++) {
        double x[3], ux[3] = {u[1] * X[3 * i + 2] - u[2] * X[3 * i + 1], u[2] * X[3 * i] - u[0] * X[3 * i + 2],
                              u[0] * X[3 * i + 1] - u[1] * X[3 * i]};
        double ud = u[0] * X[3 * i] + u[1] * X[3 * i + 1] + u[2] * X[3 * i + 2];
        memcpy(x, X + 3 * i, sizeof x);
        for (int d = 0; d < 3; d++)
            X[3 * i + d] = x[d] * c + ux[d] * sn + u[d] * ud * (1.0 - c);
    }
}

static void test_flips_quantized_scan(void **state)
{
    static const double off[3] = {0.31, 0.62, 0.17};
    mcf_mesh *clean = tl_load("bunny.drc");
    mcf_mesh_info info;
    mcf_compare_result c0, c1;
    mcf_flow_stats st;
    mcf_error err = {0};
    api_params ap;
    (void)state;
    assert_int_equal(mcf_mesh_inspect(clean, &info, NULL), MCF_OK);
    mcf_mesh *m = mcf_mesh_dup(clean, NULL);
    assert_non_null(m);
    double step = 0.5 * info.mean_edge, *X = mcf_mesh_positions_mut(m);
    for (int i = 0; i < mcf_mesh_nvertices(m); i++)
        for (int d = 0; d < 3; d++)
            X[3 * i + d] = off[d] * step + step * floor((X[3 * i + d] - off[d] * step) / step + 0.5);
    turn(m);
    turn(clean);
    int in_flips = flips_against(m, clean);
    assert_int_equal(mcf_compare(m, clean, &c0, NULL), MCF_OK);
    api_params_init(&ap);
    assert_int_equal(api_params_finish(&ap, mcf_mesh_nvertices(m), NULL, &err), MCF_OK);
    if (mcf_flow_run(m, &ap.flow, &st, &err) != MCF_OK)
        fail_msg("bunny.drc: %s", err.msg);
    assert_int_equal(mcf_compare(m, clean, &c1, NULL), MCF_OK);
    int out_flips = flips_against(m, clean);
    print_message("bunny.drc quantized to 0.5 h: faces against the clean mesh's %d -> %d, flips_repaired %d, "
                  "error/input %.3f\n", in_flips, out_flips, st.flips_repaired, c1.rms_m / c0.rms_m);
    assert_true(st.flips_repaired > 0);
    assert_true(out_flips <= in_flips);
    assert_true(c1.rms_m < 0.95 * c0.rms_m);
    mcf_flow_stats_free(&st);
    api_params_free(&ap);
    mcf_mesh_free(m);
    mcf_mesh_free(clean);
}

/* The drift repair end to end: car.drc (the repository's coarse CAD part
 * of long thin triangles) with Gaussian noise of 0.5 mean edges along the
 * normals (seed 1). Measured 2026-11-28: faces against the clean mesh's
 * 588 in the input, 564 in the default's result before the repair, 546
 * with it (turned_repaired 97); error 0.751 -> 0.741 of the input's
 * (mcf_compare's RMS). The bounds: fewer faces against the clean mesh
 * than the input had, the repair moved some vertices, the error below
 * 0.8 of the input's (a margin for other changes to the filter). About
 * 0.3 s. */
static void test_turned_cad(void **state)
{
    mcf_mesh *clean = tl_load("car.drc"), *m = mcf_mesh_dup(clean, NULL);
    mcf_compare_result c0, c1;
    mcf_flow_stats st;
    mcf_flow_params p;
    mcf_error err = {0};
    api_params ap;
    (void)state;
    assert_non_null(m);
    mcf_flow_params_init(&p);
    assert_int_equal(mcf_flow_add_noise(m, &p, 0.5, 1, NULL), MCF_OK);
    int in_flips = flips_against(m, clean);
    assert_int_equal(mcf_compare(m, clean, &c0, NULL), MCF_OK);
    api_params_init(&ap);
    assert_int_equal(api_params_finish(&ap, mcf_mesh_nvertices(m), NULL, &err), MCF_OK);
    if (mcf_flow_run(m, &ap.flow, &st, &err) != MCF_OK)
        fail_msg("car.drc: %s", err.msg);
    assert_int_equal(mcf_compare(m, clean, &c1, NULL), MCF_OK);
    int out_flips = flips_against(m, clean);
    print_message("car.drc normal 0.5 h: faces against the clean mesh's %d -> %d, turned_repaired %d, error/input %.3f\n",
                  in_flips, out_flips, st.turned_repaired, c1.rms_m / c0.rms_m);
    assert_true(st.turned_repaired > 0);
    assert_true(out_flips < in_flips);
    assert_true(c1.rms_m < 0.8 * c0.rms_m);
    mcf_flow_stats_free(&st);
    api_params_free(&ap);
    mcf_mesh_free(m);
    mcf_mesh_free(clean);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_flips_collapsed_edge),
        cmocka_unit_test(test_flips_grid_angle),
        cmocka_unit_test(test_flips_grid_sliver),
        cmocka_unit_test(test_flips_grid_wide),
        cmocka_unit_test(test_flips_reference),
        cmocka_unit_test(test_flips_none),
        cmocka_unit_test(test_turned_slide),
        cmocka_unit_test(test_turned_none),
        cmocka_unit_test(test_flips_quantized_scan),
        cmocka_unit_test(test_turned_cad),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
