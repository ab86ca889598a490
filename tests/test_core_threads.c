/* SPDX-License-Identifier: MIT */
/*
 * test_core_threads.c - the threads of the fairing filters' passes
 * (core/mcf_par.c, mcf_flow_params.threads, issue 27): mcf__par_for
 * covers its range exactly once whatever the thread count, and the
 * explicit passes give the same result with 1, 2 and 3 threads as with
 * one, bit for bit (each thread writes only its own vertices, each in the
 * order one thread would: no tolerance is needed, none is allowed). A
 * 40,962-vertex icosphere (over MCF_PAR_MIN, so the threads do run) with
 * noise 0.25 mean edges; about 4 s of CPU. The passes' column counts give
 * the same columns bit for bit (test_passes_columns_split). The threads'
 * CPU is counted for the caller (mcf_flow_stats.threads_cpu_s: mcfd's
 * per-job CPU budget, issue 28): test_threads_cpu_counted.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "mcf_internal.h"
#include "testlib.h"
#include "../api/api.h"

static void count_range(void *ctx, size_t lo, size_t hi)
{
    unsigned char *hits = ctx;
    for (size_t i = lo; i < hi; i++)
        hits[i]++;
}

static void test_par_for_covers(void **state)
{
    static const size_t sizes[] = {0, 1, MCF_PAR_MIN - 1, MCF_PAR_MIN, 100003};
    (void)state;
    for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++)
        for (int t = 0; t <= 5; t++) {
            unsigned char *hits = calloc(sizes[s] + 1, 1);
            assert_non_null(hits);
            mcf__par_for(t, NULL, sizes[s], count_range, hits);
            for (size_t i = 0; i < sizes[s]; i++)
                if (hits[i] != 1)
                    fail_msg("n %zu, %d threads: item %zu run %d times", sizes[s], t, i, hits[i]);
            assert_int_equal(hits[sizes[s]], 0);
            free(hits);
        }
}

/* The explicit passes (api_params_finish with the scheme named) on a
 * noisy icosphere, on `threads` threads, as many as SURE says (nine
 * columns: the positions and six probes) or `iterations` (three): the
 * result's positions into X (3 nv), its step count returned. */
static int explicit_run(int threads, int iterations, double *X, int nv, double *threads_cpu_s)
{
    mcf_error err = {0};
    mcf_mesh *m = mcf_mesh_new_icosphere(6, 1.0, &err);
    api_params ap;
    mcf_flow_stats st;
    int steps;
    assert_non_null(m);
    assert_int_equal(mcf_mesh_nvertices(m), nv);
    api_params_init(&ap);
    assert_int_equal(api_params_set(&ap, "scheme", "fairing_explicit", NULL, &err), MCF_OK);
    if (iterations > 0) {
        char it[16];
        snprintf(it, sizeof it, "%d", iterations);
        assert_int_equal(api_params_set(&ap, "iterations", it, NULL, &err), MCF_OK);
    }
    assert_int_equal(mcf_flow_add_noise(m, &ap.flow, 0.25, 7, &err), MCF_OK);
    assert_int_equal(api_params_finish(&ap, nv, NULL, &err), MCF_OK);
    ap.flow.threads = threads;
    if (mcf_flow_run(m, &ap.flow, &st, &err) != MCF_OK)
        fail_msg("fairing_explicit on %d threads: %s", threads, err.msg);
    memcpy(X, mcf_mesh_positions(m), 3 * sizeof(double) * (size_t)nv);
    steps = st.steps;
    if (threads_cpu_s)
        *threads_cpu_s = st.threads_cpu_s;
    mcf_flow_stats_free(&st);
    api_params_free(&ap);
    mcf_mesh_free(m);
    return steps;
}

static void test_passes_one_thread_equal(void **state)
{
    enum { NV = 40962 }; /* icosphere level 6: 10 4^6 + 2 */
    double *X1 = malloc(3 * sizeof(double) * NV), *Xt = malloc(3 * sizeof(double) * NV);
    (void)state;
    assert_true(X1 && Xt);
    for (int it = 0; it <= 12; it += 12) {
        int k1 = explicit_run(1, it, X1, NV, NULL);
        assert_true(k1 > 0); /* the noise was found and removed */
        /* 2 threads (3 on the shorter run: uneven ranges) */
        int t = it ? 3 : 2, kt = explicit_run(t, it, Xt, NV, NULL);
        assert_int_equal(kt, k1);
        assert_memory_equal(Xt, X1, 3 * sizeof(double) * NV);
    }
    free(X1);
    free(Xt);
}

/* A range's work that costs CPU in proportion to its length: sums of
 * a hash (stored, so the loop is not optimized away). */
static void busy_range(void *ctx, size_t lo, size_t hi)
{
    uint64_t acc = 0;
    volatile uint64_t sink;
    (void)ctx;
    for (size_t i = lo; i < hi; i++)
        for (uint64_t k = 0; k < 64; k++)
            acc += mcf__mix64(i * 64 + k);
    sink = acc;
    (void)sink;
}

static double own_cpu(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* mcf__par_for adds the CPU seconds of the threads it starts, never the
 * caller's: none on one thread or below MCF_PAR_MIN items; on 4 threads,
 * three ranges as long as the caller's own. The caller's own range is
 * measured on its clock around the call (it also waits in the join,
 * which costs no CPU), so the helpers' sum is about 3x it: asserted
 * within [1.5x, 6x], room for the scheduling noise of a loaded machine
 * (thread start-up, cache misses), never a time bound. Then the explicit
 * fairing passes on 2 threads report their helper's CPU in
 * mcf_flow_stats.threads_cpu_s (0 on one thread). */
static void test_threads_cpu_counted(void **state)
{
    enum { NV = 40962, N = 4 * MCF_PAR_MIN * 16 };
    double cpu = 0.0, c0, own;
    (void)state;
    mcf__par_for(1, &cpu, N, busy_range, NULL);
    assert_true(cpu == 0.0);
    mcf__par_for(4, &cpu, MCF_PAR_MIN - 1, busy_range, NULL);
    assert_true(cpu == 0.0);
    c0 = own_cpu();
    mcf__par_for(4, &cpu, N, busy_range, NULL);
    own = own_cpu() - c0;
    print_message("    4 threads: the caller's range %.3f s of CPU, the three others' %.3f s\n",
                  own, cpu);
    assert_true(own > 0.0);
    assert_true(cpu >= 1.5 * own && cpu <= 6.0 * own);

    double *X = malloc(3 * sizeof(double) * NV), t1 = -1.0, t2 = -1.0;
    assert_non_null(X);
    explicit_run(1, 12, X, NV, &t1);
    explicit_run(2, 12, X, NV, &t2);
    print_message("    12 explicit passes, 40,962 vertices: threads_cpu_s %.3f on 1 thread, "
                  "%.3f on 2\n", t1, t2);
    assert_true(t1 == 0.0);
    assert_true(t2 > 0.0);
    free(X);
}

/* The passes' column counts (mcf_graph.c: unrolled for 3, 6 and 9, any
 * other by a loop; the fairing filter moves 6 on a mesh of over a million
 * vertices, 9 otherwise): Taubin passes on 9 columns equal, bit for bit,
 * the same passes on the columns split 6 + 3, 3 + 3 + 3 and 4 + 4 + 1 (each
 * column's sums run in the same order whatever the others), some vertices
 * fixed, on 1 and 2 threads. An icosphere of 40,962 vertices, 3 passes. */
static void test_passes_columns_split(void **state)
{
    static const int splits[3][4] = {{6, 3, 0}, {3, 3, 3, 0}, {4, 4, 1, 0}};
    mcf_error err;
    mcf__graph g;
    (void)state;
    mcf_mesh *m = mcf_mesh_new_icosphere(6, 1.0, &err);
    assert_non_null(m);
    int nv = mcf_mesh_nvertices(m);
    assert_int_equal(mcf__graph_build(mcf_mesh_faces(m), mcf_mesh_nfaces(m), nv, &g, &err), MCF_OK);
    size_t n9 = 9 * (size_t)nv;
    double *Z = malloc(sizeof(double) * n9), *Zs = malloc(sizeof(double) * n9);
    double *P = malloc(sizeof(double) * n9), *tmp = malloc(sizeof(double) * n9);
    unsigned char *fixed = calloc((size_t)nv, 1);
    assert_true(Z && Zs && P && tmp && fixed);
    for (size_t i = 0; i < n9; i++)
        Z[i] = (double)(mcf__mix64(i + 1) >> 11) / 9007199254740992.0 - 0.5;
    for (int i = 0; i < nv; i += 97)
        fixed[i] = 1;
    memcpy(Zs, Z, sizeof(double) * n9);
    mcf__graph_taubin(&g, fixed, Z, 9, 3, tmp, 1, NULL);
    for (int s = 0; s < 3; s++)
        for (int t = 1; t <= 2; t++) {
            int c0 = 0;
            for (int b = 0; splits[s][b]; c0 += splits[s][b++]) {
                int nc = splits[s][b];
                for (int i = 0; i < nv; i++)
                    memcpy(P + (size_t)nc * i, Zs + 9 * (size_t)i + c0, sizeof(double) * nc);
                mcf__graph_taubin(&g, fixed, P, nc, 3, tmp, t, NULL);
                for (int i = 0; i < nv; i++)
                    if (memcmp(P + (size_t)nc * i, Z + 9 * (size_t)i + c0, sizeof(double) * nc))
                        fail_msg("split %d, columns %d..%d, %d threads: vertex %d differs", s, c0,
                                 c0 + nc - 1, t, i);
            }
        }
    mcf__graph_free(&g);
    mcf_mesh_free(m);
    free(Z);
    free(Zs);
    free(P);
    free(tmp);
    free(fixed);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_par_for_covers),
        cmocka_unit_test(test_passes_one_thread_equal),
        cmocka_unit_test(test_passes_columns_split),
        cmocka_unit_test(test_threads_cpu_counted),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
