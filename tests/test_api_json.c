/* SPDX-License-Identifier: MIT */
/*
 * test_api_json.c - the JSON builders of api_json.c: every field carries
 * the value of the struct it came from (checked after printing and
 * parsing back, so what a client reads is what is tested), non-finite
 * numbers and a meaningless genus become null, the per-step log appears
 * exactly when one was kept, and the scheme list covers every scheme.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"
#include "../api/api.h"

/* Prints j (compact or pretty), parses it back, and frees j. */
static cJSON *reparse(cJSON *j, int pretty)
{
    char *s;
    cJSON *r;
    assert_non_null(j);
    s = api_json_print(j, pretty);
    assert_non_null(s);
    if (pretty)
        assert_non_null(strchr(s, '\n'));
    else
        assert_null(strchr(s, '\n'));
    r = cJSON_Parse(s);
    assert_non_null(r);
    free(s);
    cJSON_Delete(j);
    return r;
}

static double get(const cJSON *o, const char *path)
{
    char key[64];
    const char *dot;
    const cJSON *c = o;
    while ((dot = strchr(path, '.')) != NULL) {
        memcpy(key, path, (size_t)(dot - path));
        key[dot - path] = '\0';
        c = cJSON_GetObjectItemCaseSensitive(c, key);
        if (!c)
            fail_msg("no object '%s'", key);
        path = dot + 1;
    }
    c = cJSON_GetObjectItemCaseSensitive(c, path);
    if (!c || !cJSON_IsNumber(c))
        fail_msg("no number '%s'", path);
    return c->valuedouble;
}

/* cJSON 1.7.15 prints 15 significant digits and falls back to 17 only
 * when the 15-digit text reads back more than DBL_EPSILON (relative) off,
 * so a printed value may differ from the struct by one relative epsilon;
 * 2 DBL_EPSILON * |b| covers that and nothing coarser. */
static void same(double a, double b, const char *what)
{
    tl_assert_near(a, b, 2.0 * 2.220446049250313e-16 * fabs(b), what);
}

static void test_mesh_info(void **state)
{
    mcf_mesh *m = tl_load("sphere_cgal.obj");
    mcf_mesh_info info;
    mcf_curvature_summary cs;
    mcf_error err;
    cJSON *j;
    (void)state;
    assert_int_equal(mcf_mesh_inspect(m, &info, &err), MCF_OK);
    assert_int_equal(mcf_curvature_summarize(m, &cs, &err), MCF_OK);
    j = reparse(api_json_mesh_info(&info, &cs), 1);
    same(get(j, "vertices"), 812, "vertices");
    same(get(j, "faces"), 1620, "faces");
    same(get(j, "edges"), 2430, "edges");
    same(get(j, "euler"), 2, "euler");
    same(get(j, "genus"), 0, "genus");
    same(get(j, "components"), 1, "components");
    same(get(j, "boundary_edges"), 0, "boundary_edges");
    assert_true(cJSON_IsTrue(cJSON_GetObjectItem(j, "closed")));
    assert_true(cJSON_IsTrue(cJSON_GetObjectItem(j, "manifold")));
    same(get(j, "area"), info.area, "area");
    same(get(j, "volume"), info.volume, "volume");
    same(get(j, "edge_length.mean"), info.mean_edge, "mean edge");
    same(get(j, "edge_length.min"), info.min_edge, "min edge");
    same(cJSON_GetArrayItem(cJSON_GetObjectItem(cJSON_GetObjectItem(j, "bbox"), "max"), 2)->valuedouble,
         info.bbox_max[2], "bbox max z");
    same(get(j, "curvature.H.mean"), cs.H.mean, "H mean");
    same(get(j, "curvature.H.p95"), cs.H.p95, "H p95");
    same(get(j, "curvature.K.rms"), cs.K.rms, "K rms");
    same(get(j, "curvature.A2.max"), cs.A2.max, "A2 max");
    same(get(j, "curvature.total_K"), cs.total_K, "total K");
    same(get(j, "curvature.gauss_bonnet"), cs.gauss_bonnet, "gauss_bonnet");
    cJSON_Delete(j);

    /* Without curvature there is no "curvature" member; genus -1 is null. */
    info.genus = -1;
    info.area = NAN;
    j = reparse(api_json_mesh_info(&info, NULL), 0);
    assert_null(cJSON_GetObjectItem(j, "curvature"));
    assert_true(cJSON_IsNull(cJSON_GetObjectItem(j, "genus")));
    assert_true(cJSON_IsNull(cJSON_GetObjectItem(j, "area")));
    cJSON_Delete(j);
    mcf_mesh_free(m);
}

static void test_flow_stats(void **state)
{
    mcf_step_log log[3] = {
        {0.1, 0.1, 3.0, 1.0, 0.01, 0.001, 0},
        {0.3, 0.2, 2.5, 0.9, 0.02, 0.002, 2},
        {0.6, 0.3, 2.0, 0.8, 0.03, 0.003, 1},
    };
    mcf_flow_stats st;
    cJSON *j, *l;
    (void)state;
    memset(&st, 0, sizeof st);
    st.steps = 3;
    st.rejected = 3;
    st.solves = 6;
    st.factorizations = 3;
    st.t_final = 0.6;
    st.dt_first = 0.1;
    st.dt_min = 0.1;
    st.dt_max = 0.3;
    st.area0 = 3.5;
    st.area1 = 2.0;
    st.volume0 = 1.1;
    st.volume1 = 0.8;
    st.time_assemble = 0.25;
    st.time_analyze = 0.125;
    st.time_factorize = 0.5;
    st.time_solve = 0.0625;
    st.time_total = 1.5;
    st.peak_bytes = 123456789;
    st.log = log;
    st.nlog = 3;
    j = reparse(api_json_flow_stats(&st), 0);
    same(get(j, "steps"), 3, "steps");
    same(get(j, "rejected"), 3, "rejected");
    same(get(j, "solves"), 6, "solves");
    same(get(j, "t_final"), 0.6, "t_final");
    same(get(j, "dt_max"), 0.3, "dt_max");
    same(get(j, "area1"), 2.0, "area1");
    same(get(j, "peak_bytes"), 123456789, "peak_bytes");
    same(get(j, "timings.factorize_s"), 0.5, "factorize");
    same(get(j, "timings.total_s"), 1.5, "total");
    l = cJSON_GetObjectItem(j, "log");
    assert_int_equal(cJSON_GetArraySize(l), 3);
    same(get(cJSON_GetArrayItem(l, 1), "dt"), 0.2, "log dt");
    same(get(cJSON_GetArrayItem(l, 1), "rejected"), 2, "log rejected");
    same(get(cJSON_GetArrayItem(l, 2), "max_disp"), 0.03, "log max_disp");
    cJSON_Delete(j);
    st.log = NULL;
    st.nlog = 0;
    j = reparse(api_json_flow_stats(&st), 1);
    assert_null(cJSON_GetObjectItem(j, "log"));
    /* nothing read, the scheme desbrun2 (memset: filter 0): nulls */
    assert_true(cJSON_IsNull(cJSON_GetObjectItem(j, "noise_kind")));
    assert_true(cJSON_IsNull(cJSON_GetObjectItem(j, "noise_share")));
    assert_true(cJSON_IsNull(cJSON_GetObjectItem(j, "noise_direction")));
    assert_true(cJSON_IsFalse(cJSON_GetObjectItem(j, "robust")));
    assert_string_equal(cJSON_GetObjectItem(j, "filter")->valuestring, mcf_scheme_get((mcf_scheme)0)->name);
    cJSON_Delete(j);
    {
        /* the default request's reading of one viewpoint's noise */
        static const char *const kind[] = {"given", "normal", "isotropic", "one_direction", "correlated"};
        for (int k = MCF_NOISE_GIVEN; k <= MCF_NOISE_CORRELATED; k++) {
            st.robust = 1;
            st.noise_kind = k;
            st.noise_share = 0.875;
            st.noise_direction[0] = 0.6;
            st.noise_direction[1] = 0.0;
            st.noise_direction[2] = -0.8;
            st.spikes_repaired = 7;
            st.filter = MCF_FAIRING_EXPLICIT;
            j = reparse(api_json_flow_stats(&st), 0);
            assert_string_equal(cJSON_GetObjectItem(j, "noise_kind")->valuestring, kind[k - MCF_NOISE_GIVEN]);
            same(get(j, "noise_share"), 0.875, "noise_share");
            assert_true(cJSON_IsTrue(cJSON_GetObjectItem(j, "robust")));
            same(get(j, "spikes_repaired"), 7, "spikes_repaired");
            assert_string_equal(cJSON_GetObjectItem(j, "filter")->valuestring, "fairing_explicit");
            l = cJSON_GetObjectItem(j, "noise_direction");
            if (k == MCF_NOISE_ONE_DIRECTION) {
                assert_int_equal(cJSON_GetArraySize(l), 3);
                same(cJSON_GetArrayItem(l, 0)->valuedouble, 0.6, "direction x");
                same(cJSON_GetArrayItem(l, 2)->valuedouble, -0.8, "direction z");
            } else {
                assert_true(cJSON_IsNull(l));
            }
            cJSON_Delete(j);
        }
        memset(&st, 0, sizeof st);
    }
    {
        /* A long run's log: API_LOG_MAX entries, the first and last steps
         * and evenly spaced ones between, each with its step. */
        enum { N = 2 * API_LOG_MAX + 501 };
        mcf_step_log *big = calloc(N, sizeof *big);
        int k, prev = 0;
        assert_non_null(big);
        for (k = 0; k < N; k++)
            big[k].t = k + 1;
        st.log = big;
        st.nlog = N;
        j = reparse(api_json_flow_stats(&st), 0);
        l = cJSON_GetObjectItem(j, "log");
        assert_int_equal(cJSON_GetArraySize(l), API_LOG_MAX);
        for (k = 0; k < API_LOG_MAX; k++) {
            int step = (int)get(cJSON_GetArrayItem(l, k), "step");
            same(get(cJSON_GetArrayItem(l, k), "t"), step, "log t");
            /* strides of 2 or 3 steps: evenly spaced */
            assert_true(k == 0 ? step == 1 : step - prev >= 2 && step - prev <= 3);
            prev = step;
        }
        assert_int_equal(prev, N);
        cJSON_Delete(j);
        st.log = NULL;
        st.nlog = 0;
        free(big);
    }
}

static void test_compare(void **state)
{
    mcf_compare_result c = {0.125, 0.0625, 3.5, 0.75, 12.5, 4};
    cJSON *j;
    (void)state;
    j = reparse(api_json_compare(&c), 0);
    same(get(j, "rms_m"), 0.125, "rms_m");
    same(get(j, "rms_rel"), 0.0625, "rms_rel");
    same(get(j, "frobenius"), 3.5, "frobenius");
    same(get(j, "max_err"), 0.75, "max_err");
    same(get(j, "normal_angle_deg"), 12.5, "angle");
    same(get(j, "inverted_faces"), 4, "inverted");
    cJSON_Delete(j);
    c.rms_rel = INFINITY;
    j = reparse(api_json_compare(&c), 0);
    assert_true(cJSON_IsNull(cJSON_GetObjectItem(j, "rms_rel")));
    cJSON_Delete(j);
}

static void test_schemes(void **state)
{
    cJSON *j, *a;
    int s;
    (void)state;
    j = reparse(api_json_schemes(), 1);
    a = cJSON_GetObjectItem(j, "schemes");
    assert_int_equal(cJSON_GetArraySize(a), MCF_NSCHEMES);
    for (s = 0; s < MCF_NSCHEMES; s++) {
        const mcf_scheme_info *si = mcf_scheme_get((mcf_scheme)s);
        const cJSON *e = cJSON_GetArrayItem(a, s), *stab;
        assert_string_equal(cJSON_GetObjectItem(e, "name")->valuestring, si->name);
        same(get(e, "order"), si->order, "order");
        same(get(e, "cost_per_step.solves"), si->solves_per_step, "solves");
        same(get(e, "cost_per_step.factorizations"), si->factorizations_per_step, "facts");
        assert_int_equal(cJSON_IsTrue(cJSON_GetObjectItem(e, "explicit")), si->is_explicit != 0);
        assert_int_equal(cJSON_IsTrue(cJSON_GetObjectItem(e, "adaptive")), si->has_estimate != 0);
        stab = cJSON_GetObjectItem(e, "stability");
        if (si->stability > 0)
            same(stab->valuedouble, si->stability, "stability");
        else
            assert_string_equal(stab->valuestring, "unconditional");
        assert_non_null(cJSON_GetObjectItem(e, "best_use"));
    }
    cJSON_Delete(j);
    assert_null(api_json_print(NULL, 0));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_mesh_info),
        cmocka_unit_test(test_flow_stats),
        cmocka_unit_test(test_compare),
        cmocka_unit_test(test_schemes),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
