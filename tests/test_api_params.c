/* SPDX-License-Identifier: MIT */
/*
 * test_api_params.c - job parameters (api_params.c): every key accepted
 * and refused, the three sources (api_params_set, JSON, query string)
 * giving the same result and the same error text, JSON size and depth
 * limits, percent-decoding, api_params_finish's combined checks and the
 * JSON form parsing back to the same parameters.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"
#include "../api/api.h"

static api_limits L;

static int setup(void **state)
{
    (void)state;
    api_limits_default(&L);
    return 0;
}

/* key=value must be accepted by all three sources. */
static void ok3(const char *key, const char *val, api_params *out)
{
    api_params a, b, c;
    mcf_error err;
    char json[512], qs[512];

    api_params_init(&a);
    api_params_init(&b);
    api_params_init(&c);
    if (api_params_set(&a, key, val, &L, &err) != MCF_OK)
        fail_msg("set %s=%s: %s", key, val, err.msg);
    snprintf(json, sizeof json, "{\"%s\": \"%s\"}", key, val);
    if (api_params_parse_json(&b, json, strlen(json), &L, &err) != MCF_OK)
        fail_msg("json %s: %s", json, err.msg);
    snprintf(qs, sizeof qs, "%s=%s", key, val);
    if (api_params_parse_query(&c, qs, NULL, &L, &err) != MCF_OK)
        fail_msg("query %s: %s", qs, err.msg);
    /* Same scalar fields from every source (fixed_owned differs). */
    assert_memory_equal(&a.encode, &b.encode, sizeof a.encode);
    assert_memory_equal(&a.encode, &c.encode, sizeof a.encode);
    assert_int_equal(a.flow.nfixed, b.flow.nfixed);
    assert_int_equal(a.flow.nfixed, c.flow.nfixed);
    if (a.flow.nfixed) {
        assert_memory_equal(a.flow.fixed, b.flow.fixed, sizeof(int32_t) * (size_t)a.flow.nfixed);
        assert_memory_equal(a.flow.fixed, c.flow.fixed, sizeof(int32_t) * (size_t)a.flow.nfixed);
    }
    assert_true(a.flow.dt == b.flow.dt && a.flow.dt == c.flow.dt);
    assert_true(a.flow.time == b.flow.time && a.flow.time == c.flow.time);
    assert_true(a.flow.tol == b.flow.tol && a.flow.tol == c.flow.tol);
    api_params_free(&b);
    api_params_free(&c);
    if (out) {
        *out = a;
    } else {
        api_params_free(&a);
    }
}

/* key=value must be refused by all three sources with the same message,
 * containing want. */
static void bad3(const char *key, const char *val, mcf_status code, const char *want)
{
    api_params a, b, c;
    mcf_error e1, e2, e3;
    char json[512], qs[512];

    api_params_init(&a);
    api_params_init(&b);
    api_params_init(&c);
    assert_int_equal(api_params_set(&a, key, val, &L, &e1), code);
    snprintf(json, sizeof json, "{\"%s\": \"%s\"}", key, val);
    assert_int_equal(api_params_parse_json(&b, json, strlen(json), &L, &e2), code);
    snprintf(qs, sizeof qs, "%s=%s", key, val);
    assert_int_equal(api_params_parse_query(&c, qs, NULL, &L, &e3), code);
    if (!strstr(e1.msg, want))
        fail_msg("%s=%s: \"%s\" lacks \"%s\"", key, val, e1.msg, want);
    assert_string_equal(e1.msg, e2.msg);
    assert_string_equal(e1.msg, e3.msg);
    assert_int_equal(e1.status, code);
    api_params_free(&a);
    api_params_free(&b);
    api_params_free(&c);
}

static void test_defaults(void **state)
{
    api_params p;
    (void)state;
    api_params_init(&p);
    /* the fairing filter, its variant chosen by size in api_params_finish */
    assert_int_equal(p.flow.scheme, MCF_FAIRING);
    assert_int_equal(p.scheme_set, 0);
    assert_true(p.flow.dt == 0.0); /* derived from the amount */
    assert_int_equal(p.flow.iterations, 0);
    assert_true(p.flow.strength == MCF_DEFAULT_STRENGTH);
    assert_int_equal(p.flow.normalize, 1);
    assert_int_equal(p.encode.format, API_FMT_UNKNOWN);
    assert_int_equal(p.encode.compression_level, 7);
    assert_int_equal(p.time_set + p.iterations_set, 0);
    assert_null(p.fixed_owned);
    api_params_free(&p);
    api_params_free(&p);
}

static void test_scalar_keys(void **state)
{
    api_params p;
    (void)state;
    ok3("scheme", "ros2", &p);
    assert_int_equal(p.flow.scheme, MCF_ROS2);
    api_params_free(&p);
    for (int s = 0; s < MCF_NSCHEMES; s++) {
        ok3("scheme", mcf_scheme_get((mcf_scheme)s)->name, &p);
        assert_int_equal(p.flow.scheme, s);
    }
    ok3("dt", "1e-3", &p);
    assert_true(p.flow.dt == 1e-3);
    assert_int_equal(p.flow.dt_auto, 0);
    ok3("dt", "auto", &p);
    assert_int_equal(p.flow.dt_auto, 1);
    ok3("dt", "1000", &p);
    assert_true(p.flow.dt == 1000.0);
    ok3("iterations", "1", &p);
    assert_int_equal(p.flow.iterations, 1);
    assert_int_equal(p.iterations_set, 1);
    ok3("iterations", "100000", &p);
    assert_int_equal(p.flow.iterations, 100000);
    ok3("time", "0.25", &p);
    assert_true(p.flow.time == 0.25);
    assert_int_equal(p.time_set, 1);
    ok3("boundary", "free", &p);
    assert_int_equal(p.flow.boundary, MCF_BOUNDARY_FREE);
    ok3("rescale", "volume", &p);
    assert_int_equal(p.flow.rescale, MCF_RESCALE_VOLUME);
    ok3("rescale", "area", &p);
    assert_int_equal(p.flow.rescale, MCF_RESCALE_AREA);
    ok3("normalize", "no", &p);
    assert_int_equal(p.flow.normalize, 0);
    ok3("normalize", "TRUE", &p);
    assert_int_equal(p.flow.normalize, 1);
    ok3("normalize", "0", &p);
    assert_int_equal(p.flow.normalize, 0);
    ok3("laplacian", "uniform", &p);
    assert_int_equal(p.flow.laplacian, MCF_LAPLACIAN_UNIFORM);
    ok3("mass", "voronoi", &p);
    assert_int_equal(p.flow.mass, MCF_MASS_VORONOI);
    ok3("adaptive", "yes", &p);
    assert_int_equal(p.flow.adaptive, 1);
    ok3("tol", "1e-12", &p);
    assert_true(p.flow.tol == 1e-12);
    ok3("tol", "1", &p);
    assert_true(p.flow.tol == 1.0);
    ok3("max_steps", "500", &p);
    assert_int_equal(p.flow.max_steps, 500);
    ok3("format", "draco", &p);
    assert_int_equal(p.encode.format, API_FMT_DRACO);
    ok3("format", "off", &p);
    assert_int_equal(p.encode.format, API_FMT_OFF);
    ok3("format", "drc", &p);       /* Draco's extension names it too */
    assert_int_equal(p.encode.format, API_FMT_DRACO);
    ok3("quantization_bits", "24", &p);
    assert_int_equal(p.encode.quantization_bits, 24);
    ok3("compression_level", "0", &p);
    assert_int_equal(p.encode.compression_level, 0);
    ok3("preserve_order", "true", &p);
    assert_int_equal(p.encode.preserve_order, 1);
    ok3("ply_binary", "false", &p);
    assert_int_equal(p.encode.ply_binary, 0);
}

static void test_bad_values(void **state)
{
    (void)state;
    bad3("dt", "abc", MCF_EINVAL,
         "parameter 'dt' must be a number > 0 and <= 1000 or \"auto\", got \"abc\"");
    bad3("dt", "0", MCF_EINVAL, "parameter 'dt' must be");
    bad3("dt", "-1e-3", MCF_EINVAL, "got \"-1e-3\"");
    bad3("dt", "1001", MCF_EINVAL, "parameter 'dt'");
    bad3("dt", "nan", MCF_EINVAL, "parameter 'dt'");
    bad3("dt", "inf", MCF_EINVAL, "parameter 'dt'");
    bad3("dt", "1e-3x", MCF_EINVAL, "parameter 'dt'");
    bad3("dt", "AUTO", MCF_EINVAL, "parameter 'dt'");
    bad3("scheme", "rk4", MCF_EINVAL,
         "parameter 'scheme' must be one of euler, taylor2, desbrun,");
    bad3("iterations", "0", MCF_EINVAL,
         "parameter 'iterations' must be an integer from 1 to 100000, got \"0\"");
    bad3("iterations", "100001", MCF_EINVAL, "parameter 'iterations'");
    bad3("iterations", "2.5", MCF_EINVAL, "parameter 'iterations'");
    bad3("iterations", "99999999999999999999", MCF_EINVAL, "parameter 'iterations'");
    bad3("time", "0", MCF_EINVAL, "parameter 'time' must be a finite number > 0");
    bad3("time", "-1", MCF_EINVAL, "parameter 'time'");
    bad3("boundary", "open", MCF_EINVAL,
         "parameter 'boundary' must be one of fixed, free, got \"open\"");
    bad3("rescale", "length", MCF_EINVAL, "one of none, volume, area");
    bad3("normalize", "maybe", MCF_EINVAL,
         "parameter 'normalize' must be true or false");
    bad3("laplacian", "cot", MCF_EINVAL, "one of cotan, uniform");
    bad3("mass", "lumped", MCF_EINVAL, "one of barycentric, voronoi");
    bad3("adaptive", "2", MCF_EINVAL, "parameter 'adaptive'");
    bad3("tol", "1e-13", MCF_EINVAL, "parameter 'tol' must be a number from 1e-12 to 1");
    bad3("tol", "1.5", MCF_EINVAL, "parameter 'tol'");
    bad3("max_steps", "0", MCF_EINVAL, "parameter 'max_steps'");
    /* Injecting noise is the lab's (lab/README.md), not a job parameter. */
    bad3("noise", "0.1", MCF_EINVAL, "unknown parameter 'noise'");
    bad3("seed", "1", MCF_EINVAL, "unknown parameter 'seed'");
    bad3("format", "fbx", MCF_EINVAL,
         "parameter 'format' must be one of obj, draco, ply, stl, off, glb, gltf, got \"fbx\"");
    /* a near name is offered (api_nearest_name) */
    bad3("format", "stll", MCF_EINVAL, "got \"stll\" (did you mean stl?)");
    bad3("scheme", "taubn", MCF_EINVAL, "got \"taubn\" (did you mean taubin?)");
    bad3("iterationz", "5", MCF_EINVAL, "unknown parameter 'iterationz' (did you mean 'iterations'?)");
    bad3("strenght", "1", MCF_EINVAL, "unknown parameter 'strenght' (did you mean 'strength'?)");
    {
        /* three edits from the only name of its length: no suggestion (and
         * no tie-break against a best not found yet: the fuzzer's crash) */
        static const char *const names[] = {"abcdefg", "desbrun2"};
        assert_null(api_nearest_name("xyzdefg", names, 2));
        assert_string_equal(api_nearest_name("desbrun3", names, 2), "desbrun2");
    }
    bad3("quantization_bits", "25", MCF_EINVAL,
         "parameter 'quantization_bits' must be an integer from 0 to 24");
    bad3("compression_level", "11", MCF_EINVAL,
         "parameter 'compression_level' must be an integer from 0 to 10");
    bad3("preserve_order", "on", MCF_EINVAL, "parameter 'preserve_order'");
    bad3("ply_binary", "", MCF_EINVAL, "parameter 'ply_binary' has an empty value");
    bad3("fixed_vertices", "1,x,3", MCF_EINVAL,
         "parameter 'fixed_vertices' must be a list of at most 100000000 vertex "
         "indices (integers >= 0), got \"x\" (item 2)");
    bad3("fixed_vertices", "-1", MCF_EINVAL, "got \"-1\" (item 1)");
    bad3("fixed_vertices", "3000000000", MCF_EINVAL, "(item 1)");
    bad3("smoothness", "5", MCF_EINVAL,
         "unknown parameter 'smoothness' (accepted: scheme,dt,iterations,time,"
         "strength,boundary,fixed_vertices,rescale,normalize,laplacian,mass,adaptive,tol,"
         "max_steps,format,quantization_bits,compression_level,"
         "preserve_order,ply_curvature,ply_binary)");
}

/* A long value is shortened in the message, never overflowing it. */
static void test_long_value(void **state)
{
    char v[400];
    api_params p;
    mcf_error err;
    (void)state;
    memset(v, 'q', sizeof v - 1);
    v[sizeof v - 1] = '\0';
    api_params_init(&p);
    assert_int_equal(api_params_set(&p, "scheme", v, &L, &err), MCF_EINVAL);
    assert_non_null(strstr(err.msg, "qqq...\""));
    assert_true(strlen(err.msg) < sizeof err.msg);
    assert_int_equal(api_params_set(&p, v, "1", &L, &err), MCF_EINVAL);
    assert_non_null(strstr(err.msg, "unknown parameter 'qqq"));
    assert_non_null(strstr(err.msg, "ply_binary)")); /* list not cut */
}

/* A failed set leaves the parameters as they were. */
static void test_failed_set_keeps(void **state)
{
    api_params p;
    mcf_error err;
    (void)state;
    api_params_init(&p);
    assert_int_equal(api_params_set(&p, "dt", "0.5", &L, &err), MCF_OK);
    assert_int_equal(api_params_set(&p, "fixed_vertices", "4 5", &L, &err), MCF_OK);
    assert_int_equal(api_params_set(&p, "dt", "-1", &L, &err), MCF_EINVAL);
    assert_int_equal(api_params_set(&p, "fixed_vertices", "4 x", &L, &err), MCF_EINVAL);
    assert_true(p.flow.dt == 0.5);
    assert_int_equal(p.flow.nfixed, 2);
    assert_int_equal(p.flow.fixed[1], 5);
    api_params_free(&p);
    assert_null(p.flow.fixed);
    assert_int_equal(p.flow.nfixed, 0);
}

static void test_fixed_list(void **state)
{
    api_params p;
    mcf_error err;
    const char *j = "{\"fixed_vertices\": [3, 1, 4, 1, 5]}";
    api_limits small = L;
    (void)state;
    api_params_init(&p);
    assert_int_equal(api_params_set(&p, "fixed_vertices", " 7,8\n9\t10 , 11,", &L, &err), MCF_OK);
    assert_int_equal(p.flow.nfixed, 5);
    assert_int_equal(p.flow.fixed[0], 7);
    assert_int_equal(p.flow.fixed[4], 11);
    assert_ptr_equal(p.flow.fixed, p.fixed_owned);
    /* JSON array; a later value replaces the whole list. */
    assert_int_equal(api_params_parse_json(&p, j, strlen(j), &L, &err), MCF_OK);
    assert_int_equal(p.flow.nfixed, 5);
    assert_int_equal(p.flow.fixed[2], 4);
    assert_int_equal(api_params_parse_json(&p, "{\"fixed_vertices\": []}", 22, &L, &err), MCF_OK);
    assert_int_equal(p.flow.nfixed, 0);
    assert_int_equal(api_params_parse_json(&p, "{\"fixed_vertices\": [1, 2.5]}", 28, &L, &err),
                     MCF_EINVAL);
    assert_non_null(strstr(err.msg, "got \"2.5\" (item 2)"));
    assert_int_equal(api_params_parse_json(&p, "{\"fixed_vertices\": [1, \"2\"]}", 28, &L, &err),
                     MCF_EINVAL);
    assert_non_null(strstr(err.msg, "got a string (item 2)"));
    assert_int_equal(api_params_parse_json(&p, "{\"fixed_vertices\": null}", 24, &L, &err),
                     MCF_EINVAL);
    assert_non_null(strstr(err.msg, "got null"));
    /* The list length limit. */
    small.max_fixed = 3;
    assert_int_equal(api_params_set(&p, "fixed_vertices", "1,2,3", &small, &err), MCF_OK);
    assert_int_equal(api_params_set(&p, "fixed_vertices", "1,2,3,4", &small, &err), MCF_ELIMIT);
    assert_non_null(strstr(err.msg, "max_fixed (3)"));
    api_params_free(&p);
}

static void test_json_types(void **state)
{
    api_params p;
    mcf_error err;
    const char *j = "{\"scheme\":\"euler\",\"dt\":0.001,\"iterations\":20,"
                    "\"normalize\":false,\"adaptive\":true,"
                    "\"format\":\"ply\",\"compression_level\":3}";
    (void)state;
    api_params_init(&p);
    assert_int_equal(api_params_parse_json(&p, j, strlen(j), &L, &err), MCF_OK);
    assert_int_equal(p.flow.scheme, MCF_EULER);
    assert_true(p.flow.dt == 0.001);
    assert_int_equal(p.flow.iterations, 20);
    assert_int_equal(p.flow.normalize, 0);
    assert_int_equal(p.flow.adaptive, 1);
    assert_int_equal(p.encode.format, API_FMT_PLY);
    assert_int_equal(p.encode.compression_level, 3);
    /* Numbers and booleans of the wrong kind. */
    assert_int_equal(api_params_parse_json(&p, "{\"iterations\": 2.5}", 19, &L, &err), MCF_EINVAL);
    assert_non_null(strstr(err.msg, "got \"2.5\""));
    assert_int_equal(api_params_parse_json(&p, "{\"dt\": true}", 12, &L, &err), MCF_EINVAL);
    assert_non_null(strstr(err.msg, "parameter 'dt' must be a number > 0 and <= 1000 or \"auto\", got true"));
    assert_int_equal(api_params_parse_json(&p, "{\"dt\": null}", 12, &L, &err), MCF_EINVAL);
    assert_non_null(strstr(err.msg, "got null"));
    assert_int_equal(api_params_parse_json(&p, "{\"dt\": [1]}", 11, &L, &err), MCF_EINVAL);
    assert_non_null(strstr(err.msg, "got an array"));
    assert_int_equal(api_params_parse_json(&p, "{\"dt\": {}}", 10, &L, &err), MCF_EINVAL);
    assert_non_null(strstr(err.msg, "got an object"));
    assert_int_equal(api_params_parse_json(&p, "{\"normalize\": 1}", 16, &L, &err), MCF_OK);
    assert_int_equal(p.flow.normalize, 1);
    /* Integral doubles written with a fraction or exponent are integers. */
    assert_int_equal(api_params_parse_json(&p, "{\"iterations\": 3e1}", 19, &L, &err), MCF_OK);
    assert_int_equal(p.flow.iterations, 30);
    /* Duplicate keys: the last wins. */
    assert_int_equal(api_params_parse_json(&p, "{\"tol\": 0.5, \"tol\": 0.25}", 25, &L, &err), MCF_OK);
    assert_true(p.flow.tol == 0.25);
    api_params_free(&p);
}

static void test_json_document(void **state)
{
    api_params p;
    mcf_error err;
    char deep[2 * 2000 + 16], *big;
    size_t i, n;
    api_limits lim = L;
    (void)state;
    api_params_init(&p);
    assert_int_equal(api_params_parse_json(&p, "{}", 2, &L, &err), MCF_OK);
    assert_int_equal(api_params_parse_json(&p, "  {}  \n", 7, &L, &err), MCF_OK);
    assert_int_equal(api_params_parse_json(&p, "[]", 2, &L, &err), MCF_EINVAL);
    assert_non_null(strstr(err.msg, "top level must be a JSON object"));
    assert_int_equal(api_params_parse_json(&p, "42", 2, &L, &err), MCF_EINVAL);
    assert_int_equal(api_params_parse_json(&p, "", 0, &L, &err), MCF_EINVAL);
    assert_int_equal(api_params_parse_json(&p, "{\"dt\": 1", 8, &L, &err), MCF_EINVAL);
    assert_non_null(strstr(err.msg, "invalid JSON near byte"));
    assert_int_equal(api_params_parse_json(&p, "{} {}", 5, &L, &err), MCF_EINVAL);
    /* An embedded NUL does not end the document early. */
    assert_int_equal(api_params_parse_json(&p, "{}\0junk", 7, &L, &err), MCF_EINVAL);
    assert_non_null(strstr(err.msg, "invalid JSON"));
    /* The buffer need not be NUL-terminated: only len bytes are read. */
    assert_int_equal(api_params_parse_json(&p, "{\"tol\":0.5}garbage", 11, &L, &err), MCF_OK);
    assert_true(p.flow.tol == 0.5);

    /* Depth: 16 levels pass, 17 do not (an unknown key at depth 16 fails
     * as unknown, which shows the depth check passed). */
    n = 0;
    memcpy(deep, "{\"x\":", 5);
    n = 5;
    for (i = 0; i < 15; i++)
        deep[n++] = '[';
    for (i = 0; i < 15; i++)
        deep[n++] = ']';
    deep[n++] = '}';
    assert_int_equal(api_params_parse_json(&p, deep, n, &L, &err), MCF_EINVAL);
    assert_non_null(strstr(err.msg, "unknown parameter 'x'"));
    n = 5;
    for (i = 0; i < 16; i++)
        deep[n++] = '[';
    for (i = 0; i < 16; i++)
        deep[n++] = ']';
    deep[n++] = '}';
    assert_int_equal(api_params_parse_json(&p, deep, n, &L, &err), MCF_ELIMIT);
    assert_non_null(strstr(err.msg, "max_json_depth (16)"));
    /* Deeper than cJSON's own nesting limit (1000): still ELIMIT. */
    n = 0;
    for (i = 0; i < 2000; i++)
        deep[n++] = '[';
    for (i = 0; i < 2000; i++)
        deep[n++] = ']';
    lim.max_json_bytes = sizeof deep;
    assert_int_equal(api_params_parse_json(&p, deep, n, &lim, &err), MCF_ELIMIT);

    /* Size: one byte over max_json_bytes is refused before parsing. */
    n = L.max_json_bytes + 1;
    big = malloc(n);
    assert_non_null(big);
    memset(big, ' ', n);
    big[0] = '{';
    big[n - 1] = '}';
    assert_int_equal(api_params_parse_json(&p, big, n, &L, &err), MCF_ELIMIT);
    assert_non_null(strstr(err.msg, "max_json_bytes (65536)"));
    assert_int_equal(api_params_parse_json(&p, big + 1, n - 1, &L, &err), MCF_EINVAL);
    big[1] = '{';
    assert_int_equal(api_params_parse_json(&p, big + 1, n - 1, &L, &err), MCF_OK);
    free(big);
    api_params_free(&p);
}

/* A daemon request's sources, later ones overriding earlier: the JSON
 * object, then the form fields in order, then the query, whose ignored
 * keys are skipped; a failure in any source stops there and names it. */
static void test_request_sources(void **state)
{
    api_params p;
    mcf_error err;
    const char *const ignore[] = {"stream", "fields", NULL};
    cJSON *fields = cJSON_Parse("[[\"dt\", \"2e-3\"], [\"iterations\", \"9\"], [\"dt\", \"3e-3\"]]");
    (void)state;
    assert_non_null(fields);
    api_params_init(&p);
    assert_int_equal(api_params_parse_request(&p, "{\"scheme\": \"euler\", \"dt\": 1e-3, \"tol\": 0.25}",
                                              fields, "iterations=7&stream=ndjson&fields=true",
                                              ignore, &L, &err), MCF_OK);
    assert_int_equal(p.flow.scheme, MCF_EULER);  /* the JSON alone */
    assert_true(p.flow.tol == 0.25);
    assert_true(p.flow.dt == 3e-3);              /* the last form field */
    assert_int_equal(p.flow.iterations, 7);      /* the query, last */
    /* Every source may be missing. */
    api_params_init(&p);
    assert_int_equal(api_params_parse_request(&p, NULL, NULL, NULL, NULL, &L, &err), MCF_OK);
    assert_int_equal(p.flow.iterations, 0);
    /* Without the ignore list, the daemon's keys are unknown parameters. */
    assert_int_equal(api_params_parse_request(&p, NULL, NULL, "stream=ndjson", NULL, &L, &err),
                     MCF_EINVAL);
    assert_non_null(strstr(err.msg, "stream"));
    /* A bad form field stops before the query. */
    cJSON_Delete(fields);
    fields = cJSON_Parse("[[\"dt\", \"-1\"]]");
    api_params_init(&p);
    assert_int_equal(api_params_parse_request(&p, "{\"iterations\": 3}", fields, "iterations=5",
                                              ignore, &L, &err), MCF_EINVAL);
    assert_non_null(strstr(err.msg, "dt"));
    assert_int_equal(p.flow.iterations, 3);
    cJSON_Delete(fields);
}

static void test_query(void **state)
{
    api_params p;
    mcf_error err;
    const char *const ignore[] = {"callback", "token", NULL};
    (void)state;
    api_params_init(&p);
    assert_int_equal(api_params_parse_query(&p, "scheme=euler&dt=1e-3&iterations=7", NULL, &L, &err), MCF_OK);
    assert_int_equal(p.flow.scheme, MCF_EULER);
    assert_true(p.flow.dt == 1e-3);
    assert_int_equal(p.flow.iterations, 7);
    /* Percent-decoding, '+' as space, empty segments, last value wins. */
    assert_int_equal(api_params_parse_query(&p, "fixed_vertices=1%2C2+3&&dt=1%65-2&dt=2e-3&", NULL, &L, &err),
                     MCF_OK);
    assert_int_equal(p.flow.nfixed, 3);
    assert_int_equal(p.flow.fixed[2], 3);
    assert_true(p.flow.dt == 2e-3);
    assert_int_equal(api_params_parse_query(&p, "%73cheme=%64esbrun", NULL, &L, &err), MCF_OK);
    assert_int_equal(p.flow.scheme, MCF_DESBRUN);
    /* Keys the caller handles itself are skipped, whatever their value. */
    assert_int_equal(api_params_parse_query(&p, "token=&callback=x&tol=0.5", ignore, &L, &err), MCF_OK);
    assert_true(p.flow.tol == 0.5);
    assert_int_equal(api_params_parse_query(&p, "", NULL, &L, &err), MCF_OK);
    /* Errors. */
    assert_int_equal(api_params_parse_query(&p, "dt=", NULL, &L, &err), MCF_EINVAL);
    assert_string_equal(err.msg, "parameter 'dt' has an empty value");
    assert_int_equal(api_params_parse_query(&p, "dt", NULL, &L, &err), MCF_EINVAL);
    assert_string_equal(err.msg, "parameter 'dt' has an empty value");
    assert_int_equal(api_params_parse_query(&p, "=5", NULL, &L, &err), MCF_EINVAL);
    assert_non_null(strstr(err.msg, "without a name"));
    assert_int_equal(api_params_parse_query(&p, "dt=1%2", NULL, &L, &err), MCF_EINVAL);
    assert_non_null(strstr(err.msg, "bad percent-encoding in 'dt=1%2'"));
    assert_int_equal(api_params_parse_query(&p, "dt=1%zz", NULL, &L, &err), MCF_EINVAL);
    assert_int_equal(api_params_parse_query(&p, "dt=1%00", NULL, &L, &err), MCF_EINVAL);
    assert_int_equal(api_params_parse_query(&p, "bogus=1", NULL, &L, &err), MCF_EINVAL);
    assert_non_null(strstr(err.msg, "unknown parameter 'bogus'"));
    /* Values stay as they were after the errors. */
    assert_true(p.flow.dt == 2e-3);
    api_params_free(&p);
}

static void test_finish(void **state)
{
    api_params p;
    mcf_error err;
    api_limits lim = L;
    (void)state;
    api_params_init(&p);
    assert_int_equal(api_params_finish(&p, 812, &L, &err), MCF_OK);
    /* time in 5 steps is one job now; tol without adaptive is refused */
    assert_int_equal(api_params_set(&p, "time", "0.01", &L, &err), MCF_OK);
    assert_int_equal(api_params_set(&p, "iterations", "5", &L, &err), MCF_OK);
    assert_int_equal(api_params_finish(&p, 812, &L, &err), MCF_OK);
    assert_int_equal(api_params_set(&p, "tol", "1e-5", &L, &err), MCF_OK);
    assert_int_equal(api_params_finish(&p, 812, &L, &err), MCF_EINVAL);
    assert_non_null(strstr(err.msg, "'tol' applies to adaptive runs only"));
    assert_int_equal(api_params_set(&p, "adaptive", "true", &L, &err), MCF_OK);
    assert_int_equal(api_params_finish(&p, 812, &L, &err), MCF_OK);
    assert_int_equal(api_params_set(&p, "strength", "0", &L, &err), MCF_EINVAL);
    assert_non_null(strstr(err.msg, "parameter 'strength' must be a number > 0"));
    api_params_free(&p);

    api_params_init(&p);
    assert_int_equal(api_params_set(&p, "fixed_vertices", "0,811", &L, &err), MCF_OK);
    assert_int_equal(api_params_finish(&p, 812, &L, &err), MCF_OK);
    assert_int_equal(api_params_set(&p, "fixed_vertices", "0,812", &L, &err), MCF_OK);
    assert_int_equal(api_params_finish(&p, 812, &L, &err), MCF_EINVAL);
    assert_string_equal(err.msg, "parameter 'fixed_vertices': index 812 out of range (0..811)");
    api_params_free(&p);

    /* mcf_flow_params_check runs: dt=auto needs an explicit scheme, and
     * adaptive a scheme with an error estimate. */
    api_params_init(&p);
    assert_int_equal(api_params_set(&p, "dt", "auto", &L, &err), MCF_OK);
    assert_int_equal(api_params_finish(&p, 812, &L, &err), MCF_EINVAL);
    assert_int_equal(api_params_set(&p, "scheme", "euler", &L, &err), MCF_OK);
    assert_int_equal(api_params_finish(&p, 812, &L, &err), MCF_OK);
    assert_int_equal(api_params_set(&p, "adaptive", "true", &L, &err), MCF_OK);
    assert_int_equal(api_params_finish(&p, 812, &L, &err), MCF_EINVAL);
    api_params_free(&p);

    /* Work: iterations x vertices against max_work. */
    api_params_init(&p);
    lim.max_work = 1e6;
    assert_int_equal(api_params_set(&p, "iterations", "1000", &lim, &err), MCF_OK);
    assert_int_equal(api_params_finish(&p, 1000, &lim, &err), MCF_OK);
    assert_int_equal(api_params_finish(&p, 1001, &lim, &err), MCF_ELIMIT);
    assert_non_null(strstr(err.msg, "exceeds max_work"));
    api_params_free(&p);
    /* A fixed-step run over a time: time/dt steps. */
    api_params_init(&p);
    assert_int_equal(api_params_set(&p, "time", "0.1", &lim, &err), MCF_OK);
    assert_int_equal(api_params_set(&p, "dt", "1e-4", &lim, &err), MCF_OK);
    assert_int_equal(api_params_finish(&p, 1000, &lim, &err), MCF_OK);
    assert_int_equal(api_params_finish(&p, 1001, &lim, &err), MCF_ELIMIT);
    lim.max_iterations = 999;
    /* the parameters alone exceed the limit: a bad request, not a mesh
     * too large for the limits */
    assert_int_equal(api_params_finish(&p, 10, &lim, &err), MCF_EINVAL);
    assert_non_null(strstr(err.msg, "max_iterations (999)"));
    api_params_free(&p);
    /* Adaptive over a time: max_steps is lowered to fit the limits. */
    api_params_init(&p);
    lim = L;
    lim.max_work = 1e6;
    assert_int_equal(api_params_set(&p, "time", "0.1", &lim, &err), MCF_OK);
    assert_int_equal(api_params_set(&p, "adaptive", "1", &lim, &err), MCF_OK);
    assert_int_equal(api_params_finish(&p, 4000, &lim, &err), MCF_OK);
    assert_int_equal(p.flow.max_steps, 250);
    api_params_free(&p);
}

/* The JSON form parses back to the same parameters. */
static void test_to_json_roundtrip(void **state)
{
    api_params a, b;
    mcf_error err;
    cJSON *j;
    char *s;
    (void)state;
    api_params_init(&a);
    assert_int_equal(api_params_parse_query(&a,
        "scheme=ros2&time=0.03&boundary=free&fixed_vertices=5,6,7&rescale=volume"
        "&normalize=false&laplacian=uniform&mass=voronoi&adaptive=1&tol=1e-5"
        "&max_steps=77&format=draco"
        "&quantization_bits=14&compression_level=9&preserve_order=yes&ply_binary=no",
        NULL, &L, &err), MCF_OK);
    j = api_params_to_json(&a);
    assert_non_null(j);
    s = cJSON_PrintUnformatted(j);
    assert_non_null(s);
    api_params_init(&b);
    if (api_params_parse_json(&b, s, strlen(s), &L, &err) != MCF_OK)
        fail_msg("%s: %s", s, err.msg);
    assert_memory_equal(&a.encode, &b.encode, sizeof a.encode);
    assert_int_equal(a.flow.scheme, b.flow.scheme);
    assert_true(a.flow.time == b.flow.time);
    assert_int_equal(b.time_set, 1);
    assert_int_equal(b.iterations_set, 0);
    assert_int_equal(a.flow.boundary, b.flow.boundary);
    assert_int_equal(b.flow.nfixed, 3);
    assert_memory_equal(a.flow.fixed, b.flow.fixed, 3 * sizeof(int32_t));
    assert_int_equal(a.flow.rescale, b.flow.rescale);
    assert_int_equal(a.flow.normalize, b.flow.normalize);
    assert_int_equal(a.flow.laplacian, b.flow.laplacian);
    assert_int_equal(a.flow.mass, b.flow.mass);
    assert_int_equal(a.flow.adaptive, b.flow.adaptive);
    assert_true(a.flow.tol == b.flow.tol);
    assert_int_equal(a.flow.max_steps, b.flow.max_steps);
    cJSON_free(s);
    cJSON_Delete(j);
    /* dt=auto travels as the string. */
    assert_int_equal(api_params_set(&a, "dt", "auto", &L, &err), MCF_OK);
    j = api_params_to_json(&a);
    assert_string_equal(cJSON_GetObjectItem(j, "dt")->valuestring, "auto");
    cJSON_Delete(j);
    api_params_free(&a);
    api_params_free(&b);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_defaults),
        cmocka_unit_test(test_scalar_keys),
        cmocka_unit_test(test_bad_values),
        cmocka_unit_test(test_long_value),
        cmocka_unit_test(test_failed_set_keeps),
        cmocka_unit_test(test_fixed_list),
        cmocka_unit_test(test_json_types),
        cmocka_unit_test(test_json_document),
        cmocka_unit_test(test_request_sources),
        cmocka_unit_test(test_query),
        cmocka_unit_test(test_finish),
        cmocka_unit_test(test_to_json_roundtrip),
    };
    return cmocka_run_group_tests(tests, setup, NULL);
}
