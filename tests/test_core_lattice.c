/* SPDX-License-Identifier: MIT */
/*
 * test_core_lattice.c - quantized positions (docs/fairing.md, "Quantized
 * positions"):
 *  - mcf__lattice against the grids the test builds itself: the step it
 *    rounded to on each axis, levels left empty (a greatest common
 *    divisor, not the least gap), and no grid where one coordinate is off
 *    it, where the step is coarser than the mean edge or one axis is flat;
 *  - mcf__lattice_clip against the clamp written out per coordinate, and
 *    its promise: no vertex ends further from a truth inside its cell;
 *  - end to end: car.drc and blade.obj (in $MCF_MESHES; skipped by name
 *    without them) rounded to a grid, through the default request: the
 *    noise read is the grid's (q / sqrt 12), every vertex stays in its
 *    cell, the error falls and no more faces face against the clean mesh
 *    than the input's.
 * Runs in about 5 s (blade.obj 4 s of it).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "api.h"
#include "mcf_internal.h" /* mcf__lattice, mcf__lattice_clip */
#include "testlib.h"

/* n values k_i q + a along one axis of X (the other two on steps qy, qz),
 * k_i drawn from {0, 3, 5, 8, ...}: gaps of 2, 3 and 5 steps, none of
 * one. mcf__lattice returns q (to 1e-12 of it: a remainder of doubles of
 * size 100, a few roundings), not the least gap 2 q. */
static void test_lattice_steps(void **state)
{
    enum { N = 400 };
    static const int K[] = {0, 3, 5, 8, 13, 15, 18, 23};
    (void)state;
    double X[3 * N], step[3];
    const double q[3] = {0.037, 0.1, 0.25}, a[3] = {0.0123, -3.7, 11.0}, hbar = 1.0;
    uint64_t r = 7;
    for (int i = 0; i < N; i++) {
        X[3 * i] = a[0] + q[0] * (K[i % 8] + 23 * (i / 8));
        X[3 * i + 1] = a[1] + q[1] * floor(40.0 * tl_uniform01(&r));
        X[3 * i + 2] = a[2] + q[2] * floor(10.0 * tl_uniform01(&r));
    }
    assert_int_equal(mcf__lattice(X, N, NULL, hbar, step), 1);
    for (int d = 0; d < 3; d++)
        tl_assert_near(step[d], q[d], 1e-12 * q[d], "the grid step");
    /* the vertices fixed are not read: one off the grid, fixed */
    unsigned char fixed[N] = {0};
    X[3 * 17 + 1] += 0.3 * q[1];
    fixed[17] = 1;
    assert_int_equal(mcf__lattice(X, N, fixed, hbar, step), 1);
    /* ... but free, five of them (more than 1%) off by (e - 2) q: their
     * gaps share no divisor above 1e-3 hbar with the grid's, so no grid
     * on that axis (0.3 q would make a finer grid of 0.1 q, which is one) */
    double saved[5];
    for (int i = 0; i < 5; i++) {
        saved[i] = X[3 * (40 * i + 1) + 1];
        X[3 * (40 * i + 1) + 1] += 0.718281828459045 * q[1];
    }
    assert_int_equal(mcf__lattice(X, N, fixed, hbar, step), 0);
    assert_true(step[0] == 0.0 && step[1] == 0.0 && step[2] == 0.0);
    for (int i = 0; i < 5; i++)
        X[3 * (40 * i + 1) + 1] = saved[i];
    /* a step coarser than 0.6 mean edges is a design, not a grid */
    assert_int_equal(mcf__lattice(X, N, fixed, 0.4, step), 0);
    /* one axis flat (a single level): no grid read on it */
    for (int i = 0; i < N; i++)
        X[3 * i + 2] = a[2];
    assert_int_equal(mcf__lattice(X, N, fixed, hbar, step), 0);
}

/* mcf__lattice_clip against each coordinate clamped to [x0 - q/2, x0 +
 * q/2] written out here (exact: the same two comparisons), the fixed
 * vertices untouched; and for a truth t in the cell, |clip(x) - t| <=
 * |x - t| for every vertex (a projection onto a box holding t). */
static void test_lattice_clip(void **state)
{
    enum { N = 500 };
    (void)state;
    double X[3 * N], X0[3 * N], T[3 * N], Y[3 * N];
    const double q[3] = {0.2, 0.05, 0.7};
    unsigned char fixed[N] = {0};
    uint64_t r = 11;
    for (int i = 0; i < N; i++) {
        fixed[i] = i % 7 == 0;
        for (int d = 0; d < 3; d++) {
            X0[3 * i + d] = q[d] * floor(20.0 * tl_uniform01(&r));
            T[3 * i + d] = X0[3 * i + d] + q[d] * (tl_uniform01(&r) - 0.5);
            X[3 * i + d] = X0[3 * i + d] + 2.0 * q[d] * tl_gauss01(&r);
        }
    }
    memcpy(Y, X, sizeof X);
    mcf__lattice_clip(Y, X0, N, fixed, q);
    for (int i = 0; i < N; i++) {
        double dy = 0.0, dx = 0.0;
        for (int d = 0; d < 3; d++) {
            double x = X[3 * i + d], lo = X0[3 * i + d] - 0.5 * q[d], hi = X0[3 * i + d] + 0.5 * q[d];
            double want = fixed[i] ? x : x < lo ? lo : x > hi ? hi : x;
            assert_true(Y[3 * i + d] == want);
            dy += (Y[3 * i + d] - T[3 * i + d]) * (Y[3 * i + d] - T[3 * i + d]);
            dx += (x - T[3 * i + d]) * (x - T[3 * i + d]);
        }
        assert_true(dy <= dx);
    }
}

static double rms(const mcf_mesh *m, const mcf_mesh *clean)
{
    mcf_compare_result r;
    assert_int_equal(mcf_compare(m, clean, &r, NULL), MCF_OK);
    return r.rms_m;
}

/* NAME rounded to a grid of rho mean edges (offset rho/3 per axis, every
 * vertex) through the default request: the noise read is the grid's,
 * q / sqrt(12), along the normals and in the tangent planes alike (within
 * 2% over mcf_mesh_inspect's mean edge of the quantized mesh: the run's
 * own mean edge is another count of the edges, 0.6% apart on the
 * non-manifold car.drc); every vertex within its cell (1e-9 h: the
 * normalization undone); the error over the input's at most max_ratio;
 * faces against the clean mesh at most max_new more than the input's. */
static void quantized_case(const char *name, double rho, double max_ratio, int max_new)
{
    mcf_mesh *clean = tl_load(name), *q = mcf_mesh_dup(clean, NULL);
    mcf_mesh_info info;
    api_params ap;
    mcf_flow_stats st;
    mcf_error err = {0};
    assert_non_null(q);
    assert_int_equal(mcf_mesh_inspect(clean, &info, NULL), MCF_OK);
    int nv = mcf_mesh_nvertices(clean);
    double step = rho * info.mean_edge, off = step / 3.0, *X = mcf_mesh_positions_mut(q);
    for (int i = 0; i < 3 * nv; i++)
        X[i] = off + step * floor((X[i] - off) / step + 0.5);
    mcf_mesh *q0 = mcf_mesh_dup(q, NULL);
    assert_non_null(q0);
    mcf_mesh_info qi;
    assert_int_equal(mcf_mesh_inspect(q0, &qi, NULL), MCF_OK);
    api_params_init(&ap);
    assert_int_equal(api_params_finish(&ap, nv, NULL, &err), MCF_OK);
    if (mcf_flow_run(q, &ap.flow, &st, &err) != MCF_OK)
        fail_msg("%s", err.msg);
    api_params_free(&ap);
    double e0 = rms(q0, clean), e1 = rms(q, clean);
    int f0 = tl_flips_against(q0, clean), f1 = tl_flips_against(q, clean);
    print_message("%s quantized %.2f h: noise read %.4f (grid %.4f), K=%d, error %.4f of the input's, "
                  "faces against the clean mesh %d -> %d\n",
                  name, rho, st.noise, step / sqrt(12.0) / qi.mean_edge, st.steps, e1 / e0, f0, f1);
    tl_assert_near(st.noise / (step / sqrt(12.0) / qi.mean_edge), 1.0, 0.02, "the grid's noise");
    assert_true(st.noise_tangential == st.noise);
    assert_int_equal(st.spikes_repaired, 0);
    const double *Y = mcf_mesh_positions(q), *Y0 = mcf_mesh_positions(q0);
    for (int i = 0; i < 3 * nv; i++)
        assert_true(fabs(Y[i] - Y0[i]) <= 0.5 * step + 1e-9 * info.mean_edge);
    assert_true(e1 <= max_ratio * e0);
    assert_true(f1 <= f0 + max_new);
    mcf_flow_stats_free(&st);
    mcf_mesh_free(q);
    mcf_mesh_free(q0);
    mcf_mesh_free(clean);
}

/* Measured (2026-11-29, this quantization): blade.obj at 0.25 h 0.55 of
 * the input's error (the tangential step: the plates' in-plane rounding;
 * without it 0.99), faces against the clean mesh 0 -> 0; the bound 0.7.
 * car.drc at 0.25 h (920 vertices, 72% of them on creases, where one
 * implicit step is known to cost: docs/fairing.md, "The amount") is the
 * case where the grid's reading does not pay: 1.021, faces 11 -> 12,
 * where the input came back before; the bounds 1.03 and one face state
 * that, and hold the read level and the cells. blade.obj at 0.5 h: the
 * thin rim's two sides fall on neighbouring levels and its faces,
 * degenerate in the input, came back facing against the clean mesh by
 * the hundred (0 -> 111) with the flips repair's 60 degrees; on a grid it
 * keeps an invented orientation within 41 (core/mcf_flips.c): 0 -> 2,
 * error 0.718 of the input's (0.714 before); within 63 of the input's
 * normal over 3 rings as well: 0 -> 0, error 0.7179 (2026-11-29); the
 * bounds 0.75 and no face more than the input (issue 31's bar). */
static void test_quantized_end_to_end(void **state)
{
    (void)state;
    tl_need_mesh("car.drc");
    tl_need_mesh("blade.obj");
    quantized_case("blade.obj", 0.25, 0.7, 0);
    quantized_case("blade.obj", 0.5, 0.75, 0);
    quantized_case("car.drc", 0.25, 1.03, 1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_lattice_steps),
        cmocka_unit_test(test_lattice_clip),
        cmocka_unit_test(test_quantized_end_to_end),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
