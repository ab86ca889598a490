/* SPDX-License-Identifier: MIT */
/*
 * test_cli.c - the `mcf` tool end to end: runs $MCF_BUILD/mcf (default
 * build/mcf) as a child process on the real meshes and checks exit codes,
 * stdout JSON, the files written and the one-line error contract.
 *
 * Everything runs on sphere_cgal.obj (812 vertices) with a handful of
 * steps, so the whole binary takes well under a second.
 */
#include <dirent.h>
#include <fcntl.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <sys/resource.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "testlib.h"
#include "../api/api.h"

static mcf_mesh *load_path(const char *path)
{
    char *buf;
    size_t len;
    mcf_mesh *m = NULL;
    mcf_error err;
    if (tl_read_file(path, &buf, &len) != 0)
        fail_msg("cannot read %s", path);
    if (api_mesh_decode(buf, len, NULL, &m, NULL, &err) != MCF_OK)
        fail_msg("%s: %s", path, err.msg);
    free(buf);
    return m;
}

static cJSON *load_json(const char *path)
{
    char *buf;
    size_t len;
    cJSON *j;
    if (tl_read_file(path, &buf, &len) != 0)
        fail_msg("cannot read %s", path);
    j = cJSON_Parse(buf);
    free(buf);
    if (!j)
        fail_msg("%s is not JSON", path);
    return j;
}

static int setup(void **state)
{
    (void)state;
    return tl_mcf_setup("test_cli", "/tmp/mcf_test_cli_XXXXXX");
}

static int teardown(void **state)
{
    (void)state;
    return tl_mcf_teardown();
}

static void test_help(void **state)
{
    tl_run_result r = tl_run("--help", NULL);
    (void)state;
    assert_int_equal(r.status, 0);
    assert_non_null(strstr(r.out, "usage:"));
    assert_non_null(strstr(r.out, "mcf smooth IN OUT"));
    assert_non_null(strstr(r.out, "mcf convert IN OUT"));
    assert_int_equal(r.errlen, 0);
    tl_run_free(&r);
}

static void test_schemes(void **state)
{
    tl_run_result r = tl_run("schemes", NULL);
    cJSON *j;
    (void)state;
    assert_int_equal(r.status, 0);
    assert_int_equal(r.errlen, 0);
    j = cJSON_Parse(r.out);
    assert_non_null(j);
    assert_int_equal(cJSON_GetArraySize(cJSON_GetObjectItem(j, "schemes")), MCF_NSCHEMES);
    cJSON_Delete(j);
    tl_run_free(&r);
}

static void test_info(void **state)
{
    tl_run_result r = tl_run("info", tl_sphere(), NULL);
    cJSON *j;
    (void)state;
    assert_int_equal(r.status, 0);
    j = cJSON_Parse(r.out);
    assert_non_null(j);
    assert_int_equal(cJSON_GetObjectItem(j, "vertices")->valueint, 812);
    assert_int_equal(cJSON_GetObjectItem(j, "faces")->valueint, 1620);
    assert_int_equal(cJSON_GetObjectItem(j, "genus")->valueint, 0);
    assert_string_equal(cJSON_GetObjectItem(j, "format")->valuestring, "obj");
    assert_non_null(cJSON_GetObjectItem(cJSON_GetObjectItem(j, "curvature"), "H"));
    cJSON_Delete(j);
    tl_run_free(&r);
}

/* Issue 17: `mcf info` on draco_texcoord_orientations.drc (210 bytes,
 * 2^31-1 texcoord orientations inside the stream) took 256 MiB and 6-9 s
 * of CPU, then decoded. The CLI decodes Draco under the daemon's bound
 * (64 MiB beyond its size, 2 s of CPU): refused at once (under ASan,
 * which cannot run under RLIMIT_AS, by the CPU limit). The same stream
 * as a GLB's Draco primitive too (the daemon's rule: whatever reaches
 * libdraco, api_mem_estimate.draco). Issue 28: draco_declared_faces.drc
 * (26 bytes, an edgebreaker header declaring 9,999,999 faces) took
 * 243 MB before libdraco's "Failed to decode": refused from its header,
 * more faces than its bytes can hold. */
static void test_draco_bound(void **state)
{
    static const char *const bombs[] = {"draco_texcoord_orientations.drc",
                                        "gltf/draco_bomb.glb",
                                        "draco_declared_faces.drc"};
    static const char *const was[] = {"exit 0 after 256 MiB and 6-9 s",
                                      "exit 0 after 13 s of CPU",
                                      "exit 1 after 243 MB"};
    size_t k;

    (void)state;
    for (k = 0; k < sizeof bombs / sizeof bombs[0]; k++) {
        char bomb[600];
        struct rusage before, after;
        tl_run_result r;

        snprintf(bomb, sizeof bomb, "%s/%s", tl_testdata_dir(), bombs[k]);
        if (bomb[0] != '/') {
            char cwd[400];
            assert_non_null(getcwd(cwd, sizeof cwd));
            snprintf(bomb, sizeof bomb, "%s/%s/%s", cwd, tl_testdata_dir(),
                     bombs[k]);
        }
        getrusage(RUSAGE_CHILDREN, &before);
        r = tl_run("info", bomb, NULL);
        getrusage(RUSAGE_CHILDREN, &after);
        print_message("    mcf info on %s: exit %d, %.2f s of CPU (main: %s)\n",
                      bombs[k], r.status,
                      (double)(after.ru_utime.tv_sec - before.ru_utime.tv_sec) +
                          (after.ru_utime.tv_usec - before.ru_utime.tv_usec) / 1e6,
                      was[k]);
        tl_expect_error(&r, 1, "refused");
    }
}

static void test_smooth_metrics(void **state)
{
    tl_run_result r = tl_run("smooth", tl_sphere(), "out.obj", "--iterations", "5",
                             "--metrics", "m.json", "--quiet", NULL);
    mcf_mesh *in, *out;
    cJSON *j, *flow;
    double a_in, a_out;
    (void)state;
    if (r.status != 0)
        fail_msg("smooth: status %d: %s", r.status, r.err);
    assert_int_equal(r.errlen, 0);
    assert_int_equal(r.outlen, 0);
    tl_run_free(&r);
    in = load_path(tl_sphere());
    out = load_path(tl_in_scratch("out.obj"));
    assert_int_equal(mcf_mesh_nvertices(out), 812);
    assert_memory_equal(mcf_mesh_faces(in), mcf_mesh_faces(out), 3 * 4 * 1620);
    /* MCF is the gradient flow of area: five steps strictly shrink it. */
    a_in = mcf_mesh_area(in);
    a_out = mcf_mesh_area(out);
    assert_true(a_out < a_in);

    j = load_json(tl_in_scratch("m.json"));
    assert_int_equal(cJSON_GetObjectItem(cJSON_GetObjectItem(j, "params"), "iterations")->valueint, 5);
    flow = cJSON_GetObjectItem(j, "flow");
    assert_int_equal(cJSON_GetObjectItem(flow, "steps")->valueint, 5);
    assert_int_equal(cJSON_GetArraySize(cJSON_GetObjectItem(flow, "log")), 5);
    assert_non_null(cJSON_GetObjectItem(flow, "timings"));
    /* The metrics describe the file written: OBJ keeps every bit and
     * cJSON prints within 2 relative DBL_EPSILON (see test_api_json). */
    tl_assert_near(cJSON_GetObjectItem(cJSON_GetObjectItem(cJSON_GetObjectItem(j, "output"), "info"),
                                       "area")->valuedouble,
                   a_out, 4.5e-16 * a_out, "output area");
    tl_assert_near(cJSON_GetObjectItem(cJSON_GetObjectItem(cJSON_GetObjectItem(j, "input"), "info"),
                                       "area")->valuedouble,
                   a_in, 4.5e-16 * a_in, "input area");
    assert_non_null(cJSON_GetObjectItem(cJSON_GetObjectItem(j, "curvature"), "before"));
    assert_non_null(cJSON_GetObjectItem(cJSON_GetObjectItem(j, "curvature"), "after"));
    assert_true(cJSON_GetObjectItem(j, "peak_rss_bytes")->valuedouble > 0);
    assert_true(cJSON_GetObjectItem(cJSON_GetObjectItem(j, "timings"), "decode_s")->valuedouble >= 0);
    assert_true(cJSON_GetObjectItem(cJSON_GetObjectItem(j, "timings"), "encode_s")->valuedouble >= 0);
    assert_null(cJSON_GetObjectItem(j, "compare"));
    cJSON_Delete(j);
    mcf_mesh_free(in);
    mcf_mesh_free(out);
}

/* A noisy input, the clean target, fixed vertices and an output format by
 * flag. */
static void test_smooth_noise_target_fixed(void **state)
{
    FILE *f = fopen(tl_in_scratch("fix.txt"), "w");
    tl_run_result r;
    mcf_mesh *ref, *out;
    cJSON *j, *cmp;
    const int fixed[] = {0, 17, 400};
    (void)state;
    assert_non_null(f);
    fprintf(f, "0, 17\n400\n");
    fclose(f);
    tl_write_noisy("sphere_cgal.obj", 0.05, 3, tl_in_scratch("noisy.obj"));
    r = tl_run("smooth", "noisy.obj", "out.mesh", "--format", "obj",
               "--target", tl_sphere(), "--fix-vertices", "fix.txt",
               "--iterations", "4", "--scheme", "desbrun", "--metrics", "m2.json", NULL);
    if (r.status != 0)
        fail_msg("smooth: status %d: %s", r.status, r.err);
    tl_run_free(&r);
    ref = load_path(tl_in_scratch("noisy.obj"));
    out = load_path(tl_in_scratch("out.mesh"));
    for (int k = 0; k < 3; k++)
        for (int c = 0; c < 3; c++)
            /* Fixed vertices do not move under the flow; writing OBJ keeps
             * full precision. */
            tl_assert_near(mcf_mesh_positions(out)[3 * fixed[k] + c],
                           mcf_mesh_positions(ref)[3 * fixed[k] + c], 1e-12, "fixed vertex");
    /* A free vertex did move (by far more than roundoff). */
    assert_true(fabs(mcf_mesh_positions(out)[3 * 1] - mcf_mesh_positions(ref)[3 * 1])
                + fabs(mcf_mesh_positions(out)[3 * 1 + 1] - mcf_mesh_positions(ref)[3 * 1 + 1])
                + fabs(mcf_mesh_positions(out)[3 * 1 + 2] - mcf_mesh_positions(ref)[3 * 1 + 2]) > 1e-9);
    j = load_json(tl_in_scratch("m2.json"));
    cmp = cJSON_GetObjectItem(j, "compare");
    assert_non_null(cmp);
    /* Against the clean input, the noisy start is off by about rho times
     * the mean edge (0.05 x 0.134): clearly above zero. */
    assert_true(cJSON_GetObjectItem(cJSON_GetObjectItem(cmp, "before"), "rms_m")->valuedouble > 1e-3);
    assert_non_null(cJSON_GetObjectItem(cJSON_GetObjectItem(cmp, "after"), "rms_m"));
    assert_int_equal(cJSON_GetArraySize(cJSON_GetObjectItem(cJSON_GetObjectItem(j, "params"),
                                                            "fixed_vertices")), 3);
    cJSON_Delete(j);
    mcf_mesh_free(ref);
    mcf_mesh_free(out);
}

static void test_convert(void **state)
{
    tl_run_result r = tl_run("convert", tl_sphere(), "copy.obj", NULL);
    mcf_mesh *a, *b;
    (void)state;
    assert_int_equal(r.status, 0);
    tl_run_free(&r);
    a = load_path(tl_sphere());
    b = load_path(tl_in_scratch("copy.obj"));
    /* OBJ -> OBJ keeps every bit of every coordinate. */
    assert_memory_equal(mcf_mesh_positions(a), mcf_mesh_positions(b), 3 * 8 * 812);
    assert_memory_equal(mcf_mesh_faces(a), mcf_mesh_faces(b), 3 * 4 * 1620);
    mcf_mesh_free(b);
    /* To Draco by extension, and back through info. */
    r = tl_run("convert", tl_sphere(), "copy.drc", NULL);
    if (r.status != 0)
        fail_msg("convert to drc: %s", r.err);
    tl_run_free(&r);
    r = tl_run("info", "copy.drc", NULL);
    assert_int_equal(r.status, 0);
    assert_non_null(strstr(r.out, "\"format\":\t\"draco\""));
    assert_non_null(strstr(r.out, "\"vertices\":\t812"));
    tl_run_free(&r);
    /* To PLY: float x y z (the Draco input was single precision), the
     * curvature properties only with --ply-curvature (as in the daemon). */
    r = tl_run("convert", "copy.drc", "plain.ply", NULL);
    if (r.status != 0)
        fail_msg("convert to ply: %s", r.err);
    tl_run_free(&r);
    r = tl_run("convert", "copy.drc", "copy.ply", "--ply-curvature", NULL);
    if (r.status != 0)
        fail_msg("convert to ply: %s", r.err);
    tl_run_free(&r);
    {
        char *buf;
        size_t len;
        assert_int_equal(tl_read_file(tl_in_scratch("plain.ply"), &buf, &len), 0);
        assert_non_null(strstr(buf, "property float x\n"));
        assert_null(strstr(buf, "curvature"));
        free(buf);
        assert_int_equal(tl_read_file(tl_in_scratch("copy.ply"), &buf, &len), 0);
        assert_non_null(strstr(buf, "property float mean_curvature"));
        assert_non_null(strstr(buf, "property float gaussian_curvature"));
        free(buf);
        b = load_path(tl_in_scratch("copy.ply"));
        assert_int_equal(mcf_mesh_nvertices(b), 812);
        mcf_mesh_free(b);
    }
    mcf_mesh_free(a);
}

static void test_errors(void **state)
{
    FILE *f;
    tl_run_result r;
    struct stat sb;
    (void)state;
    r = tl_run(NULL);
    tl_expect_error(&r, 2, "missing command");
    r = tl_run("frobnicate", NULL);
    tl_expect_error(&r, 2, "unknown command 'frobnicate'");
    r = tl_run("smooth", tl_sphere(), "o.obj", "--bogus", NULL);
    tl_expect_error(&r, 2, "unknown option '--bogus'");
    r = tl_run("smooth", tl_sphere(), NULL);
    tl_expect_error(&r, 2, "needs IN and OUT");
    r = tl_run("smooth", tl_sphere(), "o.obj", "--iterations", NULL);
    tl_expect_error(&r, 2, "'--iterations' needs a value");
    r = tl_run("smooth", tl_sphere(), "o.obj", "--dt", "abc", NULL);
    tl_expect_error(&r, 2, "parameter 'dt' must be a number > 0 and <= 1000 or \"auto\", got \"abc\"");
    r = tl_run("smooth", tl_sphere(), "o.obj", "--scheme=rk4", NULL);
    tl_expect_error(&r, 2, "parameter 'scheme' must be one of");
    r = tl_run("smooth", tl_sphere(), "o.obj", "--tol", "1e-5", NULL);
    tl_expect_error(&r, 2, "parameter 'tol' applies to adaptive runs only");
    r = tl_run("smooth", tl_sphere(), "o.xyz", NULL);
    tl_expect_error(&r, 2, "cannot tell the output format from 'o.xyz' "
                    "(use --format obj|draco|ply|stl|off|glb|gltf)");
    /* issue 29: a mistyped option is offered the nearest one; format=drc
     * (Draco's extension) is Draco; an empty file says so */
    r = tl_run("smooth", tl_sphere(), "o.obj", "--strenght", "0.5", NULL);
    tl_expect_error(&r, 2, "unknown option '--strenght', did you mean '--strength'?");
    r = tl_run("smooth", tl_sphere(), "o.obj", "--progres", NULL);
    tl_expect_error(&r, 2, "did you mean '--progress'?");
    r = tl_run("smooth", tl_sphere(), "o.obj", "--fix-vertice", "f.txt", NULL);
    tl_expect_error(&r, 2, "did you mean '--fix-vertices'?");
    r = tl_run("smooth", tl_sphere(), "o.obj", "--no-normalise", NULL);
    tl_expect_error(&r, 2, "did you mean '--no-normalize'?");
    r = tl_run("smooth", tl_sphere(), "o.obj", "--scheme", "desbrun3", NULL);
    tl_expect_error(&r, 2, "got \"desbrun3\" (did you mean desbrun2?)");
    r = tl_run("convert", tl_sphere(), "o.xyz", "--format", "drc", NULL);
    assert_int_equal(r.status, 0);
    tl_run_free(&r);
    f = fopen(tl_in_scratch("o.xyz"), "rb");
    assert_non_null(f);
    {
        char magic[5] = "";
        assert_int_equal(fread(magic, 1, 5, f), 5);
        assert_memory_equal(magic, "DRACO", 5);
    }
    fclose(f);
    f = fopen(tl_in_scratch("empty.obj"), "w");
    assert_non_null(f);
    fclose(f);
    r = tl_run("smooth", "empty.obj", "o.obj", NULL);
    tl_expect_error(&r, 1, "empty.obj: the input is empty (0 bytes): no mesh to read");
    r = tl_run("smooth", "missing.obj", "o.obj", NULL);
    tl_expect_error(&r, 1, "cannot read 'missing.obj'");
    r = tl_run("info", NULL);
    tl_expect_error(&r, 2, "info: needs exactly one input file");
    r = tl_run("schemes", "extra", NULL);
    tl_expect_error(&r, 2, "schemes: takes no arguments");
    r = tl_run("convert", tl_sphere(), "o.obj", "--iterations", "3", NULL);
    tl_expect_error(&r, 2, "convert: unknown option '--iterations'");
    /* A malformed input names its line; nothing is written. */
    f = fopen(tl_in_scratch("bad.obj"), "w");
    assert_non_null(f);
    fprintf(f, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
    fclose(f);
    r = tl_run("smooth", "bad.obj", "never.obj", NULL);
    tl_expect_error(&r, 1, "bad.obj: line 4: face index 9 out of range (1..3)");
    assert_int_equal(stat(tl_in_scratch("never.obj"), &sb), -1);
    /* A fixed vertex out of range, and a target of another shape. */
    f = fopen(tl_in_scratch("fix2.txt"), "w");
    assert_non_null(f);
    fprintf(f, "5 812\n");
    fclose(f);
    r = tl_run("smooth", tl_sphere(), "o.obj", "--fix-vertices", "fix2.txt", NULL);
    tl_expect_error(&r, 2, "index 812 out of range (0..811)");
    r = tl_run("smooth", tl_sphere(), "o.obj", "--target", "bad.obj", NULL);
    tl_expect_error(&r, 1, "bad.obj: line 4");
    r = tl_run("smooth", tl_sphere(), "o.obj", "--target", "copy.obj", "--fix-vertices", "missing.txt", NULL);
    tl_expect_error(&r, 1, "cannot read 'missing.txt'");
    assert_int_equal(stat(tl_in_scratch("o.obj"), &sb), -1);
}

/* ------------------------------------------------ the metrics document */

/* An open 8 x 8 grid with a bump (z = 0.2 sin(pi x) sin(pi y)), shifted
 * off the origin by (3, -2, 5): on an open mesh the signed volume depends
 * on the point the cones start from (by c . (vector area) / 3, here about
 * 5/3 between the origin and the area centroid), so every volume the
 * metrics report must be measured about the same point. */
static void write_open_grid(const char *path)
{
    FILE *f = fopen(path, "w");
    const double pi = 3.14159265358979323846;
    int i, k, n = 8;
    assert_non_null(f);
    for (k = 0; k < n; k++)
        for (i = 0; i < n; i++) {
            double x = (double)i / (n - 1), y = (double)k / (n - 1);
            fprintf(f, "v %.17g %.17g %.17g\n", x + 3, y - 2,
                    0.2 * sin(pi * x) * sin(pi * y) + 5);
        }
    for (k = 0; k + 1 < n; k++)
        for (i = 0; i + 1 < n; i++) {
            int a = k * n + i + 1, b = a + 1, c = a + n, d = c + 1;
            fprintf(f, "f %d %d %d\nf %d %d %d\n", a, b, d, a, d, c);
        }
    fclose(f);
}

static const cJSON *member(const cJSON *o, const char *key)
{
    const cJSON *x = cJSON_GetObjectItemCaseSensitive(o, key);
    if (!x)
        fail_msg("metrics: no member '%s'", key);
    return x;
}

static double number(const cJSON *o, const char *key)
{
    const cJSON *x = member(o, key);
    if (!cJSON_IsNumber(x))
        fail_msg("metrics: '%s' is not a number", key);
    return x->valuedouble;
}

/* Fails unless object o has exactly the members of the NULL-terminated
 * list, in any order. */
static void exact_members(const cJSON *o, const char *const *keys, const char *what)
{
    const cJSON *x;
    int n = 0, i;
    for (i = 0; keys[i]; i++)
        if (!cJSON_GetObjectItemCaseSensitive(o, keys[i]))
            fail_msg("%s: no member '%s'", what, keys[i]);
    cJSON_ArrayForEach(x, o)
        n++;
    if (n != i) {
        cJSON_ArrayForEach(x, o) {
            for (i = 0; keys[i] && strcmp(keys[i], x->string); i++)
                ;
            if (!keys[i])
                fail_msg("%s: unexpected member '%s'", what, x->string);
        }
    }
}

/* The document's layout (api.h, openapi.yaml Metrics): the daemon answers
 * the same keys for the same request (test_server's test_metrics_same_as_cli
 * compares the two documents key by key). */
static void test_metrics_document_layout(void **state)
{
    static const char *const top[] = {"command", "job", "scheme", "params", "warnings",
                                      "input", "output", "curvature", "flow", "compare",
                                      "timings", "timing", "peak_rss_bytes", "measured",
                                      NULL};
    static const char *const input[] = {"path", "format", "bytes", "info", "mesh", NULL};
    static const char *const output[] = {"path", "format", "bytes", "vertices", "faces",
                                         "area", "volume", "quantization_max_error",
                                         "not_kept", "info", NULL};
    static const char *const timings[] = {"queue_s", "read_s", "decode_s", "flow_s",
                                          "encode_s", "write_s", "metrics_s", "total_s",
                                          NULL};
    static const char *const compare[] = {"rms_m", "rms_rel", "frobenius", "max_err",
                                          "normal_angle_deg", "inverted_faces", "target",
                                          "before", "after", NULL};
    tl_run_result r;
    cJSON *j;
    (void)state;
    tl_write_noisy("sphere_cgal.obj", 0.1, 5, tl_in_scratch("noisy.obj"));
    r = tl_run("smooth", "noisy.obj", "lay.drc", "--iterations", "2", "--target", tl_sphere(),
               "--metrics", "lay.json", NULL);
    if (r.status != 0)
        fail_msg("smooth: status %d: %s", r.status, r.err);
    tl_run_free(&r);
    j = load_json(tl_in_scratch("lay.json"));
    exact_members(j, top, "metrics");
    assert_true(cJSON_IsTrue(member(j, "measured"))); /* --metrics asks for them */
    exact_members(member(j, "input"), input, "input");
    exact_members(member(j, "output"), output, "output");
    exact_members(member(j, "timings"), timings, "timings");
    exact_members(member(j, "timing"), timings, "timing");
    exact_members(member(j, "compare"), compare, "compare");
    assert_true(cJSON_IsArray(member(j, "warnings")));
    assert_true(cJSON_IsNull(member(j, "job")));                  /* the daemon's */
    assert_true(cJSON_IsNull(member(member(j, "timings"), "queue_s")));
    /* the measures before and after the flow are timed (was NaN: null) */
    assert_true(number(member(j, "timings"), "metrics_s") >= 0);
    assert_string_equal(cJSON_GetStringValue(member(j, "command")), "smooth");
    assert_string_equal(cJSON_GetStringValue(member(member(j, "output"), "format")), "draco");
    /* Draco output: the quantization error is measured (a number >= 0). */
    assert_true(number(member(j, "output"), "quantization_max_error") >= 0);
    /* "mesh" repeats "info" (the daemon's first name for it). */
    assert_true(cJSON_Compare(member(member(j, "input"), "info"),
                              member(member(j, "input"), "mesh"), 1));
    /* The flat compare members are the after's. */
    assert_true(number(member(j, "compare"), "rms_m")
                == number(member(member(j, "compare"), "after"), "rms_m"));
    cJSON_Delete(j);
}

/* One volume in the step log, the summary and the mesh information: the
 * signed volume about the input's origin (mcf_mesh_volume), on an open
 * mesh off the origin with a free boundary, where the log measured about
 * the area centroid before (off by about 5/3 here). */
static void test_metrics_one_volume(void **state)
{
    tl_run_result r;
    mcf_mesh *in, *out;
    cJSON *j, *log, *last;
    const cJSON *flow, *inp, *outp;
    double v0, v1;
    int n;
    (void)state;
    write_open_grid(tl_in_scratch("grid.obj"));
    r = tl_run("smooth", "grid.obj", "grid-out.obj", "--iterations", "5", "--dt", "1e-3",
               "--boundary", "free", "--metrics", "grid.json", "--quiet", NULL);
    if (r.status != 0)
        fail_msg("smooth: status %d: %s", r.status, r.err);
    tl_run_free(&r);
    in = load_path(tl_in_scratch("grid.obj"));
    out = load_path(tl_in_scratch("grid-out.obj"));
    j = load_json(tl_in_scratch("grid.json"));
    flow = member(j, "flow");
    inp = member(member(j, "input"), "info");
    outp = member(j, "output");
    v0 = mcf_mesh_volume(in);
    v1 = mcf_mesh_volume(out);
    /* the flow moved the surface: the volume changed measurably */
    assert_true(fabs(v1 - v0) > 1e-4 * fabs(v0));
    /* Each is one sum over 98 faces of terms ~ 5 in size: relative 1e-12
     * covers the rounding of different summation orders and of 17-digit
     * OBJ and JSON numbers. */
    tl_assert_near(number(flow, "volume0"), v0, 1e-12 * fabs(v0), "flow.volume0");
    tl_assert_near(number(inp, "volume"), v0, 1e-12 * fabs(v0), "input.info.volume");
    tl_assert_near(number(flow, "volume1"), v1, 1e-12 * fabs(v1), "flow.volume1");
    tl_assert_near(number(outp, "volume"), v1, 1e-12 * fabs(v1), "output.volume");
    tl_assert_near(number(member(outp, "info"), "volume"), v1, 1e-12 * fabs(v1),
                   "output.info.volume");
    log = cJSON_GetObjectItemCaseSensitive(flow, "log");
    n = cJSON_GetArraySize(log);
    assert_int_equal(n, 5);
    last = cJSON_GetArrayItem(log, n - 1);
    tl_assert_near(number(last, "volume"), v1, 1e-12 * fabs(v1), "last log volume");
    tl_assert_near(number(last, "area"), mcf_mesh_area(out), 1e-12 * mcf_mesh_area(out),
                   "last log area");
    cJSON_Delete(j);
    mcf_mesh_free(in);
    mcf_mesh_free(out);
}

/* The core's warnings reach the document as their names: 1e-9 of
 * unit-area time covers 8e-4 mean edges of diffusion, under the 0.1 of
 * "little_smoothing"; the default amount warns of nothing on the sphere. */
static void test_metrics_warnings(void **state)
{
    tl_run_result r = tl_run("smooth", tl_sphere(), "w.obj", "--iterations", "1", "--dt",
                             "1e-9", "--metrics", "w.json", "--quiet", NULL);
    cJSON *j;
    const cJSON *w;
    (void)state;
    if (r.status != 0)
        fail_msg("smooth: status %d: %s", r.status, r.err);
    tl_run_free(&r);
    j = load_json(tl_in_scratch("w.json"));
    w = member(j, "warnings");
    assert_int_equal(cJSON_GetArraySize(w), 1);
    assert_string_equal(cJSON_GetStringValue(cJSON_GetArrayItem(w, 0)), "little_smoothing");
    assert_true(number(member(j, "flow"), "strength") < 0.1);
    cJSON_Delete(j);

    r = tl_run("smooth", tl_sphere(), "w2.obj", "--metrics", "w2.json", "--quiet", NULL);
    if (r.status != 0)
        fail_msg("smooth: status %d: %s", r.status, r.err);
    tl_run_free(&r);
    j = load_json(tl_in_scratch("w2.json"));
    w = member(j, "warnings");
    assert_true(cJSON_IsArray(w));
    assert_int_equal(cJSON_GetArraySize(w), 0);
    cJSON_Delete(j);
}

/* ------------------------------------------------ what the tool says */

/* Counts the lines of s that start with prefix. */
static int lines_starting(const char *s, const char *prefix)
{
    int n = 0;
    size_t pl = strlen(prefix);
    while (s && *s) {
        const char *nl = strchr(s, '\n');
        if (strncmp(s, prefix, pl) == 0)
            n++;
        s = nl ? nl + 1 : NULL;
    }
    return n;
}

static void test_version(void **state)
{
    tl_run_result r = tl_run("--version", NULL);
    char want[64];
    (void)state;
    assert_int_equal(r.status, 0);
    snprintf(want, sizeof want, "mcf %s\n", API_VERSION);
    assert_string_equal(r.out, want);
    assert_int_equal(r.errlen, 0);
    tl_run_free(&r);
}

/* Each command's --help: its own usage; smooth's lists every parameter of
 * the table (api_params_describe) with its default, and its unit when it
 * has one; convert's the output parameters only. */
static void test_command_help(void **state)
{
    static const char *const cmds[] = {"smooth", "convert", "info", "schemes", "params"};
    cJSON *table = api_params_describe(NULL);
    const cJSON *e;
    tl_run_result r, c;
    size_t i;
    (void)state;
    for (i = 0; i < sizeof cmds / sizeof cmds[0]; i++) {
        char want[64];
        r = tl_run(cmds[i], "--help", NULL);
        assert_int_equal(r.status, 0);
        assert_int_equal(r.errlen, 0);
        snprintf(want, sizeof want, "mcf %s", cmds[i]);
        if (!strstr(r.out, "usage:") || !strstr(r.out, want))
            fail_msg("mcf %s --help: no usage line for it:\n%s", cmds[i], r.out);
        tl_run_free(&r);
    }
    r = tl_run("smooth", "--help", NULL);
    c = tl_run("convert", "--help", NULL);
    assert_non_null(table);
    cJSON_ArrayForEach(e, table) {
        const char *name = cJSON_GetStringValue(cJSON_GetObjectItem(e, "name"));
        const char *unit = cJSON_GetStringValue(cJSON_GetObjectItem(e, "unit"));
        const cJSON *dv = cJSON_GetObjectItem(e, "default");
        char flag[80], line[160], *txt = NULL;
        const char *at;
        size_t k;
        flag[0] = flag[1] = '-';
        for (k = 0; name[k] && k + 3 < sizeof flag; k++)
            flag[k + 2] = name[k] == '_' ? '-' : name[k];
        flag[k + 2] = '\0';
        at = strstr(r.out, flag);
        if (!at)
            fail_msg("mcf smooth --help does not list %s", flag);
        /* its two lines of text: help (and unit), then range and default */
        if (dv && !cJSON_IsString(dv))
            txt = cJSON_PrintUnformatted(dv);
        snprintf(line, sizeof line, "; default %s\n",
                 txt ? txt : dv ? cJSON_GetStringValue(dv)
                 : cJSON_GetStringValue(cJSON_GetObjectItem(e, "default_text")));
        cJSON_free(txt);
        if (!strstr(at, line))
            fail_msg("mcf smooth --help: %s without '%s'", flag, line);
        if (unit) {
            snprintf(line, sizeof line, "unit: %s\n", unit);
            if (!strstr(at, line))
                fail_msg("mcf smooth --help: %s without its unit (%s)", flag, unit);
        }
        if ((strstr(c.out, flag) != NULL) != cJSON_IsTrue(cJSON_GetObjectItem(e, "output")))
            fail_msg("mcf convert --help: %s %s", flag,
                     strstr(c.out, flag) ? "listed, but not an output option" : "missing");
    }
    /* the tool's own options */
    assert_non_null(strstr(r.out, "--strict"));
    assert_non_null(strstr(r.out, "--progress"));
    assert_non_null(strstr(r.out, "--metrics FILE.json"));
    cJSON_Delete(table);
    tl_run_free(&r);
    tl_run_free(&c);
    /* the overview names every command and the exit statuses */
    r = tl_run("--help", NULL);
    assert_non_null(strstr(r.out, "mcf params"));
    assert_non_null(strstr(r.out, "3 `mcf smooth --strict`"));
    tl_run_free(&r);
}

/* A sphere of unit area vanishes at t = 1/(16 pi) = 0.0199: run to 0.03
 * (6 steps of the default desbrun2), it ends as a speck (area x 1e-3). The
 * run succeeds, but says so on stderr; --strict fails it (3) and keeps OUT
 * unwritten; --quiet keeps the warning and drops the summary. */
static void test_warnings_on_stderr(void **state)
{
    struct stat sb;
    tl_run_result r = tl_run("smooth", tl_sphere(), "speck.obj", "--time", "0.03",
                             "--iterations", "6", NULL);
    (void)state;
    if (r.status != 0)
        fail_msg("smooth: status %d: %s", r.status, r.err);
    if (lines_starting(r.err, "mcf: warning: area_loss: ") != 1)
        fail_msg("no area_loss warning on stderr:\n%s", r.err);
    /* the summary line says the result has warnings */
    assert_non_null(strstr(r.err, "-> speck.obj: 812 vertices, 6 steps to t = 0.03"));
    assert_non_null(strstr(r.err, "(with warnings)\n"));
    assert_int_equal(r.outlen, 0);
    tl_run_free(&r);
    assert_int_equal(stat(tl_in_scratch("speck.obj"), &sb), 0);

    r = tl_run("smooth", tl_sphere(), "strict.obj", "--time", "0.03", "--iterations", "6",
               "--strict", "--metrics", "strict.json", NULL);
    assert_int_equal(r.status, 3);
    assert_int_equal(lines_starting(r.err, "mcf: warning: area_loss: "), 1);
    assert_non_null(strstr(r.err, "mcf: --strict: the result has"));
    assert_non_null(strstr(r.err, "'strict.obj' not written\n"));
    tl_run_free(&r);
    assert_int_equal(stat(tl_in_scratch("strict.obj"), &sb), -1);
    /* the metrics say why */
    {
        cJSON *j = load_json(tl_in_scratch("strict.json"));
        const cJSON *w = member(j, "warnings");
        assert_true(cJSON_GetArraySize(w) >= 1);
        cJSON_Delete(j);
    }
    /* a clean run is not affected by --strict: exit 0, OUT written */
    r = tl_run("smooth", tl_sphere(), "clean.obj", "--strict", "--quiet", NULL);
    assert_int_equal(r.status, 0);
    assert_int_equal(r.errlen, 0);
    tl_run_free(&r);
    assert_int_equal(stat(tl_in_scratch("clean.obj"), &sb), 0);

    r = tl_run("smooth", tl_sphere(), "speck2.obj", "--time", "0.03", "--iterations", "6",
               "--quiet", NULL);
    assert_int_equal(r.status, 0);
    assert_int_equal(lines_starting(r.err, "mcf: warning: "), (int)lines_starting(r.err, "mcf: "));
    assert_int_equal(lines_starting(r.err, "mcf: warning: area_loss: "), 1);
    tl_run_free(&r);
}

/* The fairing default's plain progress lines (r: mcf smooth --progress
 * off a terminal), "mcf: P%  PHASE, step K  E s elapsed[, about L s
 * left]": each of the filter's phases reported (the spike repair, the
 * graph, the creases, the set-up, the noise reading, the probes or the
 * factorization; its steps when `steps`; the output at 100% last), the
 * shares and the times never decreasing, at least 5 lines, the time left
 * once a share is done. Before the core reported its phases' own
 * milestones the clean sphere printed 4 (setup, noise, probes, output). */
static void progress_phases(const tl_run_result *r, int steps)
{
    static const char *const phase[] = {"spikes", "graph", "creases", "setup", "noise", "output"};
    int n = 0, last = -1, k;
    double tlast = -1.0;
    const char *s = r->err;
    assert_int_equal(r->status, 0);
    assert_null(strchr(r->err, '\r'));
    while (s && *s) {
        const char *nl = strchr(s, '\n');
        int pct, step;
        double el;
        char name[16];
        if (sscanf(s, "mcf: %d%%  %15[a-z], step %d  %lf s elapsed", &pct, name, &step, &el) == 4) {
            if (pct < last || el < tlast || pct > 100)
                fail_msg("--progress: share or time decreased at '%.*s':\n%s",
                         (int)(nl ? nl - s : (long)strlen(s)), s, r->err);
            last = pct;
            tlast = el;
            n++;
        }
        s = nl ? nl + 1 : NULL;
    }
    for (k = 0; k < 6; k++) {
        char want[32];
        snprintf(want, sizeof want, "%%  %s, step ", phase[k]);
        if (!strstr(r->err, want))
            fail_msg("--progress: no phase '%s':\n%s", phase[k], r->err);
    }
    if (!strstr(r->err, "%  probes, step ") && !strstr(r->err, "%  factor, step "))
        fail_msg("--progress: no probes nor factorization:\n%s", r->err);
    if (steps && !strstr(r->err, "%  steps, step ") && !strstr(r->err, "%  passes, step "))
        fail_msg("--progress: no steps:\n%s", r->err);
    assert_int_equal(lines_starting(r->err, "mcf: 100%  output, step "), 1);
    assert_int_equal(last, 100);
    if (n < 5)
        fail_msg("--progress: %d lines:\n%s", n, r->err);
    assert_non_null(strstr(r->err, " s left\n"));
}

/* Off a terminal (the harness captures stderr in a file): no progress
 * unless --progress, then one plain line per 10% (10 equal steps: 10
 * lines, 10% to 100%), then the summary; --quiet: nothing. */
static void test_progress_lines(void **state)
{
    /* a flow's progress at a named amount (the fairing default and the
     * automatic amount take as many steps as the noise they read says) */
    tl_run_result r = tl_run("smooth", tl_sphere(), "p.obj", "--scheme", "desbrun2", "--strength", "0.33", NULL);
    char want[64];
    int k;
    (void)state;
    assert_int_equal(r.status, 0);
    assert_int_equal(lines_starting(r.err, "mcf: "), 1);
    assert_non_null(strstr(r.err, "-> p.obj: 812 vertices, 10 steps to t = "));
    assert_null(strchr(r.err, '\r'));
    tl_run_free(&r);

    r = tl_run("smooth", tl_sphere(), "p.obj", "--progress", "--scheme", "desbrun2", "--strength", "0.33", NULL);
    assert_int_equal(r.status, 0);
    assert_null(strchr(r.err, '\r'));     /* no bar redrawn in place */
    for (k = 1; k <= 10; k++) {
        snprintf(want, sizeof want, "mcf: %3d%%  steps, step %d  ", 10 * k, k);
        if (lines_starting(r.err, want) != 1)
            fail_msg("--progress: no line '%s':\n%s", want, r.err);
    }
    assert_int_equal(lines_starting(r.err, "mcf: "), 11);
    assert_non_null(strstr(r.err, "-> p.obj: 812 vertices, 10 steps"));
    tl_run_free(&r);

    r = tl_run("smooth", tl_sphere(), "p.obj", "--progress", "--quiet", "--scheme", "desbrun2", "--strength", "0.33", NULL);
    assert_int_equal(r.status, 0);
    assert_int_equal(r.errlen, 0);
    tl_run_free(&r);

    /* the fairing default on the clean sphere (nothing to remove: no
     * steps, the run's plan shrinks after the noise reading) and on the
     * noisy knot (steps): progress_phases */
    r = tl_run("smooth", tl_sphere(), "p.obj", "--progress", NULL);
    progress_phases(&r, 0);
    tl_run_free(&r);
    r = tl_run("smooth", tl_write_noisy("knot1.obj", 0.3, 7, tl_in_scratch("knot_noisy.obj")), "p.obj",
               "--progress", NULL);
    progress_phases(&r, 1);
    tl_run_free(&r);
}

/* Amounts that contradict each other are refused, naming both; amounts
 * that agree are not. */
static void test_contradictory_amounts(void **state)
{
    tl_run_result r;
    (void)state;
    r = tl_run("smooth", tl_sphere(), "c.obj", "--time", "1e-3", "--dt", "1e-4",
               "--iterations", "5", NULL);
    tl_expect_error(&r, 2, "parameters 'time' (0.001) and 'dt' (0.0001) make 10 steps, "
                    "but 'iterations' says 5");
    r = tl_run("smooth", tl_sphere(), "c.obj", "--time", "1e-3", "--dt", "1e-2", NULL);
    tl_expect_error(&r, 2, "parameter 'dt' (0.01) is larger than 'time' (0.001)");
    r = tl_run("smooth", tl_sphere(), "c.obj", "--scheme", "euler", "--time", "1e-3",
               "--dt", "auto", "--iterations", "5", NULL);
    tl_expect_error(&r, 2, "parameters 'time' and 'iterations' contradict 'dt' = auto");
    r = tl_run("smooth", tl_sphere(), "c.obj", "--time", "1e-3", "--dt", "1e-4",
               "--iterations", "10", "--quiet", NULL);
    assert_int_equal(r.status, 0);
    tl_run_free(&r);
}

/* The limits on the input (issue 27: no size wall below memory): none of
 * the old caps (256 MiB, 5M vertices) stands in the tool's way, and its
 * options --max-input-bytes, --max-vertices, --max-faces bound a
 * generated 41 x 41 grid (1,681 vertices, 3,200 triangles, a gentle
 * bump: 1 = just over, 0 = at the bound) the same way the old caps bound
 * a 5,000,001-vertex scan, through the same checks of every decoder. */
static void test_limits(void **state)
{
    enum { N = 41 };
    FILE *f;
    tl_run_result r;
    long bytes;
    char nb[32];
    (void)state;
    f = fopen(tl_in_scratch("grid.obj"), "w");
    assert_non_null(f);
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++)
            fprintf(f, "v %d %d %.6f\n", i, j, 0.3 * sin(0.2 * i) * cos(0.3 * j));
    for (int i = 0; i + 1 < N; i++)
        for (int j = 0; j + 1 < N; j++) {
            int a = i * N + j + 1;
            fprintf(f, "f %d %d %d\nf %d %d %d\n", a, a + N, a + 1, a + 1, a + N, a + N + 1);
        }
    bytes = ftell(f);
    fclose(f);
    r = tl_run("convert", "grid.obj", "grid.ply", NULL);
    assert_int_equal(r.status, 0);
    tl_run_free(&r);
    r = tl_run("smooth", "grid.obj", "g.obj", "--max-vertices", "1680", NULL);
    tl_expect_error(&r, 1, "more than max_vertices (1680) vertices");
    r = tl_run("smooth", "grid.ply", "g.obj", "--max-vertices=1680", NULL);
    tl_expect_error(&r, 1, "ply: 1681 vertices exceed max_vertices (1680)");
    r = tl_run("smooth", "grid.ply", "g.obj", "--max-faces", "3199", NULL);
    tl_expect_error(&r, 1, "ply: 3200 faces exceed max_faces (3199)");
    snprintf(nb, sizeof nb, "%ld", bytes - 1);
    r = tl_run("smooth", "grid.obj", "g.obj", "--max-input-bytes", nb, NULL);
    tl_expect_error(&r, 1, "larger than max_input_bytes");
    r = tl_run("convert", "grid.obj", "g.ply", "--max-vertices", "1680", NULL);
    tl_expect_error(&r, 1, "more than max_vertices (1680) vertices");
    /* steps x vertices, the work of a job that names its steps */
    r = tl_run("smooth", "grid.obj", "g.obj", "--iterations", "3", "--max-work", "5000", NULL);
    tl_expect_error(&r, 1, "work of 3 steps x 1681 vertices = 5.04e+03 exceeds max_work (5e+03)");
    r = tl_run("smooth", "grid.obj", "g.obj", "--max-vertices", "1.5", NULL);
    tl_expect_error(&r, 2, "option '--max-vertices' needs a whole number from 1 to 2147483647");
    r = tl_run("smooth", "grid.obj", "g.obj", "--max-faces", "3000000000", NULL);
    tl_expect_error(&r, 2, "option '--max-faces' needs a whole number");
    /* at the bounds, and with no option at all: accepted */
    snprintf(nb, sizeof nb, "%ld", bytes);
    r = tl_run("smooth", "grid.ply", "g.obj", "--max-vertices", "1681", "--max-faces", "3200",
               "--quiet", NULL);
    assert_int_equal(r.status, 0);
    tl_run_free(&r);
    r = tl_run("smooth", "grid.obj", "g.obj", "--max-input-bytes", nb, "--quiet", NULL);
    assert_int_equal(r.status, 0);
    tl_run_free(&r);
}

/* ---- a run stopped by a signal (issue 27) */

/* A noisy n x n grid (a gentle wave, Gaussian noise of 0.25 of its
 * spacing along z) as a binary PLY with float32 positions: a scan-sized
 * mesh whose default request, the explicit passes above 150,000 vertices,
 * sets up for seconds (the graph, the spike repair, the creases, the
 * noise reading, the probes) before its first pass. */
static void write_big_grid(const char *path, int n)
{
    FILE *f = fopen(path, "wb");
    uint64_t rng = 27;
    float *row = malloc(3 * sizeof(float) * (size_t)n);
    unsigned char face[13];
    assert_non_null(f);
    assert_non_null(row);
    fprintf(f, "ply\nformat binary_little_endian 1.0\nelement vertex %d\nproperty float x\n"
            "property float y\nproperty float z\nelement face %d\n"
            "property list uchar int vertex_indices\nend_header\n", n * n, 2 * (n - 1) * (n - 1));
    for (int i = 0; i < n; i++) {
        for (int j = 0; j < n; j++) {
            row[3 * j] = (float)i;
            row[3 * j + 1] = (float)j;
            row[3 * j + 2] = (float)(3.0 * sin(0.05 * i) * cos(0.04 * j) + 0.25 * tl_gauss01(&rng));
        }
        assert_int_equal(fwrite(row, sizeof(float), 3 * (size_t)n, f), 3 * (size_t)n);
    }
    face[0] = 3;
    for (int i = 0; i + 1 < n; i++)
        for (int j = 0; j + 1 < n; j++) {
            int32_t a = i * n + j, t[2][3] = {{a, a + n, a + 1}, {a + 1, a + n, a + n + 1}};
            for (int k = 0; k < 2; k++) {
                memcpy(face + 1, t[k], sizeof t[k]); /* little-endian, as the header says */
                assert_int_equal(fwrite(face, 1, sizeof face, f), sizeof face);
            }
        }
    free(row);
    assert_int_equal(fclose(f), 0);
}

static double mono_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* mcf with args (NULL-terminated) in the scratch directory, stdout to
 * /dev/null, stderr to *err_fd and, when in_fd is not NULL, stdin from
 * *in_fd (the write ends: the test's). */
static pid_t spawn_mcf(const char *const *args, int *in_fd, int *err_fd)
{
    const char *argv[16];
    int ep[2], ip[2] = {-1, -1}, n = 0;
    pid_t pid;
    argv[n++] = tl_prog();
    for (; *args && n < 15; args++)
        argv[n++] = *args;
    argv[n] = NULL;
    assert_int_equal(pipe(ep), 0);
    if (in_fd)
        assert_int_equal(pipe(ip), 0);
    pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        int dn = open("/dev/null", O_WRONLY);
        if (dn < 0 || chdir(tl_scratch()) != 0)
            _exit(127);
        dup2(dn, 1);
        dup2(ep[1], 2);
        close(ep[0]);
        if (in_fd) {
            dup2(ip[0], 0);
            close(ip[1]); /* else stdin never ends */
        }
        execv(argv[0], (char *const *)(void *)argv);
        _exit(127);
    }
    close(ep[1]);
    *err_fd = ep[0];
    if (in_fd) {
        close(ip[0]);
        *in_fd = ip[1];
    }
    return pid;
}

/* Appends the child's stderr to buf (cap bytes, kept NUL-terminated)
 * until want (NULL: EOF) is in it, EOF, or the monotonic deadline; 1 when
 * what was waited for came. */
static int read_until(int fd, char *buf, size_t cap, size_t *len, const char *want, double deadline)
{
    for (;;) {
        struct pollfd pf = {fd, POLLIN, 0};
        double left = deadline - mono_s();
        ssize_t r;
        if (want && strstr(buf, want))
            return 1;
        if (left <= 0 || poll(&pf, 1, (int)(left * 1000) + 1) <= 0)
            return 0;
        r = read(fd, buf + *len, cap - 1 - *len);
        if (r <= 0)
            return want == NULL;
        *len += (size_t)r;
        buf[*len] = '\0';
    }
}

/* The exit status of pid (-1: killed by a signal), waiting at most until
 * the deadline: past it, the child is killed and the test fails (a hang
 * detector, not a timing claim). */
static int wait_exit(pid_t pid, double deadline, const char *what)
{
    int st;
    for (;;) {
        pid_t w = waitpid(pid, &st, WNOHANG);
        assert_true(w >= 0);
        if (w == pid)
            return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
        if (mono_s() > deadline) {
            kill(pid, SIGKILL);
            waitpid(pid, &st, 0);
            fail_msg("%s: mcf did not exit within its bound", what);
        }
        nanosleep(&(struct timespec){0, 20000000}, NULL);
    }
}

/* No file of the scratch directory starts with prefix (OUT's temporary
 * file, OUT itself). */
static void assert_no_file(const char *prefix)
{
    DIR *d = opendir(tl_scratch());
    struct dirent *e;
    assert_non_null(d);
    while ((e = readdir(d)))
        if (strncmp(e->d_name, prefix, strlen(prefix)) == 0)
            fail_msg("'%s' left in the scratch directory", e->d_name);
    closedir(d);
}

/* SIGTERM during the set-up of a 640,000-vertex scan's default request
 * (sent once its first milestone line, a set-up phase's, is out): mcf
 * stops at the next phase, not at its first pass minutes later (the 7M
 * scan's set-up: 70 s of wall at load 10), exits 143 with one line
 * naming the signal and the phase, and leaves OUT as it was (here: an
 * older file) with no temporary file beside it. SIGINT while the mesh is
 * still arriving on stdin: 130, nothing written. The 60 s bounds detect a
 * hang; they are not the promise (a phase: seconds). */
static void test_signal_stops(void **state)
{
    static char err[65536];
    const char *const setup_args[] = {"smooth", "big.ply", "out.ply", "--progress", NULL};
    const char *const stdin_args[] = {"smooth", "-", "piped.ply", NULL};
    char *bytes, *old;
    size_t len, n = 0, oldlen;
    int efd, ifd;
    pid_t pid;
    FILE *f;
    (void)state;
    signal(SIGPIPE, SIG_IGN);
    write_big_grid(tl_in_scratch("big.ply"), 800);
    f = fopen(tl_in_scratch("out.ply"), "w");
    assert_non_null(f);
    fputs("an older out.ply\n", f);
    assert_int_equal(fclose(f), 0);

    err[0] = '\0';
    pid = spawn_mcf(setup_args, NULL, &efd);
    if (!read_until(efd, err, sizeof err, &n, "\n", mono_s() + 60)) {
        kill(pid, SIGKILL);
        waitpid(pid, NULL, 0);
        fail_msg("no progress line within 60 s: %s", err);
    }
    assert_non_null(strstr(err, "mcf: "));
    assert_null(strstr(err, "passes")); /* still setting up */
    assert_int_equal(kill(pid, SIGTERM), 0);
    read_until(efd, err, sizeof err, &n, NULL, mono_s() + 60);
    close(efd);
    if (wait_exit(pid, mono_s() + 60, "SIGTERM in the set-up") != 143)
        fail_msg("want exit status 143; stderr:\n%s", err);
    if (!strstr(err, "mcf: smooth: stopped by SIGTERM (canceled before the ") ||
        !strstr(err, "): 'out.ply' not written\n"))
        fail_msg("want the line of a stop in the set-up; stderr:\n%s", err);
    assert_int_equal(tl_read_file(tl_in_scratch("out.ply"), &old, &oldlen), 0);
    assert_string_equal(old, "an older out.ply\n");
    free(old);
    assert_no_file("out.ply.");

    assert_int_equal(tl_read_file(tl_in_scratch("big.ply"), &bytes, &len), 0);
    n = 0;
    err[0] = '\0';
    pid = spawn_mcf(stdin_args, &ifd, &efd);
    /* the writes block until mcf reads: it is in its read when they end */
    assert_int_equal(write(ifd, bytes, len / 2), (ssize_t)(len / 2));
    assert_int_equal(kill(pid, SIGINT), 0);
    close(ifd);
    free(bytes);
    read_until(efd, err, sizeof err, &n, NULL, mono_s() + 60);
    close(efd);
    if (wait_exit(pid, mono_s() + 60, "SIGINT in the read") != 130)
        fail_msg("want exit status 130; stderr:\n%s", err);
    assert_string_equal(err, "mcf: smooth: stopped by SIGINT while its input was read: 'piped.ply' "
                        "not written\n");
    assert_no_file("piped.ply");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_help),
        cmocka_unit_test(test_schemes),
        cmocka_unit_test(test_info),
        cmocka_unit_test(test_draco_bound),
        cmocka_unit_test(test_smooth_metrics),
        cmocka_unit_test(test_smooth_noise_target_fixed),
        cmocka_unit_test(test_convert),
        cmocka_unit_test(test_errors),
        cmocka_unit_test(test_metrics_document_layout),
        cmocka_unit_test(test_metrics_one_volume),
        cmocka_unit_test(test_metrics_warnings),
        cmocka_unit_test(test_version),
        cmocka_unit_test(test_command_help),
        cmocka_unit_test(test_warnings_on_stderr),
        cmocka_unit_test(test_progress_lines),
        cmocka_unit_test(test_contradictory_amounts),
        cmocka_unit_test(test_limits),
        cmocka_unit_test(test_signal_stops),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
