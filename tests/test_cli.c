/*
 * test_cli.c - the `mcf` tool end to end: runs $MCF_BUILD/mcf (default
 * build/mcf) as a child process on the real meshes and checks exit codes,
 * stdout JSON, the files written and the one-line error contract.
 *
 * Everything runs on sphere_cgal.obj (812 vertices) with a handful of
 * steps, so the whole binary takes well under a second.
 */
#define _XOPEN_SOURCE 700 /* realpath */
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "testlib.h"
#include "../api/api.h"

static char dir[64];          /* scratch directory of this run */
static char mcf_path[4096];
static char sphere[4096];

typedef struct {
    int status;               /* exit status, or -1 when killed */
    char *out, *err;          /* captured, NUL-terminated */
    size_t outlen, errlen;
} run_result;

static void result_free(run_result *r)
{
    free(r->out);
    free(r->err);
}

/* Runs mcf with the NULL-terminated arguments. */
static run_result run(const char *a0, ...)
{
    const char *argv[40];
    char opath[128], epath[128];
    run_result r = {0, NULL, NULL, 0, 0};
    va_list ap;
    int n = 0, st;
    pid_t pid;

    argv[n++] = mcf_path;
    va_start(ap, a0);
    for (const char *a = a0; a && n < 39; a = va_arg(ap, const char *))
        argv[n++] = a;
    va_end(ap);
    argv[n] = NULL;
    snprintf(opath, sizeof opath, "%s/stdout", dir);
    snprintf(epath, sizeof epath, "%s/stderr", dir);
    pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        int fo = open(opath, O_WRONLY | O_CREAT | O_TRUNC, 0600);
        int fe = open(epath, O_WRONLY | O_CREAT | O_TRUNC, 0600);
        if (fo < 0 || fe < 0 || chdir(dir) != 0)
            _exit(127);
        dup2(fo, 1);
        dup2(fe, 2);
        execv(mcf_path, (char *const *)(void *)argv);
        _exit(127);
    }
    assert_int_equal(waitpid(pid, &st, 0), pid);
    r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
    if (r.status == 127)
        fail_msg("cannot run %s (set MCF_BUILD)", mcf_path);
    assert_int_equal(tl_read_file(opath, &r.out, &r.outlen), 0);
    assert_int_equal(tl_read_file(epath, &r.err, &r.errlen), 0);
    return r;
}

/* An error run: status code, exactly one stderr line "mcf: ...want...". */
static void expect_error(run_result *r, int code, const char *want)
{
    const char *nl = strchr(r->err, '\n');
    if (r->status != code || strncmp(r->err, "mcf: ", 5) != 0 || !nl
        || nl[1] != '\0' || !strstr(r->err, want))
        fail_msg("status %d, stderr \"%s\"; want status %d and one line with \"%s\"",
                 r->status, r->err, code, want);
    result_free(r);
}

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

static const char *in_dir(const char *name)
{
    static char p[4][256];
    static int k;
    k = (k + 1) % 4;
    snprintf(p[k], sizeof p[k], "%s/%s", dir, name);
    return p[k];
}

static int setup(void **state)
{
    const char *b = getenv("MCF_BUILD");
    char rel[4096];
    (void)state;
    /* Absolute paths: the children run inside the scratch directory. */
    snprintf(rel, sizeof rel, "%s/mcf", b && *b ? b : "build");
    if (!realpath(rel, mcf_path)) {
        fprintf(stderr, "test_cli: no %s (build it, or set MCF_BUILD)\n", rel);
        return -1;
    }
    snprintf(rel, sizeof rel, "%s/sphere_cgal.obj", tl_meshes_dir());
    if (!realpath(rel, sphere)) {
        fprintf(stderr, "test_cli: no %s (set MCF_MESHES)\n", rel);
        return -1;
    }
    strcpy(dir, "/tmp/mcf_test_cli_XXXXXX");
    return mkdtemp(dir) ? 0 : -1;
}

static int teardown(void **state)
{
    char cmd[128];
    (void)state;
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    return system(cmd) == 0 ? 0 : -1;
}

static void test_help(void **state)
{
    run_result r = run("--help", NULL);
    (void)state;
    assert_int_equal(r.status, 0);
    assert_non_null(strstr(r.out, "usage:"));
    assert_non_null(strstr(r.out, "mcf smooth IN OUT"));
    assert_non_null(strstr(r.out, "mcf convert IN OUT"));
    assert_int_equal(r.errlen, 0);
    result_free(&r);
}

static void test_schemes(void **state)
{
    run_result r = run("schemes", NULL);
    cJSON *j;
    (void)state;
    assert_int_equal(r.status, 0);
    assert_int_equal(r.errlen, 0);
    j = cJSON_Parse(r.out);
    assert_non_null(j);
    assert_int_equal(cJSON_GetArraySize(cJSON_GetObjectItem(j, "schemes")), MCF_NSCHEMES);
    cJSON_Delete(j);
    result_free(&r);
}

static void test_info(void **state)
{
    run_result r = run("info", sphere, NULL);
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
    result_free(&r);
}

static void test_smooth_metrics(void **state)
{
    run_result r = run("smooth", sphere, "out.obj", "--iterations", "5",
                       "--metrics", "m.json", "--quiet", NULL);
    mcf_mesh *in, *out;
    cJSON *j, *flow;
    double a_in, a_out;
    (void)state;
    if (r.status != 0)
        fail_msg("smooth: status %d: %s", r.status, r.err);
    assert_int_equal(r.errlen, 0);
    assert_int_equal(r.outlen, 0);
    result_free(&r);
    in = load_path(sphere);
    out = load_path(in_dir("out.obj"));
    assert_int_equal(mcf_mesh_nvertices(out), 812);
    assert_memory_equal(mcf_mesh_faces(in), mcf_mesh_faces(out), 3 * 4 * 1620);
    /* MCF is the gradient flow of area: five steps strictly shrink it. */
    a_in = mcf_mesh_area(in);
    a_out = mcf_mesh_area(out);
    assert_true(a_out < a_in);

    j = load_json(in_dir("m.json"));
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

/* Noise, a target, fixed vertices and an output format by flag. */
static void test_smooth_noise_target_fixed(void **state)
{
    FILE *f = fopen(in_dir("fix.txt"), "w");
    run_result r;
    mcf_mesh *ref, *out;
    mcf_error err;
    cJSON *j, *cmp;
    const int fixed[] = {0, 17, 400};
    (void)state;
    assert_non_null(f);
    fprintf(f, "0, 17\n400\n");
    fclose(f);
    r = run("smooth", sphere, "out.mesh", "--format", "obj", "--noise", "0.05",
            "--seed", "3", "--target", sphere, "--fix-vertices", "fix.txt",
            "--iterations", "4", "--scheme", "desbrun", "--metrics", "m2.json", NULL);
    if (r.status != 0)
        fail_msg("smooth: status %d: %s", r.status, r.err);
    result_free(&r);
    /* The same noise, made here from the same seed (it is deterministic). */
    ref = load_path(sphere);
    assert_int_equal(mcf_mesh_add_noise(ref, 0.05, 3, &err), MCF_OK);
    out = load_path(in_dir("out.mesh"));
    for (int k = 0; k < 3; k++)
        for (int c = 0; c < 3; c++)
            /* Fixed vertices do not move; normalizing to unit area and
             * back may cost a few ulp of |x| ~ 1, far below 1e-12. */
            tl_assert_near(mcf_mesh_positions(out)[3 * fixed[k] + c],
                           mcf_mesh_positions(ref)[3 * fixed[k] + c], 1e-12, "fixed vertex");
    /* A free vertex did move (by far more than roundoff). */
    assert_true(fabs(mcf_mesh_positions(out)[3 * 1] - mcf_mesh_positions(ref)[3 * 1])
                + fabs(mcf_mesh_positions(out)[3 * 1 + 1] - mcf_mesh_positions(ref)[3 * 1 + 1])
                + fabs(mcf_mesh_positions(out)[3 * 1 + 2] - mcf_mesh_positions(ref)[3 * 1 + 2]) > 1e-9);
    j = load_json(in_dir("m2.json"));
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
    run_result r = run("convert", sphere, "copy.obj", NULL);
    mcf_mesh *a, *b;
    (void)state;
    assert_int_equal(r.status, 0);
    result_free(&r);
    a = load_path(sphere);
    b = load_path(in_dir("copy.obj"));
    /* OBJ -> OBJ keeps every bit of every coordinate. */
    assert_memory_equal(mcf_mesh_positions(a), mcf_mesh_positions(b), 3 * 8 * 812);
    assert_memory_equal(mcf_mesh_faces(a), mcf_mesh_faces(b), 3 * 4 * 1620);
    mcf_mesh_free(b);
    /* To Draco by extension, and back through info. */
    r = run("convert", sphere, "copy.drc", NULL);
    if (r.status != 0)
        fail_msg("convert to drc: %s", r.err);
    result_free(&r);
    r = run("info", "copy.drc", NULL);
    assert_int_equal(r.status, 0);
    assert_non_null(strstr(r.out, "\"format\":\t\"draco\""));
    assert_non_null(strstr(r.out, "\"vertices\":\t812"));
    result_free(&r);
    /* To PLY, with the curvature properties in the header. */
    r = run("convert", "copy.drc", "copy.ply", NULL);
    if (r.status != 0)
        fail_msg("convert to ply: %s", r.err);
    result_free(&r);
    {
        char *buf;
        size_t len;
        assert_int_equal(tl_read_file(in_dir("copy.ply"), &buf, &len), 0);
        assert_non_null(strstr(buf, "property float mean_curvature"));
        assert_non_null(strstr(buf, "property float gaussian_curvature"));
        free(buf);
        b = load_path(in_dir("copy.ply"));
        assert_int_equal(mcf_mesh_nvertices(b), 812);
        mcf_mesh_free(b);
    }
    mcf_mesh_free(a);
}

static void test_errors(void **state)
{
    FILE *f;
    run_result r;
    struct stat sb;
    (void)state;
    r = run(NULL);
    expect_error(&r, 2, "missing command");
    r = run("frobnicate", NULL);
    expect_error(&r, 2, "unknown command 'frobnicate'");
    r = run("smooth", sphere, "o.obj", "--bogus", NULL);
    expect_error(&r, 2, "unknown option '--bogus'");
    r = run("smooth", sphere, NULL);
    expect_error(&r, 2, "needs IN and OUT");
    r = run("smooth", sphere, "o.obj", "--iterations", NULL);
    expect_error(&r, 2, "'--iterations' needs a value");
    r = run("smooth", sphere, "o.obj", "--dt", "abc", NULL);
    expect_error(&r, 2, "parameter 'dt' must be a number > 0 and <= 1000 or \"auto\", got \"abc\"");
    r = run("smooth", sphere, "o.obj", "--scheme=rk4", NULL);
    expect_error(&r, 2, "parameter 'scheme' must be one of");
    r = run("smooth", sphere, "o.obj", "--time", "0.1", "--iterations", "3", NULL);
    expect_error(&r, 2, "either 'time' or 'iterations'");
    r = run("smooth", sphere, "o.xyz", NULL);
    expect_error(&r, 2, "cannot tell the output format from 'o.xyz'");
    r = run("smooth", "missing.obj", "o.obj", NULL);
    expect_error(&r, 1, "cannot read 'missing.obj'");
    r = run("info", NULL);
    expect_error(&r, 2, "info: needs exactly one input file");
    r = run("schemes", "extra", NULL);
    expect_error(&r, 2, "schemes: takes no arguments");
    r = run("convert", sphere, "o.obj", "--iterations", "3", NULL);
    expect_error(&r, 2, "convert: unknown option '--iterations'");
    /* A malformed input names its line; nothing is written. */
    f = fopen(in_dir("bad.obj"), "w");
    assert_non_null(f);
    fprintf(f, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
    fclose(f);
    r = run("smooth", "bad.obj", "never.obj", NULL);
    expect_error(&r, 1, "bad.obj: line 4: face index 9 out of range (1..3)");
    assert_int_equal(stat(in_dir("never.obj"), &sb), -1);
    /* A fixed vertex out of range, and a target of another shape. */
    f = fopen(in_dir("fix2.txt"), "w");
    assert_non_null(f);
    fprintf(f, "5 812\n");
    fclose(f);
    r = run("smooth", sphere, "o.obj", "--fix-vertices", "fix2.txt", NULL);
    expect_error(&r, 2, "index 812 out of range (0..811)");
    r = run("smooth", sphere, "o.obj", "--target", "bad.obj", NULL);
    expect_error(&r, 1, "bad.obj: line 4");
    r = run("smooth", sphere, "o.obj", "--target", "copy.obj", "--fix-vertices", "missing.txt", NULL);
    expect_error(&r, 1, "cannot read 'missing.txt'");
    assert_int_equal(stat(in_dir("o.obj"), &sb), -1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_help),
        cmocka_unit_test(test_schemes),
        cmocka_unit_test(test_info),
        cmocka_unit_test(test_smooth_metrics),
        cmocka_unit_test(test_smooth_noise_target_fixed),
        cmocka_unit_test(test_convert),
        cmocka_unit_test(test_errors),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
