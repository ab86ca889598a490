/* SPDX-License-Identifier: MIT */
/*
 * test_core_threads.c - the threads of the fairing filters' passes
 * (core/mcf_par.c, mcf_flow_params.threads, issue 27): mcf__par_for
 * covers its range exactly once whatever the thread count, and the
 * explicit passes give the same result with 1, 2 and 3 threads as with
 * one, bit for bit (each thread writes only its own vertices, each in the
 * order one thread would: no tolerance is needed, none is allowed). A
 * 40,962-vertex icosphere (over MCF_PAR_MIN, so the threads do run) with
 * noise 0.25 mean edges; about 4 s of CPU.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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
            mcf__par_for(t, sizes[s], count_range, hits);
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
static int explicit_run(int threads, int iterations, double *X, int nv)
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
        int k1 = explicit_run(1, it, X1, NV);
        assert_true(k1 > 0); /* the noise was found and removed */
        /* 2 threads (3 on the shorter run: uneven ranges) */
        int t = it ? 3 : 2, kt = explicit_run(t, it, Xt, NV);
        assert_int_equal(kt, k1);
        assert_memory_equal(Xt, X1, 3 * sizeof(double) * NV);
    }
    free(X1);
    free(Xt);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_par_for_covers),
        cmocka_unit_test(test_passes_one_thread_equal),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
