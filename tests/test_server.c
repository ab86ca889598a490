/* SPDX-License-Identifier: MIT */
/*
 * test_server.c - integration tests of mcfd: the real daemon, started as
 * a child process on a loopback port, driven with libcurl.
 *
 * Every daemon runs `$MCF_BUILD/mcfd --bind 127.0.0.1 --port 0` (MCF_BUILD
 * defaults to "build") on a spool under a fresh temporary directory; the
 * test reads the one "mcfd listening on http://127.0.0.1:PORT" line from
 * its stdout and sends its stderr (JSON log lines) to a file that is
 * printed when something fails. Meshes come from tests/data/meshes
 * (tl_need_mesh).
 *
 * Nothing here can hang: every transfer has a curl timeout, every poll
 * loop a deadline, every wait for a process exit a bound after which the
 * process is killed and the test fails. The work per job is small
 * (sphere_cgal.obj, 812 vertices, about 0.5-1 ms per step here), so the
 * whole binary takes well under a minute on two shared cores.
 *
 * This file: the REST API, one request at a time: the service endpoints,
 * POST /smooth in every form (multipart, raw, glTF, attributes, targets,
 * ndjson progress), async jobs and their cancel, the errors as
 * problem+json, the page, the per-vertex fields and the metrics document
 * (the same as the CLI's). The other concerns are
 * test_server_{http,spool,life,limits}.c; what they share is srvlib.c.
 */
#include "srvlib.h"

/* Probes, schemes, the OpenAPI document, metrics, unknown routes. */
static void test_service_endpoints(void **state)
{
    resp_t r;
    cJSON *j, *s;
    char ct[128];
    int found = 0;

    (void)state;
    http(&g_main, "GET", "/healthz", NULL, NULL, &r);
    expect_status(&g_main, &r, 200, "healthz");
    resp_free(&r);
    http(&g_main, "GET", "/readyz", NULL, NULL, &r);
    expect_status(&g_main, &r, 200, "readyz");
    resp_free(&r);

    http(&g_main, "GET", "/v1/schemes", NULL, NULL, &r);
    expect_status(&g_main, &r, 200, "schemes");
    j = body_json(&r, "schemes");
    cJSON_ArrayForEach(s, cJSON_GetObjectItemCaseSensitive(j, "schemes"))
        found += strcmp(jstr(s, "name"), "desbrun2") == 0;
    assert_int_equal(found, 1);
    cJSON_Delete(j);
    resp_free(&r);

    http(&g_main, "GET", "/openapi.yaml", NULL, NULL, &r);
    expect_status(&g_main, &r, 200, "openapi");
    assert_true(strncmp(r.body.data, "openapi: 3.", 11) == 0);
    assert_non_null(strstr(r.body.data, "/v1/jobs/{id}/events"));
    assert_non_null(header(&r, "Content-Type", ct, sizeof ct));
    assert_string_equal(ct, "application/yaml");
    resp_free(&r);

    http(&g_main, "GET", "/metrics", NULL, NULL, &r);
    expect_status(&g_main, &r, 200, "metrics");
    assert_true(strncmp(header(&r, "Content-Type", ct, sizeof ct), "text/plain",
                        10) == 0);
    /* the flags of group_setup, visible as gauges */
    assert_true(metric(r.body.data, "mcfd_workers") == 2);
    assert_true(metric(r.body.data, "mcfd_queue_capacity") == 8);
    assert_non_null(strstr(r.body.data, "# TYPE mcfd_job_duration_seconds histogram"));
    assert_non_null(strstr(r.body.data, "# TYPE mcfd_upload_bytes histogram"));
    resp_free(&r);

    http(&g_main, "GET", "/nope", NULL, NULL, &r);
    expect_problem(&g_main, &r, 404, "ENOTFOUND", "/nope", "unknown route");
    resp_free(&r);
    http(&g_main, "GET", "/smooth", NULL, NULL, &r);
    expect_problem(&g_main, &r, 405, "EMETHOD", "GET", "GET /smooth");
    assert_string_equal(header(&r, "Allow", ct, sizeof ct), "POST");
    resp_free(&r);
}

/* Follows the Link header of a /smooth answer to the job's metrics. */
static cJSON *follow_metrics_link(const daemon_t *d, const resp_t *r,
                                  const char *id)
{
    char link[256], want[160], path[160];
    resp_t m;
    cJSON *j;

    assert_non_null(header(r, "Link", link, sizeof link));
    snprintf(want, sizeof want, "</v1/jobs/%s/metrics>; rel=\"metrics\"", id);
    assert_string_equal(link, want);
    snprintf(path, sizeof path, "/v1/jobs/%s/metrics", id);
    http(d, "GET", path, NULL, NULL, &m);
    expect_status(d, &m, 200, "metrics link");
    j = body_json(&m, "metrics link");
    assert_string_equal(jstr(j, "job"), id);
    resp_free(&m);
    return j;
}

/* curl -F mesh=@sphere_cgal.obj '/smooth?scheme=desbrun2&strength=0.33' (an
 * amount named: without one, the automatic amount finds no noise on this
 * clean sphere and returns it unchanged) */
static void test_smooth_obj_multipart(void **state)
{
    upload_t up = {.mesh = "sphere_cgal.obj"};
    resp_t r;
    char id[64], buf[256];
    api_format fmt;
    mcf_mesh *in = tl_load("sphere_cgal.obj"), *out;
    cJSON *m;

    (void)state;
    http(&g_main, "POST", "/smooth?scheme=desbrun2&strength=0.33", NULL, &up, &r);
    expect_status(&g_main, &r, 200, "POST /smooth obj");
    assert_string_equal(header(&r, "Content-Type", buf, sizeof buf), "model/obj");
    assert_string_equal(header(&r, "Content-Disposition", buf, sizeof buf),
                        "attachment; filename=\"sphere_cgal-smoothed.obj\"");
    assert_non_null(header(&r, "X-Job-Id", id, sizeof id));
    out = decode_body(&r, &fmt);
    assert_int_equal(fmt, API_FMT_OBJ);
    assert_int_equal(mcf_mesh_nvertices(out), 812);
    assert_int_equal(mcf_mesh_nfaces(out), 1620);
    /* Mean curvature flow shrinks a sphere: its volume must drop. */
    assert_true(mcf_mesh_volume(out) < mcf_mesh_volume(in));
    m = follow_metrics_link(&g_main, &r, id);
    assert_string_equal(jstr(m, "scheme"), "desbrun2");
    assert_int_equal((int)jnum(m, "flow.steps"), 10); /* the default */
    assert_int_equal((int)jnum(m, "output.vertices"), 812);
    /* Same number, two routes: the metrics' volume is the body's, to the
     * 17 significant digits OBJ carries (relative 1e-12). */
    tl_assert_near(jnum(m, "output.volume"), mcf_mesh_volume(out),
                   1e-12 * fabs(mcf_mesh_volume(out)), "output volume");
    cJSON_Delete(m);
    mcf_mesh_free(out);
    mcf_mesh_free(in);
    resp_free(&r);
}

/* curl -F mesh=@bunny.drc '/v1/smooth?scheme=desbrun2' */
static void test_smooth_draco_multipart(void **state)
{
    upload_t up = {.mesh = "bunny.drc"};
    resp_t r;
    char id[64], buf[256];
    api_format fmt;
    mcf_mesh *in = tl_load("bunny.drc"), *out;
    cJSON *m;

    (void)state;
    http(&g_main, "POST", "/v1/smooth?scheme=desbrun2&iterations=3", NULL, &up,
         &r);
    expect_status(&g_main, &r, 200, "POST /v1/smooth drc");
    assert_string_equal(header(&r, "Content-Disposition", buf, sizeof buf),
                        "attachment; filename=\"bunny-smoothed.drc\"");
    assert_non_null(header(&r, "X-Job-Id", id, sizeof id));
    out = decode_body(&r, &fmt);
    assert_int_equal(fmt, API_FMT_DRACO);
    assert_int_equal(mcf_mesh_nvertices(out), mcf_mesh_nvertices(in));
    assert_int_equal(mcf_mesh_nvertices(out), 34834); /* SOURCES.md */
    assert_int_equal(mcf_mesh_nfaces(out), 69451);
    m = follow_metrics_link(&g_main, &r, id);
    assert_int_equal((int)jnum(m, "flow.steps"), 3);
    assert_string_equal(jstr(cJSON_GetObjectItemCaseSensitive(m, "input"),
                             "format"), "draco");
    cJSON_Delete(m);
    mcf_mesh_free(out);
    mcf_mesh_free(in);
    resp_free(&r);
}

/* Issue 20: glTF through the REST door. A GLB of two primitives (uploaded
 * as a form field) with no scheme named (whatever the default is), comes
 * back as a GLB; a .gltf sent raw as model/gltf+json is asked for as GLB;
 * a GLB+Draco scan stays Draco. Debian's assimp reads every answer. */
static void test_smooth_gltf(void **state)
{
    char path[1024], buf[256], *raw = NULL;
    static const char *const h[] = {"Content-Type: model/gltf+json", "Expect:", NULL};
    upload_t up;
    resp_t r;
    api_format fmt;
    mcf_mesh *out;
    size_t len;

    (void)state;
    snprintf(path, sizeof path, "%s/gltf/sphere_2prims.glb", getenv("MCF_TESTDATA"));
    memset(&up, 0, sizeof up);
    up.mesh = path;
    http(&g_main, "POST", "/v1/smooth", NULL, &up, &r);
    expect_status(&g_main, &r, 200, "POST /v1/smooth glb");
    assert_string_equal(header(&r, "Content-Type", buf, sizeof buf), "model/gltf-binary");
    assert_string_equal(header(&r, "Content-Disposition", buf, sizeof buf),
                        "attachment; filename=\"sphere_2prims-smoothed.glb\"");
    out = decode_body(&r, &fmt);
    assert_int_equal(fmt, API_FMT_GLB);
    assert_int_equal(mcf_mesh_nvertices(out), 812); /* the two primitives, welded */
    tl_assimp_reads(r.body.data, r.body.len, "rest.glb", 966, 1670); /* and the LINES primitive */
    mcf_mesh_free(out);
    resp_free(&r);

    snprintf(path, sizeof path, "%s/gltf/sphere_2prims.gltf", getenv("MCF_TESTDATA"));
    assert_int_equal(tl_read_file(path, &raw, &len), 0);
    memset(&up, 0, sizeof up);
    up.raw = raw;
    up.raw_len = len;
    http(&g_main, "POST", "/smooth?format=glb&iterations=2", h, &up, &r);
    free(raw);
    expect_status(&g_main, &r, 200, "POST /smooth gltf -> glb");
    assert_string_equal(header(&r, "Content-Type", buf, sizeof buf), "model/gltf-binary");
    out = decode_body(&r, &fmt);
    assert_int_equal(fmt, API_FMT_GLB);
    tl_assimp_reads(r.body.data, r.body.len, "rest2.glb", 866, 1620);
    mcf_mesh_free(out);
    resp_free(&r);

    post_file(&g_main, "/smooth?iterations=2", "gltf/car_draco.glb", &r);
    expect_status(&g_main, &r, 200, "POST /smooth glb+draco");
    assert_non_null(strstr(r.body.data + 20, "\"KHR_draco_mesh_compression\":{")); /* the JSON chunk */
    tl_assimp_reads(r.body.data, r.body.len, "rest3.glb", 0, 1744);
    resp_free(&r);
}

/* Threads stay bounded: main + 2 workers + 2 HTTP threads, after
 * test_smooth_draco_multipart (just before in main's list) has run a job
 * on the bunny. CHOLMOD opens no threads (the Makefile links a copy
 * without OpenMP; Debian's own opened 3 more per worker there, with its
 * num_threads(4) regions) and OpenBLAS has one per job. Without /proc
 * there is nothing to count: skipped, saying so. */
static void test_thread_count(void **state)
{
    char st[64], *status = NULL, why[128];
    const char *t;
    size_t n;

    (void)state;
    snprintf(st, sizeof st, "/proc/%d/status", (int)g_main.pid);
    if (tl_read_file(st, &status, &n) != 0) {
        snprintf(why, sizeof why, "cannot read %s to count mcfd's threads", st);
        tl_skip("/proc", why);
    }
    t = strstr(status, "\nThreads:");
    assert_non_null(t);
#if defined(__SANITIZE_THREAD__)
    assert_int_equal(atoi(t + 9), 6); /* and ThreadSanitizer's background thread */
#else
    assert_int_equal(atoi(t + 9), 5);
#endif
    free(status);
}

/* Attributes through the daemon (issue 12): car.drc's texcoords and
 * normals come back in the default Draco output, float32 and raw like the
 * input; PLY is float with nx ny nz and the face texcoord list (UV seams
 * at the welded vertices), and the curvature properties only with
 * ply_curvature=true, as in mcf. */
static void test_smooth_attributes(void **state)
{
    upload_t up = {.mesh = "car.drc"};
    resp_t r;
    mcf_mesh *m = NULL;
    api_attrs *a = NULL;
    mcf_error err;
    int pass;

    (void)state;
    http(&g_main, "POST", "/smooth?iterations=1&dt=1e-5", NULL, &up, &r);
    expect_status(&g_main, &r, 200, "car.drc");
    assert_int_equal(api_mesh_decode_attrs(r.body.data, r.body.len, NULL, &m, &a,
                                           NULL, &err), MCF_OK);
    assert_int_equal(mcf_mesh_nfaces(m), 1744);
    assert_true(api_attrs_get(a, API_ATTR_TEXCOORD, NULL, NULL, NULL, NULL));
    assert_true(api_attrs_get(a, API_ATTR_NORMAL, NULL, NULL, NULL, NULL));
    assert_int_equal(api_attrs_float32(a), 1);
    assert_int_equal(api_attrs_draco_bits(a, API_ATTR_POSITION), 0);
    api_attrs_free(a);
    mcf_mesh_free(m);
    resp_free(&r);
    for (pass = 0; pass < 2; pass++) {
        http(&g_main, "POST",
             pass ? "/smooth?iterations=1&dt=1e-5&format=ply&ply_curvature=true"
                  : "/smooth?iterations=1&dt=1e-5&format=ply",
             NULL, &up, &r);
        expect_status(&g_main, &r, 200, "car.drc to ply");
        assert_non_null(strstr(r.body.data, "property float x\n"));
        assert_non_null(strstr(r.body.data, "property float nx\n"));
        /* car.drc's seams (vertices welded, texcoords per corner) */
        assert_non_null(strstr(r.body.data, "property list uchar float texcoord\n"));
        assert_true((strstr(r.body.data, "property float mean_curvature\n") != NULL)
                    == pass);
        resp_free(&r);
    }
}

/* The raw body, params from a JSON field and a plain field, format=. */
static void test_smooth_raw_and_params(void **state)
{
    char *obj = NULL, path[1024], buf[128], id[64];
    size_t len = 0;
    upload_t raw;
    static const char *const h[] = {"Content-Type: model/obj", NULL};
    resp_t r;
    api_format fmt;
    mcf_mesh *out;
    cJSON *m;

    (void)state;
    mesh_path(path, sizeof path, "sphere_cgal.obj");
    assert_int_equal(tl_read_file(path, &obj, &len), 0);
    raw = (upload_t){.raw = obj, .raw_len = len};
    http(&g_main, "POST", "/smooth?format=ply&iterations=2", h, &raw, &r);
    expect_status(&g_main, &r, 200, "raw body, format=ply");
    out = decode_body(&r, &fmt);
    assert_int_equal(fmt, API_FMT_PLY);
    assert_int_equal(mcf_mesh_nvertices(out), 812);
    assert_string_equal(header(&r, "Content-Disposition", buf, sizeof buf),
                        "attachment; filename=\"mesh-smoothed.ply\"");
    mcf_mesh_free(out);
    resp_free(&r);

    /* params JSON, a plain form field and the query: the query wins */
    {
        upload_t up = {.mesh = "sphere_cgal.obj",
                       .params = "{\"scheme\": \"desbrun\", \"iterations\": 7}",
                       .field = "dt", .value = "2e-4"};
        http(&g_main, "POST", "/smooth?iterations=4", NULL, &up, &r);
        expect_status(&g_main, &r, 200, "params field");
        assert_non_null(header(&r, "X-Job-Id", id, sizeof id));
        m = follow_metrics_link(&g_main, &r, id);
        assert_string_equal(jstr(m, "scheme"), "desbrun");
        assert_int_equal((int)jnum(m, "flow.steps"), 4);
        /* 4 steps of dt 2e-4: t_final = 8e-4 up to rounding (1e-15) */
        tl_assert_near(jnum(m, "flow.t_final"), 8e-4, 1e-15, "t_final");
        cJSON_Delete(m);
        resp_free(&r);
    }
    free(obj);
}

/* A target mesh adds the comparison to the metrics; a noisy upload makes
 * the error measurable; a target of another connectivity is a 422. */
static void test_smooth_target(void **state)
{
    resp_t r;
    char id[64], noisy[512];
    cJSON *m, *cmp;

    (void)state;
    snprintf(noisy, sizeof noisy, "%s/noisy-0.2-7.obj", g_tmp);
    {
        upload_t up = {.mesh = tl_write_noisy("sphere_cgal.obj", 0.2, 7, noisy),
                       .target = "sphere_cgal.obj"};
        http(&g_main, "POST", "/smooth?iterations=3&dt=1e-5", NULL, &up, &r);
        expect_status(&g_main, &r, 200, "with target");
        assert_non_null(header(&r, "X-Job-Id", id, sizeof id));
        m = follow_metrics_link(&g_main, &r, id);
        cmp = cJSON_GetObjectItemCaseSensitive(m, "compare");
        assert_non_null(cmp);
        /* noise of 0.2 mean edges, barely smoothed: the error is of that
         * order, positive and finite (a loose, non-degenerate bracket) */
        assert_true(jnum(cmp, "rms_m") > 0);
        assert_true(jnum(cmp, "max_err") > jnum(cmp, "rms_m"));
        assert_true(jnum(cmp, "max_err") <
                    jnum(m, "input.mesh.edge_length.mean") * 2);
        cJSON_Delete(m);
        resp_free(&r);
    }
    {
        upload_t up = {.mesh = "sphere_cgal.obj",
                       .target = "bunny_npm_closed.obj"};
        http(&g_main, "POST", "/smooth", NULL, &up, &r);
        expect_problem(&g_main, &r, 422, "EINVAL", "connectivity",
                       "target of another mesh");
        resp_free(&r);
    }
}

/* A request that names no scheme runs the fairing filter (the default,
 * issue 16): its metrics name it and carry its noise estimate, the SURE
 * curve whose minimum is the step count, the guard's rounds; against the
 * target the error falls. The schemes list has both variants. */
static void test_smooth_default_fairing(void **state)
{
    char noisy[512];
    upload_t up = {.mesh = noisy, .target = "sphere_cgal.obj"};
    resp_t r;
    char id[64];
    cJSON *m, *sure, *e;
    int found = 0, k = 0, kmin = 0;
    double vmin = INFINITY;

    (void)state;
    snprintf(noisy, sizeof noisy, "%s/noisy-0.25-1.obj", g_tmp);
    tl_write_noisy("sphere_cgal.obj", 0.25, 1, noisy);
    http(&g_main, "POST", "/smooth", NULL, &up, &r);
    expect_status(&g_main, &r, 200, "default request");
    assert_non_null(header(&r, "X-Job-Id", id, sizeof id));
    m = follow_metrics_link(&g_main, &r, id);
    assert_string_equal(jstr(m, "scheme"), "fairing");
    /* 0.25 clean mean edges, read in the noisy mesh's (10% longer) */
    assert_true(jnum(m, "flow.noise") > 0.15 && jnum(m, "flow.noise") < 0.3);
    sure = cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(m, "flow"), "sure");
    assert_true(cJSON_IsArray(sure));
    cJSON_ArrayForEach(e, sure) {
        if (e->valuedouble < vmin) {
            vmin = e->valuedouble;
            kmin = k;
        }
        k++;
    }
    assert_int_equal(kmin, (int)jnum(m, "flow.steps"));
    assert_true(kmin >= 1);
    assert_true(jnum(m, "flow.guard_rounds") >= 0 && jnum(m, "flow.guard_rounds") <= 5);
    assert_true(jnum(m, "compare.after.rms_m") < 0.5 * jnum(m, "compare.before.rms_m"));
    cJSON_Delete(m);
    resp_free(&r);

    http(&g_main, "GET", "/v1/schemes", NULL, NULL, &r);
    expect_status(&g_main, &r, 200, "schemes");
    m = body_json(&r, "schemes");
    cJSON_ArrayForEach(e, cJSON_GetObjectItemCaseSensitive(m, "schemes"))
        found += !strcmp(jstr(e, "name"), "fairing") || !strcmp(jstr(e, "name"), "fairing_explicit");
    assert_int_equal(found, 2);
    cJSON_Delete(m);
    resp_free(&r);
}

/* Accept: multipart/mixed: a JSON metrics part, then the mesh part. */
static void test_smooth_multipart_mixed(void **state)
{
    static const char *const h[] = {"Accept: multipart/mixed", NULL};
    upload_t up = {.mesh = "sphere_cgal.obj"};
    resp_t r;
    char ct[256], delim[200];
    const char *b, *p1, *p2, *end, *body1, *body2;
    cJSON *m;
    api_limits lim;
    mcf_mesh *out = NULL;
    mcf_error err = {MCF_OK, ""};

    (void)state;
    http(&g_main, "POST", "/smooth?scheme=desbrun2&iterations=5", h, &up, &r);
    expect_status(&g_main, &r, 200, "multipart/mixed");
    assert_non_null(header(&r, "Content-Type", ct, sizeof ct));
    b = strstr(ct, "boundary=");
    assert_true(strncmp(ct, "multipart/mixed;", 16) == 0 && b);
    snprintf(delim, sizeof delim, "--%s", b + 9);
    /* part 1 */
    p1 = strstr(r.body.data, delim);
    assert_true(p1 == r.body.data);
    body1 = strstr(p1, "\r\n\r\n");
    assert_non_null(body1);
    assert_non_null(strstr(p1, "Content-Type: application/json"));
    body1 += 4;
    p2 = strstr(body1, delim);
    assert_non_null(p2);
    m = cJSON_ParseWithLength(body1, (size_t)(p2 - 2 - body1));
    assert_non_null(m);
    assert_int_equal((int)jnum(m, "flow.steps"), 5);
    assert_int_equal((int)jnum(m, "output.vertices"), 812);
    /* part 2: the mesh, up to the closing delimiter (binary-safe search) */
    assert_non_null(strstr(p2, "Content-Type: model/obj"));
    body2 = strstr(p2, "\r\n\r\n") + 4;
    {
        char close[210];
        size_t cl = (size_t)snprintf(close, sizeof close, "\r\n%s--", delim);
        const char *q;
        end = NULL;
        for (q = body2; q + cl <= r.body.data + r.body.len; q++)
            if (memcmp(q, close, cl) == 0) {
                end = q;
                break;
            }
        assert_non_null(end);
    }
    api_limits_default(&lim);
    assert_int_equal(api_mesh_decode(body2, (size_t)(end - body2), &lim, &out,
                                     NULL, &err), MCF_OK);
    assert_int_equal(mcf_mesh_nvertices(out), 812);
    /* the metrics describe this very mesh (relative 1e-12, see above) */
    tl_assert_near(jnum(m, "output.volume"), mcf_mesh_volume(out),
                   1e-12 * fabs(mcf_mesh_volume(out)), "mixed volume");
    mcf_mesh_free(out);
    cJSON_Delete(m);
    resp_free(&r);
}

/* A milestone line of a job's stream (openapi.yaml WorkEvent): its shape,
 * its share never below the last one's (the core's promise); 1 when line
 * j is one, 0 when it is a step or the final line. */
static int work_event(const cJSON *j, double *last_fraction)
{
    const cJSON *ph = cJSON_GetObjectItemCaseSensitive(j, "phase");
    double f;

    if (!ph)
        return 0;
    assert_true(cJSON_IsString(ph) && ph->valuestring[0]);
    assert_true(cJSON_IsNumber(cJSON_GetObjectItemCaseSensitive(j, "step")));
    f = jnum(j, "fraction");
    assert_true(f >= *last_fraction && f <= 1.0);
    *last_fraction = f;
    return 1;
}

/* ?stream=ndjson: one line per step while it runs, then the summary. */
static void test_smooth_ndjson(void **state)
{
    upload_t up = {.mesh = "sphere_cgal.obj"};
    resp_t r, res;
    char *line, *save = NULL, path[160];
    int steps = 0, done = 0;
    double last_t = 0, last_energy = INFINITY, last_volume = 0, frac = 0;
    enum { N = 500 };
    mcf_mesh *out;
    api_format fmt;

    (void)state;
    /* t = 500 * 2e-5 = 0.01, half the sphere's extinction time 1/(16 pi)
     * at unit area: the flow stays smooth all the way. */
    http(&g_main, "POST",
         "/smooth?scheme=desbrun2&iterations=500&dt=2e-5&stream=ndjson", NULL,
         &up, &r);
    expect_status(&g_main, &r, 200, "ndjson");
    assert_string_equal(header(&r, "Content-Type", path, sizeof path),
                        "application/x-ndjson");
    /* streamed, not buffered: test_smooth_ndjson_live */
    for (line = strtok_r(r.body.data, "\n", &save); line;
         line = strtok_r(NULL, "\n", &save)) {
        cJSON *j = cJSON_Parse(line);
        assert_non_null(j);
        assert_false(done); /* nothing after the final line */
        /* no phases=true: the steps only */
        assert_false(work_event(j, &frac));
        if (cJSON_GetObjectItemCaseSensitive(j, "done")) {
            const cJSON *m = cJSON_GetObjectItemCaseSensitive(j, "metrics");
            done = 1;
            assert_true(cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(j, "done")));
            assert_string_equal(jstr(j, "status"), "succeeded");
            assert_int_equal((int)jnum(m, "flow.steps"), N);
            /* The last step's volume is the flow's final volume: the
             * stream undoes the core's normalization exactly (relative
             * 1e-9 covers the rounding of 1/sqrt(area) and the sums). */
            tl_assert_near(last_volume, jnum(m, "flow.volume1"),
                           1e-9 * fabs(last_volume), "streamed volume");
            snprintf(path, sizeof path, "%s", jstr(j, "result"));
        } else {
            steps++;
            assert_int_equal((int)jnum(j, "step"), steps);
            assert_true(jnum(j, "t") > last_t);
            assert_true(jnum(j, "dt") > 0);
            /* MCF is the gradient flow of area: it never grows here */
            assert_true(jnum(j, "energy") <= last_energy);
            last_t = jnum(j, "t");
            last_energy = jnum(j, "energy");
            last_volume = jnum(j, "volume");
        }
        cJSON_Delete(j);
    }
    assert_int_equal(steps, N);
    assert_true(done);
    http(&g_main, "GET", path, NULL, NULL, &res);
    expect_status(&g_main, &res, 200, "ndjson result URL");
    out = decode_body(&res, &fmt);
    assert_int_equal(mcf_mesh_nvertices(out), 812);
    mcf_mesh_free(out);
    resp_free(&res);
    resp_free(&r);
}

/* The default request (the fairing filter) reports no step until its
 * end, if any: its stream carries the core's milestones, each phase as it
 * starts (the README's client example prints them). The bunny of
 * tests/data: spike repair, the graph, creases, the noise reading, ...,
 * the output at 1. */
static void test_default_stream_milestones(void **state)
{
    upload_t up = {.mesh = "bunny.drc"};
    resp_t r;
    char *line, *save = NULL, phases[256] = "";
    int n = 0, done = 0;
    double frac = 0;

    (void)state;
    /* asked for (a client of before reads every line but the last as a
     * step: without phases=true it gets the steps only) */
    http(&g_main, "POST", "/smooth?stream=ndjson&phases=true", NULL, &up, &r);
    expect_status(&g_main, &r, 200, "default, ndjson");
    for (line = strtok_r(r.body.data, "\n", &save); line;
         line = strtok_r(NULL, "\n", &save)) {
        cJSON *j = cJSON_Parse(line);
        assert_non_null(j);
        assert_false(done);
        if (work_event(j, &frac)) {
            const char *ph = jstr(j, "phase");
            n++;
            if (!strstr(phases, ph) && strlen(phases) + strlen(ph) + 2 < sizeof phases) {
                strcat(phases, ph);
                strcat(phases, " ");
            }
        } else if (cJSON_GetObjectItemCaseSensitive(j, "done")) {
            done = 1;
            assert_string_equal(jstr(j, "status"), "succeeded");
        }
        cJSON_Delete(j);
    }
    assert_true(done);
    print_message("    default request on bunny.drc: %d milestones, phases %s\n", n, phases);
    /* at least the five phases every default run has */
    assert_true(n >= 5);
    assert_non_null(strstr(phases, "spikes"));
    assert_non_null(strstr(phases, "noise"));
    assert_non_null(strstr(phases, "output"));
    tl_assert_near(frac, 1.0, 0.0, "the last milestone's share");
    resp_free(&r);
    http(&g_main, "POST", "/smooth?stream=ndjson", NULL, &up, &r);
    expect_status(&g_main, &r, 200, "default, ndjson without phases");
    assert_null(strstr(r.body.data, "\"phase\""));
    resp_free(&r);
    http(&g_main, "POST", "/smooth?stream=ndjson&phases=yes", NULL, &up, &r);
    expect_problem(&g_main, &r, 400, "EINVAL", "'phases'", "phases=yes");
    resp_free(&r);
}

/* ?stream=ndjson is streamed, not buffered: the first step line reaches
 * the client while the job is still running (the job's own state says so,
 * whatever the timing), and a DELETE then ends the stream with the
 * cancellation. 100,000 steps of dt 1e-7 would take over a minute: a
 * buffered stream fails on the job's state or the curl timeout. */
static void test_smooth_ndjson_live(void **state)
{
    live_client_t lc = {.d = &g_main, .method = "POST", .mesh = 1,
                        .path = "/smooth?iterations=100000&dt=1e-7&max_steps=100000&stream=ndjson",
                        .watch = "{\"step\":"};
    pthread_t th;
    char id[64], path[160];
    const char *last;
    resp_t r;
    cJSON *j;

    (void)state;
    assert_int_equal(pthread_create(&th, NULL, live_client, &lc), 0);
    watch_seen(&g_main, &lc.r, 30, "first ndjson step line");
    assert_non_null(header(&lc.r, "X-Job-Id", id, sizeof id));
    snprintf(path, sizeof path, "/v1/jobs/%s", id);
    j = poll_job(&g_main, id, "running", 10);
    assert_true(jnum(j, "progress.step") < 100000);
    cJSON_Delete(j);
    http(&g_main, "DELETE", path, NULL, NULL, &r);
    expect_status(&g_main, &r, 202, "DELETE the streaming job");
    resp_free(&r);
    pthread_join(th, NULL);
    expect_status(&g_main, &lc.r, 200, "ndjson stream");
    assert_true(lc.r.body.len > 0 && lc.r.body.data[lc.r.body.len - 1] == '\n');
    lc.r.body.data[lc.r.body.len - 1] = '\0';
    last = strrchr(lc.r.body.data, '\n');
    last = last ? last + 1 : lc.r.body.data;
    j = cJSON_Parse(last);
    if (!j || strcmp(jstr(j, "status"), "canceled") != 0)
        fail_msg("last ndjson line: %s", last);
    cJSON_Delete(j);
    resp_free(&lc.r);
}

/* POST /v1/jobs, poll, result, metrics, SSE replay, DELETE when done. */
static void test_async_job(void **state)
{
    char id[SRV_ID_BUF], path[160];
    resp_t r;
    cJSON *j;
    mcf_mesh *out;
    api_format fmt;
    int progress = 0;

    (void)state;
    submit(&g_main, "?scheme=desbrun2&iterations=25", id);
    j = poll_job(&g_main, id, "succeeded", 30);
    assert_true(jnum(j, "progress.fraction") == 1);
    assert_int_equal((int)jnum(j, "progress.step"), 25);
    assert_int_equal((int)jnum(j, "metrics.flow.steps"), 25);
    assert_non_null(cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(j, "finished")));
    cJSON_Delete(j);

    snprintf(path, sizeof path, "/v1/jobs/%s/result", id);
    http(&g_main, "GET", path, NULL, NULL, &r);
    expect_status(&g_main, &r, 200, "result");
    out = decode_body(&r, &fmt);
    assert_int_equal(mcf_mesh_nvertices(out), 812);
    mcf_mesh_free(out);
    resp_free(&r);

    snprintf(path, sizeof path, "/v1/jobs/%s/metrics", id);
    http(&g_main, "GET", path, NULL, NULL, &r);
    expect_status(&g_main, &r, 200, "metrics");
    j = body_json(&r, "metrics");
    assert_int_equal((int)jnum(j, "flow.steps"), 25);
    cJSON_Delete(j);
    resp_free(&r);

    /* SSE of a finished job: status, every step again, then done. */
    snprintf(path, sizeof path, "/v1/jobs/%s/events", id);
    http(&g_main, "GET", path, NULL, NULL, &r);
    expect_status(&g_main, &r, 200, "events");
    assert_string_equal(header(&r, "Content-Type", path, sizeof path),
                        "text/event-stream");
    assert_true(strncmp(strstr(r.body.data, "event: "), "event: status", 13) == 0);
    {
        const char *p = r.body.data;
        while ((p = strstr(p, "event: progress")) != NULL) {
            progress++;
            p++;
        }
    }
    assert_int_equal(progress, 25);
    assert_non_null(strstr(r.body.data, "id: 25\nevent: progress"));
    assert_non_null(strstr(r.body.data, "event: done\ndata: {"));
    assert_non_null(strstr(strstr(r.body.data, "event: done"), "\"succeeded\""));
    resp_free(&r);

    /* Last-Event-ID resumes after that step */
    {
        static const char *const h[] = {"Last-Event-ID: 20", NULL};
        snprintf(path, sizeof path, "/v1/jobs/%s/events", id);
        http(&g_main, "GET", path, h, NULL, &r);
        expect_status(&g_main, &r, 200, "events after 20");
        assert_null(strstr(r.body.data, "id: 20\n"));
        assert_non_null(strstr(r.body.data, "id: 21\n"));
        resp_free(&r);
    }

    snprintf(path, sizeof path, "/v1/jobs/%s", id);
    http(&g_main, "DELETE", path, NULL, NULL, &r);
    expect_status(&g_main, &r, 204, "DELETE finished job");
    resp_free(&r);
    http(&g_main, "GET", path, NULL, NULL, &r);
    expect_problem(&g_main, &r, 404, "ENOTFOUND", id, "GET deleted job");
    resp_free(&r);
}

/* SSE of a running job arrives live; DELETE stops it at the next step; a
 * queued job is canceled at once; 409 before a result exists. */
static void test_cancel(void **state)
{
    char a[SRV_ID_BUF], b[SRV_ID_BUF], c[SRV_ID_BUF], path[160];
    resp_t r;
    cJSON *j;
    int steps_a;

    (void)state;
    /* two long jobs for the two workers, a third waits in the queue */
    /* dt 1e-7: 100000 steps stay far from the sphere's extinction */
    submit(&g_main, "?iterations=100000&dt=1e-7&max_steps=100000", a);
    submit(&g_main, "?iterations=100000&dt=1e-7&max_steps=100000", b);
    submit(&g_main, "?iterations=100000&dt=1e-7&max_steps=100000", c);
    wait_running(&g_main, a);
    wait_running(&g_main, b);
    j = poll_job(&g_main, c, "queued", 5);
    cJSON_Delete(j);

    snprintf(path, sizeof path, "/v1/jobs/%s/result", a);
    http(&g_main, "GET", path, NULL, NULL, &r);
    expect_problem(&g_main, &r, 409, "ENOTREADY", "running", "result too early");
    resp_free(&r);
    snprintf(path, sizeof path, "/v1/jobs/%s/metrics", c);
    http(&g_main, "GET", path, NULL, NULL, &r);
    expect_problem(&g_main, &r, 409, "ENOTREADY", "queued", "metrics too early");
    resp_free(&r);

    /* queued: canceled immediately, 200 with the job */
    snprintf(path, sizeof path, "/v1/jobs/%s", c);
    http(&g_main, "DELETE", path, NULL, NULL, &r);
    expect_status(&g_main, &r, 200, "DELETE queued");
    j = body_json(&r, "DELETE queued");
    assert_string_equal(jstr(j, "status"), "canceled");
    cJSON_Delete(j);
    resp_free(&r);

    /* running: 202, then canceled at the next step; a live SSE follower
     * sees steps arrive and the stream end with the cancellation */
    {
        char events[160];
        live_client_t sc = {.d = &g_main, .method = "GET", .path = events,
                            .watch = "event: progress"};
        pthread_t th;
        snprintf(events, sizeof events, "/v1/jobs/%s/events", a);
        assert_int_equal(pthread_create(&th, NULL, live_client, &sc), 0);
        /* live: a progress event arrives while the job runs (it ends only
         * by the DELETE below) */
        watch_seen(&g_main, &sc.r, 20, "live events of a running job");
        snprintf(path, sizeof path, "/v1/jobs/%s", a);
        http(&g_main, "DELETE", path, NULL, NULL, &r);
        expect_status(&g_main, &r, 202, "DELETE running");
        resp_free(&r);
        pthread_join(th, NULL);
        expect_status(&g_main, &sc.r, 200, "live events");
        assert_non_null(strstr(sc.r.body.data, "event: progress"));
        assert_non_null(strstr(sc.r.body.data, "event: done"));
        assert_non_null(strstr(strstr(sc.r.body.data, "event: done"),
                               "\"canceled\""));
        resp_free(&sc.r);
    }
    snprintf(path, sizeof path, "/v1/jobs/%s", b);
    http(&g_main, "DELETE", path, NULL, NULL, &r);
    expect_status(&g_main, &r, 202, "DELETE running b");
    resp_free(&r);
    j = poll_job(&g_main, a, "canceled", 10);
    steps_a = (int)jnum(j, "progress.step");
    assert_true(steps_a >= 1 && steps_a < 100000);
    assert_string_equal(jstr(cJSON_GetObjectItemCaseSensitive(j, "error"), "code"),
                        "ECANCELED");
    cJSON_Delete(j);
    j = poll_job(&g_main, b, "canceled", 10);
    cJSON_Delete(j);

    snprintf(path, sizeof path, "/v1/jobs/%s/result", a);
    http(&g_main, "GET", path, NULL, NULL, &r);
    expect_problem(&g_main, &r, 409, "ENORESULT", "canceled", "result of canceled");
    resp_free(&r);
    /* the canceled job stays visible until deleted */
    snprintf(path, sizeof path, "/v1/jobs/%s", c);
    http(&g_main, "DELETE", path, NULL, NULL, &r);
    expect_status(&g_main, &r, 204, "DELETE canceled");
    resp_free(&r);
}

/* Every error status with its problem+json body. */
static void test_errors(void **state)
{
    resp_t r;
    upload_t up = {.mesh = "sphere_cgal.obj"};

    (void)state;
    /* 400: a bad value and an unknown key, each named */
    http(&g_main, "POST", "/smooth?dt=abc", NULL, &up, &r);
    expect_problem(&g_main, &r, 400, "EINVAL", "'dt'", "dt=abc");
    resp_free(&r);
    http(&g_main, "POST", "/smooth?bogus=1", NULL, &up, &r);
    expect_problem(&g_main, &r, 400, "EINVAL", "'bogus'", "bogus=1");
    resp_free(&r);
    {
        upload_t p = {.mesh = "sphere_cgal.obj", .params = "{\"scheme\": 3"};
        http(&g_main, "POST", "/smooth", NULL, &p, &r);
        expect_problem(&g_main, &r, 400, "EINVAL", "JSON", "broken params");
        resp_free(&r);
    }
    {
        upload_t p = {.params = "{}"};
        http(&g_main, "POST", "/smooth", NULL, &p, &r);
        expect_problem(&g_main, &r, 400, "EINVAL", "'mesh'", "no mesh field");
        resp_free(&r);
    }
    http(&g_main, "POST", "/smooth?fixed_vertices=5000", NULL, &up, &r);
    expect_problem(&g_main, &r, 400, "EINVAL", "fixed_vertices", "fixed out of range");
    resp_free(&r);
    {
        static const char bad[] = "v 0 0 0\nv 1 x 0\nv 0 1 0\nf 1 2 3\n";
        upload_t raw = {.raw = bad, .raw_len = sizeof bad - 1};
        http(&g_main, "POST", "/smooth", NULL, &raw, &r);
        expect_problem(&g_main, &r, 400, "EDECODE", "line 2", "bad OBJ number");
        resp_free(&r);
    }
    /* 404 */
    http(&g_main, "GET", "/v1/jobs/0123456789abcdef0123456789abcdef", NULL, NULL, &r);
    expect_problem(&g_main, &r, 404, "ENOTFOUND", "0123456789abcdef", "unknown job");
    resp_free(&r);
    http(&g_main, "DELETE", "/v1/jobs/0123456789abcdef0123456789abcdef", NULL,
         NULL, &r);
    expect_problem(&g_main, &r, 404, "ENOTFOUND", NULL, "DELETE unknown job");
    resp_free(&r);
    /* 415: a declared non-mesh type, and bytes of no known format */
    {
        static const char *const h[] = {"Content-Type: application/json", NULL};
        upload_t raw = {.raw = "{}", .raw_len = 2};
        http(&g_main, "POST", "/smooth", h, &raw, &r);
        expect_problem(&g_main, &r, 415, "EFORMAT", "application/json", "json body");
        resp_free(&r);
    }
    {
        static const char junk[] = "\x01\x02\x03 not a mesh \xff\xfe";
        static const char *const h[] = {"Content-Type: application/octet-stream",
                                        NULL};
        upload_t raw = {.raw = junk, .raw_len = sizeof junk - 1};
        http(&g_main, "POST", "/smooth", h, &raw, &r);
        expect_problem(&g_main, &r, 415, "EFORMAT", "format", "junk bytes");
        resp_free(&r);
    }
    /* 422: decodes, cannot be smoothed (zero area) */
    {
        static const char flat[] = "v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1 2 3\n";
        upload_t raw = {.raw = flat, .raw_len = sizeof flat - 1};
        http(&g_main, "POST", "/smooth", NULL, &raw, &r);
        expect_problem(&g_main, &r, 422, "EMESH", "area", "zero-area mesh");
        resp_free(&r);
    }
    /* 422 also through the async route: the job fails with the reason */
    {
        static const char flat[] = "v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1 2 3\n";
        upload_t raw = {.raw = flat, .raw_len = sizeof flat - 1};
        cJSON *j, *e;
        char id[SRV_ID_BUF];
        http(&g_main, "POST", "/v1/jobs", NULL, &raw, &r);
        expect_status(&g_main, &r, 202, "async zero-area");
        j = body_json(&r, "async");
        snprintf(id, sizeof id, "%s", jstr(j, "id"));
        cJSON_Delete(j);
        resp_free(&r);
        j = poll_job(&g_main, id, "failed", 10);
        e = cJSON_GetObjectItemCaseSensitive(j, "error");
        assert_int_equal((int)jnum(e, "status"), 422);
        assert_string_equal(jstr(e, "code"), "EMESH");
        cJSON_Delete(j);
    }
    /* 413 (a): announced by Content-Length, answered before the body. */
    {
        struct sockaddr_in sa;
        struct timeval tv = {10, 0};
        char req[512], buf[2048];
        size_t got = 0;
        int fd = socket(AF_INET, SOCK_STREAM, 0);
        assert_true(fd >= 0);
        memset(&sa, 0, sizeof sa);
        sa.sin_family = AF_INET;
        sa.sin_port = htons((uint16_t)g_main.port);
        sa.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
        assert_int_equal(connect(fd, (struct sockaddr *)&sa, sizeof sa), 0);
        snprintf(req, sizeof req, "POST /smooth HTTP/1.1\r\nHost: 127.0.0.1\r\n"
                 "Content-Type: application/octet-stream\r\n"
                 "Content-Length: 10000000000\r\nExpect: 100-continue\r\n\r\n");
        assert_true(write(fd, req, strlen(req)) == (ssize_t)strlen(req));
        while (got < sizeof buf - 1) {
            ssize_t n = read(fd, buf + got, sizeof buf - 1 - got);
            if (n <= 0)
                break;
            got += (size_t)n;
            buf[got] = '\0';
            if (strstr(buf, "\r\n\r\n") && strstr(buf, "}"))
                break;
        }
        close(fd);
        buf[got] = '\0';
        if (strncmp(buf, "HTTP/1.1 413", 12) != 0)
            fail_msg("expected 413 before the body, got: %.200s", buf);
        assert_non_null(strstr(buf, "application/problem+json"));
        assert_non_null(strstr(buf, "\"ELIMIT\""));
        assert_non_null(strstr(buf, "Content-Length 10000000000"));
    }
    /* 413 (b): a multipart mesh part over --max-upload (3M), after the
     * body: 3,584,000 bytes of OBJ comment lines */
    {
        char file[600];
        upload_t big = {.mesh = file};
        FILE *f;
        int i;
        snprintf(file, sizeof file, "%s/big.obj", g_tmp);
        f = fopen(file, "w");
        assert_non_null(f);
        for (i = 0; i < 3500; i++)
            fprintf(f, "# %1020d\n", i);
        assert_int_equal(fclose(f), 0);
        http(&g_main, "POST", "/smooth", NULL, &big, &r);
        unlink(file);
        expect_problem(&g_main, &r, 413, "ELIMIT", "'mesh'", "mesh part too big");
        resp_free(&r);
    }
    /* 413 (c): a chunked raw body (no Content-Length) over the limit */
    {
        static const char *const h[] = {"Transfer-Encoding: chunked",
                                        "Content-Type: model/obj", NULL};
        size_t n = (size_t)3500000;
        char *blob = malloc(n);
        upload_t raw;
        assert_non_null(blob);
        memset(blob, '#', n);
        raw = (upload_t){.raw = blob, .raw_len = n};
        http(&g_main, "POST", "/smooth", h, &raw, &r);
        expect_problem(&g_main, &r, 413, "ELIMIT", "exceeds", "chunked too big");
        resp_free(&r);
        free(blob);
    }
}

/* The page (issue 21): GET / and its files under /ui/, embedded at build
 * time, public, with their media type, ETag (304 on If-None-Match), the
 * page's Content-Security-Policy; unknown files and other methods refused. */
static void test_page(void **state)
{
    resp_t r;
    char buf[512], etag[64];
    cJSON *j;
    static const char *const unknown[] = {
        "/ui/", "/ui/nope.js", "/ui/../openapi.yaml", "/ui/app.js/", "/ui//app.js",
        "/ui/APP.JS", "/index.htm", "//"};
    size_t i;

    (void)state;
    http(&g_main, "GET", "/", NULL, NULL, &r);
    expect_status(&g_main, &r, 200, "GET /");
    assert_string_equal(header(&r, "Content-Type", buf, sizeof buf),
                        "text/html; charset=utf-8");
    assert_non_null(strstr(r.body.data, "<script type=\"module\" src=\"/ui/app.js\">"));
    assert_non_null(header(&r, "Content-Security-Policy", buf, sizeof buf));
    assert_non_null(strstr(buf, "default-src 'none'"));
    assert_non_null(strstr(buf, "script-src 'self';"));
    assert_null(strstr(buf, "unsafe"));
    assert_string_equal(header(&r, "X-Content-Type-Options", buf, sizeof buf), "nosniff");
    assert_string_equal(header(&r, "Cache-Control", buf, sizeof buf), "no-cache");
    assert_non_null(header(&r, "ETag", etag, sizeof etag));
    assert_int_equal(strlen(etag), 18); /* "16 hex digits" */
    resp_free(&r);
    {
        char inm[160];
        const char *h[] = {inm, NULL};
        snprintf(inm, sizeof inm, "If-None-Match: \"0000000000000000\", %s", etag);
        http(&g_main, "GET", "/", h, NULL, &r);
        expect_status(&g_main, &r, 304, "GET / revalidated");
        assert_int_equal(r.body.len, 0);
        assert_string_equal(header(&r, "ETag", buf, sizeof buf), etag);
        resp_free(&r);
        snprintf(inm, sizeof inm, "If-None-Match: \"0000000000000000\"");
        http(&g_main, "GET", "/", h, NULL, &r);
        expect_status(&g_main, &r, 200, "GET / with another ETag");
        resp_free(&r);
    }
    /* three.js and the page's modules, as the Makefile embedded them */
    http(&g_main, "GET", "/ui/three.module.js", NULL, NULL, &r);
    expect_status(&g_main, &r, 200, "three.module.js");
    assert_string_equal(header(&r, "Content-Type", buf, sizeof buf),
                        "text/javascript; charset=utf-8");
    assert_true(r.body.len > 100000);
    resp_free(&r);
    http(&g_main, "GET", "/ui/OrbitControls.js", NULL, NULL, &r);
    expect_status(&g_main, &r, 200, "OrbitControls.js");
    assert_null(strstr(r.body.data, "from 'three'")); /* no bare import left */
    assert_non_null(strstr(r.body.data, "from './three.module.js'"));
    resp_free(&r);
    http(&g_main, "GET", "/ui/style.css", NULL, NULL, &r);
    expect_status(&g_main, &r, 200, "style.css");
    assert_string_equal(header(&r, "Content-Type", buf, sizeof buf), "text/css; charset=utf-8");
    resp_free(&r);
    http(&g_main, "HEAD", "/ui/app.js", NULL, NULL, &r);
    expect_status(&g_main, &r, 200, "HEAD app.js");
    resp_free(&r);
    http(&g_main, "GET", "/ui/config.json", NULL, NULL, &r);
    expect_status(&g_main, &r, 200, "config.json");
    j = body_json(&r, "config.json");
    assert_true(cJSON_IsFalse(cJSON_GetObjectItemCaseSensitive(j, "token_required")));
    cJSON_Delete(j);
    resp_free(&r);

    for (i = 0; i < sizeof unknown / sizeof unknown[0]; i++) {
        http(&g_main, "GET", unknown[i], NULL, NULL, &r);
        expect_problem(&g_main, &r, 404, "ENOTFOUND", NULL, unknown[i]);
        resp_free(&r);
    }
    http(&g_main, "POST", "/", NULL, NULL, &r);
    expect_problem(&g_main, &r, 405, "EMETHOD", "POST", "POST /");
    resp_free(&r);
    http(&g_main, "DELETE", "/ui/app.js", NULL, NULL, &r);
    expect_problem(&g_main, &r, 405, "EMETHOD", "DELETE", "DELETE /ui/app.js");
    resp_free(&r);
}

/* Reads the fields document's header: the JSON (caller deletes) and where
 * the data begins. */
static cJSON *fields_header(const resp_t *r, size_t *data)
{
    const unsigned char *b = (const unsigned char *)r->body.data;
    uint32_t v, h;
    char *text;
    cJSON *j;

    assert_true(r->body.len >= 12);
    assert_memory_equal(b, "MCFF", 4);
    v = b[4] | b[5] << 8 | b[6] << 16 | (uint32_t)b[7] << 24;
    h = b[8] | b[9] << 8 | b[10] << 16 | (uint32_t)b[11] << 24;
    assert_int_equal(v, 1);
    assert_int_equal(h % 4, 0);
    assert_true(12 + (size_t)h <= r->body.len);
    text = strndup(r->body.data + 12, h);
    j = cJSON_Parse(text);
    free(text);
    assert_non_null(j);
    *data = 12 + h;
    return j;
}

/* The float32 array `name` of a fields document, converted to doubles
 * (malloc'ed; *n values). */
static double *fields_array(const resp_t *r, const cJSON *hdr, size_t data,
                            const char *name, int *n)
{
    const cJSON *a;
    cJSON_ArrayForEach(a, cJSON_GetObjectItemCaseSensitive(hdr, "arrays"))
        if (strcmp(jstr(a, "name"), name) == 0) {
            int k, count = (int)(jnum(a, "count") * jnum(a, "components"));
            size_t off = data + (size_t)jnum(a, "offset");
            double *v = malloc((size_t)count * sizeof *v);
            assert_string_equal(jstr(a, "type"), "float32");
            assert_true(off + 4 * (size_t)count <= r->body.len);
            for (k = 0; k < count; k++) {
                float f;
                memcpy(&f, r->body.data + off + 4 * (size_t)k, 4); /* x86: LE */
                v[k] = f;
            }
            *n = count;
            return v;
        }
    fail_msg("no array %s in the fields document", name);
    return NULL;
}

/* GET /v1/jobs/ID/fields (issue 21): the per-vertex fields of a job
 * submitted with fields=true, checked against the core on the same meshes
 * (the input as uploaded, the result as downloaded); and its refusals:
 * unknown, unfinished and field-less jobs, hostile IDs. */
static void test_fields(void **state)
{
    char id[SRV_ID_BUF], plain[SRV_ID_BUF], run[SRV_ID_BUF], path[200];
    resp_t r, res;
    cJSON *hdr;
    size_t data;
    int n, i, nv;
    double *X0, *H0, *X1, *H1, *K1, *D, *H, *K;
    api_format fmt;
    mcf_mesh *in = tl_load("sphere_cgal.obj"), *out;
    mcf_error err;
    static const char *const hostile[] = {
        "/v1/jobs/../../etc/passwd/fields",
        "/v1/jobs/0123456789ABCDEF0123456789abcdef/fields",
        "/v1/jobs/0123456789abcdef0123456789abcde/fields",
        "/v1/jobs/0123456789abcdef0123456789abcdef0/fields",
        "/v1/jobs/0123456789abcdef0123456789abcde%2e/fields",
        "/v1/jobs/0123456789abcdef0123456789abcdef/fields/x",
        "/v1/jobs/0123456789abcdef0123456789abcdef/field"};

    (void)state;
    submit(&g_main, "?fields=true&iterations=5", id);
    submit(&g_main, "?iterations=5", plain);
    cJSON_Delete(poll_job(&g_main, id, "succeeded", 30));
    cJSON_Delete(poll_job(&g_main, plain, "succeeded", 30));

    snprintf(path, sizeof path, "/v1/jobs/%s/fields", id);
    http(&g_main, "GET", path, NULL, NULL, &r);
    expect_status(&g_main, &r, 200, "GET fields");
    {
        char ct[64], jid[64];
        assert_string_equal(header(&r, "Content-Type", ct, sizeof ct),
                            "application/vnd.mcfd.fields");
        assert_string_equal(header(&r, "X-Job-Id", jid, sizeof jid), id);
    }
    hdr = fields_header(&r, &data);
    nv = mcf_mesh_nvertices(in);
    assert_int_equal((int)jnum(hdr, "vertices"), nv);
    assert_int_equal((int)jnum(hdr, "faces"), mcf_mesh_nfaces(in));
    /* 12 + header + faces (3 x 4 bytes) + 2 positions (3 x 4) + 5 fields */
    assert_int_equal(r.body.len, data + 12 * (size_t)mcf_mesh_nfaces(in) +
                                     (24 + 20) * (size_t)nv);
    {   /* the faces are the input's, in order */
        const cJSON *a = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(hdr, "arrays"), 0);
        const int32_t *F = mcf_mesh_faces(in);
        assert_string_equal(jstr(a, "name"), "faces");
        assert_string_equal(jstr(a, "type"), "uint32");
        for (i = 0; i < 3 * mcf_mesh_nfaces(in); i++) {
            const unsigned char *b = (const unsigned char *)r.body.data + data + 4 * (size_t)i;
            assert_int_equal((int32_t)(b[0] | b[1] << 8 | b[2] << 16 | (uint32_t)b[3] << 24), F[i]);
        }
    }
    /* the result as GET /result serves it: the fields describe that mesh */
    snprintf(path, sizeof path, "/v1/jobs/%s/result", id);
    http(&g_main, "GET", path, NULL, NULL, &res);
    expect_status(&g_main, &res, 200, "GET result");
    out = decode_body(&res, &fmt);
    resp_free(&res);
    X0 = fields_array(&r, hdr, data, "input.positions", &n);
    assert_int_equal(n, 3 * nv);
    X1 = fields_array(&r, hdr, data, "result.positions", &n);
    H0 = fields_array(&r, hdr, data, "input.mean_curvature", &n);
    H1 = fields_array(&r, hdr, data, "result.mean_curvature", &n);
    K1 = fields_array(&r, hdr, data, "result.gaussian_curvature", &n);
    D = fields_array(&r, hdr, data, "displacement", &n);
    assert_int_equal(n, nv);
    H = malloc((size_t)nv * sizeof *H);
    K = malloc((size_t)nv * sizeof *K);
    assert_int_equal(mcf_curvature(in, NULL, H, NULL, NULL, &err), MCF_OK);
    /* float32 of the core's doubles: a relative 2^-24, 1e-6 with margin */
    for (i = 0; i < 3 * nv; i++) {
        tl_assert_near(X0[i], mcf_mesh_positions(in)[i], 1e-6, "input position");
        tl_assert_near(X1[i], mcf_mesh_positions(out)[i], 1e-6, "result position");
    }
    for (i = 0; i < nv; i++)
        tl_assert_near(H0[i], H[i], 1e-6 * (1 + fabs(H[i])), "input H");
    assert_int_equal(mcf_curvature(out, NULL, H, K, NULL, &err), MCF_OK);
    for (i = 0; i < nv; i++) {
        const double *a = mcf_mesh_positions(in) + 3 * i, *b = mcf_mesh_positions(out) + 3 * i;
        double d = sqrt((b[0] - a[0]) * (b[0] - a[0]) + (b[1] - a[1]) * (b[1] - a[1]) +
                        (b[2] - a[2]) * (b[2] - a[2]));
        /* the result's OBJ keeps every double (%.17g): the same curvature */
        tl_assert_near(H1[i], H[i], 1e-6 * (1 + fabs(H[i])), "result H");
        tl_assert_near(K1[i], K[i], 1e-6 * (1 + fabs(K[i])), "result K");
        tl_assert_near(D[i], d, 1e-6 * (1 + d), "displacement");
    }
    /* a sphere of radius ~1 smoothed 5 steps: H about 1 (outward normals) */
    {
        const cJSON *a;
        cJSON_ArrayForEach(a, cJSON_GetObjectItemCaseSensitive(hdr, "arrays"))
            if (strcmp(jstr(a, "name"), "result.mean_curvature") == 0) {
                assert_true(jnum(a, "stats.p02") > 0.8 && jnum(a, "stats.p98") < 1.3);
                assert_true(jnum(a, "stats.min") <= jnum(a, "stats.p02"));
            }
    }
    free(X0); free(X1); free(H0); free(H1); free(K1); free(D); free(H); free(K);
    mcf_mesh_free(out);
    cJSON_Delete(hdr);
    resp_free(&r);
    mcf_mesh_free(in);

    /* refusals */
    snprintf(path, sizeof path, "/v1/jobs/%s/fields", plain);
    http(&g_main, "GET", path, NULL, NULL, &r);
    expect_problem(&g_main, &r, 409, "ENORESULT", "without fields=true", "no fields asked");
    resp_free(&r);
    http(&g_main, "GET", "/v1/jobs/0123456789abcdef0123456789abcdef/fields", NULL, NULL, &r);
    expect_problem(&g_main, &r, 404, "ENOTFOUND", "0123456789abcdef0123456789abcdef",
                   "unknown job");
    resp_free(&r);
    for (i = 0; i < (int)(sizeof hostile / sizeof hostile[0]); i++) {
        http(&g_main, "GET", hostile[i], NULL, NULL, &r);
        expect_problem(&g_main, &r, 404, "ENOTFOUND", NULL, hostile[i]);
        resp_free(&r);
    }
    snprintf(path, sizeof path, "/v1/jobs/%s/fields", id);
    http(&g_main, "POST", path, NULL, NULL, &r);
    expect_problem(&g_main, &r, 405, "EMETHOD", "POST", "POST fields");
    resp_free(&r);
    {   /* a query key of the daemon, like stream; its value is checked */
        upload_t up = {.mesh = "sphere_cgal.obj"};
        http(&g_main, "POST", "/v1/jobs?fields=maybe", NULL, &up, &r);
        expect_problem(&g_main, &r, 400, "EINVAL", "'fields' must be true or false",
                       "fields=maybe");
        resp_free(&r);
    }
    /* running: not yet; canceled: never */
    submit(&g_main, "?fields=true&iterations=100000&dt=1e-7&max_steps=100000", run);
    wait_running(&g_main, run);
    snprintf(path, sizeof path, "/v1/jobs/%s/fields", run);
    http(&g_main, "GET", path, NULL, NULL, &r);
    expect_problem(&g_main, &r, 409, "ENOTREADY", "running", "fields too early");
    resp_free(&r);
    snprintf(path, sizeof path, "/v1/jobs/%s", run);
    http(&g_main, "DELETE", path, NULL, NULL, &r);
    resp_free(&r);
    cJSON_Delete(poll_job(&g_main, run, "canceled", 30));
    snprintf(path, sizeof path, "/v1/jobs/%s/fields", run);
    http(&g_main, "GET", path, NULL, NULL, &r);
    expect_problem(&g_main, &r, 409, "ENORESULT", "canceled", "fields of a canceled job");
    resp_free(&r);
}

/* ------------------------------------------ metrics: one document, CLI */

/* What only a door knows, or a clock measures: left out of the
 * comparison of the two doors' documents (paths, the job id, the process's
 * resident size, and every duration: a key ending in "_s"). */
static int door_fact(const char *path)
{
    static const char *const facts[] = {
        "metrics.job", "metrics.input.path", "metrics.output.path",
        "metrics.compare.target", "metrics.peak_rss_bytes", NULL};
    size_t n = strlen(path);
    int i;
    for (i = 0; facts[i]; i++)
        if (strcmp(path, facts[i]) == 0)
            return 1;
    return n > 2 && strcmp(path + n - 2, "_s") == 0;
}

/* Fails unless a and b have the same members, recursively, and the same
 * values: strings and booleans equal, numbers within a relative 1e-12
 * (both doors run the same deterministic job on one BLAS thread, and
 * cJSON prints every double so that it reads back the same: measured
 * equal to the last bit; the margin covers nothing but printing),
 * arrays of the same length element by element; door facts (door_fact)
 * are skipped. */
static void same_document(const cJSON *a, const cJSON *b, const char *path)
{
    char sub[256];
    const cJSON *x;
    int i, n;

    if (door_fact(path))
        return;
    if (cJSON_IsObject(a) || cJSON_IsObject(b)) {
        if (!cJSON_IsObject(a) || !cJSON_IsObject(b))
            fail_msg("%s: an object in one document only", path);
        cJSON_ArrayForEach(x, a) {
            snprintf(sub, sizeof sub, "%s.%s", path, x->string);
            if (!cJSON_GetObjectItemCaseSensitive(b, x->string))
                fail_msg("%s: in the CLI's metrics only", sub);
            same_document(x, cJSON_GetObjectItemCaseSensitive(b, x->string), sub);
        }
        cJSON_ArrayForEach(x, b)
            if (!cJSON_GetObjectItemCaseSensitive(a, x->string))
                fail_msg("%s.%s: in the daemon's metrics only", path, x->string);
        return;
    }
    if (cJSON_IsArray(a) || cJSON_IsArray(b)) {
        n = cJSON_GetArraySize(a);
        if (!cJSON_IsArray(a) || !cJSON_IsArray(b) || n != cJSON_GetArraySize(b))
            fail_msg("%s: arrays of different lengths", path);
        for (i = 0; i < n; i++) {
            snprintf(sub, sizeof sub, "%s[%d]", path, i);
            same_document(cJSON_GetArrayItem(a, i), cJSON_GetArrayItem(b, i), sub);
        }
        return;
    }
    if (cJSON_IsNumber(a) && cJSON_IsNumber(b)) {
        tl_assert_near(b->valuedouble, a->valuedouble, 1e-12 * fabs(a->valuedouble), path);
        return;
    }
    if (cJSON_IsString(a) && cJSON_IsString(b)) {
        if (strcmp(a->valuestring, b->valuestring) != 0)
            fail_msg("%s: \"%s\" (CLI) but \"%s\" (daemon)", path, a->valuestring,
                     b->valuestring);
        return;
    }
    if (!((cJSON_IsBool(a) && cJSON_IsBool(b) && cJSON_IsTrue(a) == cJSON_IsTrue(b)) ||
          (cJSON_IsNull(a) && cJSON_IsNull(b))))
        fail_msg("%s: different values", path);
}

/* path made absolute (from the working directory when relative). */
static void abs_path(char *out, size_t size, const char *path)
{
    char cwd[512];
    if (path[0] == '/')
        snprintf(out, size, "%s", path);
    else
        snprintf(out, size, "%s/%s", getcwd(cwd, sizeof cwd) ? cwd : ".", path);
}

/* One request through both doors: `mcf smooth IN OUT ARGS --metrics` and
 * POST /smooth?QUERY; returns the two documents. */
static void both_doors(const char *mesh, const char *target, const char *out,
                       const char *const *args, const char *query, cJSON **cli,
                       cJSON **srv)
{
    const char *argv[24];
    upload_t up = {.mesh = mesh, .target = target};
    char in[1024], tg[1024], path[256], id[64], *buf;
    size_t len;
    tl_run_result cr;
    resp_t r;
    int n = 0, i;

    /* absolute: mcf runs in its scratch directory */
    abs_path(in, sizeof in, tl_need_mesh(mesh));
    argv[n++] = "smooth";
    argv[n++] = in;
    argv[n++] = out;
    for (i = 0; args[i]; i++)
        argv[n++] = args[i];
    if (target) {
        abs_path(tg, sizeof tg, tl_need_mesh(target));
        argv[n++] = "--target";
        argv[n++] = tg;
    }
    argv[n++] = "--metrics";
    argv[n++] = "m.json";
    argv[n++] = "--quiet";
    /* one BLAS thread, as the daemon runs (make test sets it too): more
     * threads sum in another order, and roundoff differs */
    setenv("OPENBLAS_NUM_THREADS", "1", 1);
    while (n < 24)
        argv[n++] = NULL;
    cr = tl_run(argv[0], argv[1], argv[2], argv[3], argv[4], argv[5], argv[6], argv[7],
                argv[8], argv[9], argv[10], argv[11], argv[12], argv[13], argv[14],
                argv[15], argv[16], argv[17], NULL);
    if (cr.status != 0)
        fail_msg("mcf smooth %s: status %d: %s", mesh, cr.status, cr.err);
    tl_run_free(&cr);
    assert_int_equal(tl_read_file(tl_in_scratch("m.json"), &buf, &len), 0);
    *cli = cJSON_Parse(buf);
    free(buf);
    assert_non_null(*cli);

    snprintf(path, sizeof path, "/smooth%s%s", query[0] ? "?" : "", query);
    http(&g_main, "POST", path, NULL, &up, &r);
    expect_status(&g_main, &r, 200, mesh);
    assert_non_null(header(&r, "X-Job-Id", id, sizeof id));
    *srv = follow_metrics_link(&g_main, &r, id);
    resp_free(&r);
    /* the door's own facts, where each door has them */
    assert_string_equal(jstr(*srv, "job"), id);
    assert_true(cJSON_IsNull(cJSON_GetObjectItemCaseSensitive(*cli, "job")));
    assert_true(jnum(*srv, "timings.queue_s") >= 0);
    assert_true(jnum(*cli, "timings.read_s") >= 0);
}

/* Issue 18: the CLI and the daemon run one function for a job
 * (api_job_run), so the same request gives the same metrics document,
 * key for key and value for value (timings and door facts aside), through
 * either door: on three repository meshes, with a target and a flow's
 * step log (sphere_cgal), the default request (knot1, the fairing filter,
 * PLY out), and a Draco input and output (car, decoded in the daemon's
 * sandbox and under the CLI's in-process bound). The daemon measures
 * when asked (measures=true; a target asks too), as `--metrics` asks the
 * CLI. */
static void test_metrics_same_as_cli(void **state)
{
    static const char *const sphere[] = {"--scheme", "desbrun2", "--iterations", "3", NULL};
    static const char *const knot[] = {NULL};
    static const char *const car[] = {"--scheme", "taubin", "--iterations", "4", NULL};
    static const struct {
        const char *mesh, *target, *out, *const *args, *query;
    } runs[] = {
        {"sphere_cgal.obj", "sphere_cgal.obj", "out.obj", sphere, "scheme=desbrun2&iterations=3"},
        {"knot1.obj", NULL, "out.ply", knot, "format=ply&measures=true"},
        {"car.drc", NULL, "out.drc", car, "scheme=taubin&iterations=4&measures=true"},
    };
    cJSON *cli, *srv;
    size_t k;

    (void)state;
    assert_int_equal(tl_mcf_setup("test_server", "/tmp/mcfd-cli-XXXXXX"), 0);
    for (k = 0; k < sizeof runs / sizeof runs[0]; k++) {
        both_doors(runs[k].mesh, runs[k].target, runs[k].out, runs[k].args, runs[k].query,
                   &cli, &srv);
        same_document(cli, srv, "metrics");
        if (k == 0) /* the step log came through both */
            assert_int_equal(cJSON_GetArraySize(cJSON_GetObjectItemCaseSensitive(
                                 cJSON_GetObjectItemCaseSensitive(srv, "flow"), "log")), 3);
        cJSON_Delete(cli);
        cJSON_Delete(srv);
    }
    assert_int_equal(tl_mcf_teardown(), 0);
}

/* The step events of finished job id, replayed by its SSE stream: with
 * the measures (m its measured document) each carries its step's energy
 * and volume from the step log, the last step's energy the output's area
 * as the document's measures found it (mcf_mesh_inspect, not the log's
 * sum: relative 1e-12 for sums over 98 faces in different orders); the
 * job's progress the last of them. Without (m the light document) both
 * are null in every event and in the progress (the core made no pass
 * over the faces for them: test_core_flow's test_progress_energy). */
static void check_step_events(const char *id, const cJSON *m, int measured, int steps)
{
    const cJSON *log = cJSON_GetObjectItemCaseSensitive(
        cJSON_GetObjectItemCaseSensitive(m, "flow"), "log");
    char path[160];
    const char *p;
    resp_t r;
    cJSON *j, *pr;
    int n = 0;
    double last = NAN;

    snprintf(path, sizeof path, "/v1/jobs/%s/events", id);
    http(&g_main, "GET", path, NULL, NULL, &r);
    expect_status(&g_main, &r, 200, "events");
    for (p = r.body.data; (p = strstr(p, "event: progress\ndata: ")) != NULL; n++) {
        const cJSON *e, *v;
        p += strlen("event: progress\ndata: ");
        j = cJSON_ParseWithOpts(p, NULL, 0);
        assert_non_null(j);
        assert_int_equal((int)jnum(j, "step"), n + 1);
        e = cJSON_GetObjectItemCaseSensitive(j, "energy");
        v = cJSON_GetObjectItemCaseSensitive(j, "volume");
        if (!measured) {
            assert_true(cJSON_IsNull(e) && cJSON_IsNull(v));
        } else {
            const cJSON *L = cJSON_GetArrayItem(log, n);
            assert_non_null(L);
            assert_true(cJSON_IsNumber(e) && cJSON_IsNumber(v));
            /* the log's numbers: the event prints 17 digits, cJSON the
             * document's 15 when they read back within DBL_EPSILON */
            tl_assert_near(e->valuedouble, jnum(L, "area"), 1e-15 * fabs(e->valuedouble),
                           "streamed energy = logged area");
            tl_assert_near(v->valuedouble, jnum(L, "volume"), 1e-15 * fabs(v->valuedouble),
                           "streamed = logged volume");
            last = e->valuedouble;
        }
        cJSON_Delete(j);
    }
    assert_int_equal(n, steps);
    resp_free(&r);
    if (measured)
        tl_assert_near(last, jnum(m, "output.info.area"), 1e-12 * last,
                       "last step's energy = output.info.area");
    snprintf(path, sizeof path, "/v1/jobs/%s", id);
    http(&g_main, "GET", path, NULL, NULL, &r);
    expect_status(&g_main, &r, 200, "job");
    j = body_json(&r, "job");
    pr = cJSON_GetObjectItemCaseSensitive(j, "progress");
    if (measured)
        tl_assert_near(jnum(pr, "energy"), last, 1e-15 * last, "progress.energy = last step's");
    else
        assert_true(cJSON_IsNull(cJSON_GetObjectItemCaseSensitive(pr, "energy")));
    assert_true(measured ? cJSON_IsNumber(cJSON_GetObjectItemCaseSensitive(pr, "volume"))
                         : cJSON_IsNull(cJSON_GetObjectItemCaseSensitive(pr, "volume")));
    cJSON_Delete(j);
    resp_free(&r);
}

/* Diagnostics cost nothing unless asked for (issue 27): a job whose
 * request did not ask for the measures (measures=true, a target, fields,
 * the metrics with the result) gets the light document: every key, the
 * measured ones null (input.info, input.mesh, output.info, curvature's
 * before and after, timings.metrics_s), measured false, no step log; its
 * output counts, area and volume are the flow's, equal to what the
 * measured document of the same request says (relative 1e-12: the flow's
 * sums and mcf_mesh_inspect's run over the faces in different orders);
 * its step events carry energy and volume null (check_step_events). */
static void test_metrics_light_unless_asked(void **state)
{
    static const char *const h[] = {"Content-Type: model/obj", NULL};
    const double pi = 3.14159265358979323846;
    const char *const query[2] = {"/smooth?scheme=desbrun2&iterations=3",
                                  "/smooth?scheme=desbrun2&iterations=3&measures=true"};
    cJSON *m[2];
    api_buf obj;
    upload_t raw;
    resp_t r;
    char id[64];
    int i, k, n = 8;

    (void)state;
    api_buf_init(&obj, 0);
    for (k = 0; k < n; k++)
        for (i = 0; i < n; i++) {
            double x = (double)i / (n - 1), y = (double)k / (n - 1);
            assert_int_equal(api_buf_printf(&obj, "v %.17g %.17g %.17g\n", x, y,
                                            0.2 * sin(pi * x) * sin(pi * y)), MCF_OK);
        }
    for (k = 0; k + 1 < n; k++)
        for (i = 0; i + 1 < n; i++) {
            int a = k * n + i + 1, b = a + 1, c = a + n, d = c + 1;
            assert_int_equal(api_buf_printf(&obj, "f %d %d %d\nf %d %d %d\n", a, b, d, a,
                                            d, c), MCF_OK);
        }
    for (k = 0; k < 2; k++) {
        raw = (upload_t){.raw = obj.data, .raw_len = obj.len};
        http(&g_main, "POST", query[k], h, &raw, &r);
        expect_status(&g_main, &r, 200, query[k]);
        assert_non_null(header(&r, "X-Job-Id", id, sizeof id));
        m[k] = follow_metrics_link(&g_main, &r, id);
        resp_free(&r);
        check_step_events(id, m[k], k, 3);
    }
    assert_true(cJSON_IsFalse(cJSON_GetObjectItemCaseSensitive(m[0], "measured")));
    assert_true(cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(m[1], "measured")));
    for (k = 0; k < 2; k++) {
        const cJSON *in = cJSON_GetObjectItemCaseSensitive(m[k], "input"),
                    *out = cJSON_GetObjectItemCaseSensitive(m[k], "output"),
                    *cv = cJSON_GetObjectItemCaseSensitive(m[k], "curvature"),
                    *fl = cJSON_GetObjectItemCaseSensitive(m[k], "flow"),
                    *tm = cJSON_GetObjectItemCaseSensitive(m[k], "timings");
        /* light (k 0): null, never missing; measured (k 1): objects */
        assert_true(k ? cJSON_IsObject(cJSON_GetObjectItemCaseSensitive(in, "info"))
                      : cJSON_IsNull(cJSON_GetObjectItemCaseSensitive(in, "info")));
        assert_true(k ? cJSON_IsObject(cJSON_GetObjectItemCaseSensitive(in, "mesh"))
                      : cJSON_IsNull(cJSON_GetObjectItemCaseSensitive(in, "mesh")));
        assert_true(k ? cJSON_IsObject(cJSON_GetObjectItemCaseSensitive(out, "info"))
                      : cJSON_IsNull(cJSON_GetObjectItemCaseSensitive(out, "info")));
        assert_true(k ? cJSON_IsObject(cJSON_GetObjectItemCaseSensitive(cv, "before"))
                      : cJSON_IsNull(cJSON_GetObjectItemCaseSensitive(cv, "before")));
        assert_true(k ? cJSON_IsObject(cJSON_GetObjectItemCaseSensitive(cv, "after"))
                      : cJSON_IsNull(cJSON_GetObjectItemCaseSensitive(cv, "after")));
        assert_true(k ? cJSON_IsNumber(cJSON_GetObjectItemCaseSensitive(tm, "metrics_s"))
                      : cJSON_IsNull(cJSON_GetObjectItemCaseSensitive(tm, "metrics_s")));
        assert_int_equal(cJSON_GetArraySize(cJSON_GetObjectItemCaseSensitive(fl, "log")),
                         k ? 3 : 0);
        assert_int_equal((int)jnum(m[k], "output.vertices"), n * n);
        assert_int_equal((int)jnum(m[k], "output.faces"), 2 * (n - 1) * (n - 1));
    }
    tl_assert_near(jnum(m[0], "output.area"), jnum(m[1], "output.area"),
                   1e-12 * jnum(m[1], "output.area"), "output.area, light = measured");
    tl_assert_near(jnum(m[0], "output.volume"), jnum(m[1], "output.volume"),
                   1e-12 * fabs(jnum(m[1], "output.volume")), "output.volume, light = measured");
    cJSON_Delete(m[0]);
    cJSON_Delete(m[1]);
    api_buf_free(&obj);
}

/* One volume in the stream, the step log and the summary: mcf_mesh_volume's
 * (about the input's origin), on an open mesh off the origin with a free
 * boundary, where volumes about the origin and about the area centroid
 * differ by about 5/3. Each streamed volume is the log's. */
static void test_metrics_stream_volume_open(void **state)
{
    static const char *const h[] = {"Content-Type: model/obj", NULL};
    const double pi = 3.14159265358979323846;
    api_buf obj;
    upload_t raw;
    resp_t r;
    char *line, *save = NULL;
    double vol[8], frac = 0;
    int i, k, n = 8, steps = 0, done = 0;

    (void)state;
    /* an 8 x 8 grid with a bump, shifted by (3, -2, 5) (test_cli's) */
    api_buf_init(&obj, 0);
    for (k = 0; k < n; k++)
        for (i = 0; i < n; i++) {
            double x = (double)i / (n - 1), y = (double)k / (n - 1);
            assert_int_equal(api_buf_printf(&obj, "v %.17g %.17g %.17g\n", x + 3, y - 2,
                                            0.2 * sin(pi * x) * sin(pi * y) + 5), MCF_OK);
        }
    for (k = 0; k + 1 < n; k++)
        for (i = 0; i + 1 < n; i++) {
            int a = k * n + i + 1, b = a + 1, c = a + n, d = c + 1;
            assert_int_equal(api_buf_printf(&obj, "f %d %d %d\nf %d %d %d\n", a, b, d, a,
                                            d, c), MCF_OK);
        }
    raw = (upload_t){.raw = obj.data, .raw_len = obj.len};
    http(&g_main, "POST", "/smooth?iterations=5&dt=1e-3&boundary=free&stream=ndjson", h,
         &raw, &r);
    expect_status(&g_main, &r, 200, "open grid, ndjson");
    for (line = strtok_r(r.body.data, "\n", &save); line;
         line = strtok_r(NULL, "\n", &save)) {
        cJSON *j = cJSON_Parse(line);
        assert_non_null(j);
        if (work_event(j, &frac)) {
            cJSON_Delete(j);
            continue;
        }
        if (cJSON_GetObjectItemCaseSensitive(j, "done")) {
            const cJSON *m = cJSON_GetObjectItemCaseSensitive(j, "metrics");
            const cJSON *log = cJSON_GetObjectItemCaseSensitive(
                cJSON_GetObjectItemCaseSensitive(m, "flow"), "log");
            double v0 = jnum(m, "flow.volume0"), v1 = jnum(m, "flow.volume1");
            done = 1;
            assert_int_equal(steps, 5);
            assert_int_equal(cJSON_GetArraySize(log), 5);
            for (i = 0; i < 5; i++)
                tl_assert_near(vol[i], jnum(cJSON_GetArrayItem(log, i), "volume"),
                               1e-15 * fabs(vol[i]), "streamed = logged volume");
            /* relative 1e-12: sums over 98 faces in different orders */
            tl_assert_near(vol[4], v1, 1e-12 * fabs(v1), "last streamed = volume1");
            tl_assert_near(jnum(m, "output.volume"), v1, 1e-12 * fabs(v1),
                           "output.volume = volume1");
            tl_assert_near(jnum(m, "input.info.volume"), v0, 1e-12 * fabs(v0),
                           "input.info.volume = volume0");
            assert_true(fabs(v1 - v0) > 1e-4 * fabs(v0)); /* it moved */
        } else {
            assert_true(steps < 8);
            vol[steps++] = jnum(j, "volume");
        }
        cJSON_Delete(j);
    }
    assert_true(done);
    resp_free(&r);
    api_buf_free(&obj);
}

/* The core's warnings in the daemon's metrics, as the CLI writes them:
 * 1e-9 of unit-area time is "little_smoothing". */
static void test_metrics_warnings(void **state)
{
    upload_t up = {.mesh = "sphere_cgal.obj"};
    resp_t r;
    char id[64];
    cJSON *m;
    const cJSON *w;

    (void)state;
    http(&g_main, "POST", "/smooth?iterations=1&dt=1e-9", NULL, &up, &r);
    expect_status(&g_main, &r, 200, "a negligible amount");
    assert_non_null(header(&r, "X-Job-Id", id, sizeof id));
    m = follow_metrics_link(&g_main, &r, id);
    w = cJSON_GetObjectItemCaseSensitive(m, "warnings");
    assert_int_equal(cJSON_GetArraySize(w), 1);
    assert_string_equal(cJSON_GetStringValue(cJSON_GetArrayItem(w, 0)), "little_smoothing");
    assert_true(jnum(m, "flow.strength") < 0.1);
    /* and in a header of the answer, as of GET .../result */
    {
        char hv[128], path[160];
        assert_non_null(header(&r, "X-Warnings", hv, sizeof hv));
        assert_string_equal(hv, "little_smoothing");
        resp_free(&r);
        snprintf(path, sizeof path, "/v1/jobs/%s/result", id);
        http(&g_main, "GET", path, NULL, NULL, &r);
        expect_status(&g_main, &r, 200, "result of a warned job");
        assert_non_null(header(&r, "X-Warnings", hv, sizeof hv));
        assert_string_equal(hv, "little_smoothing");
    }
    cJSON_Delete(m);
    resp_free(&r);
    /* the default amount warns of nothing: no header */
    http(&g_main, "POST", "/smooth", NULL, &up, &r);
    expect_status(&g_main, &r, 200, "the default amount");
    {
        char hv[128];
        assert_null(header(&r, "X-Warnings", hv, sizeof hv));
    }
    resp_free(&r);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_teardown(test_service_endpoints, kill_strays),
        cmocka_unit_test_teardown(test_smooth_obj_multipart, kill_strays),
        cmocka_unit_test_teardown(test_smooth_draco_multipart, kill_strays),
        cmocka_unit_test_teardown(test_thread_count, kill_strays),
        cmocka_unit_test_teardown(test_smooth_gltf, kill_strays),
        cmocka_unit_test_teardown(test_smooth_attributes, kill_strays),
        cmocka_unit_test_teardown(test_smooth_raw_and_params, kill_strays),
        cmocka_unit_test_teardown(test_smooth_target, kill_strays),
        cmocka_unit_test_teardown(test_smooth_default_fairing, kill_strays),
        cmocka_unit_test_teardown(test_smooth_multipart_mixed, kill_strays),
        cmocka_unit_test_teardown(test_smooth_ndjson, kill_strays),
        cmocka_unit_test_teardown(test_default_stream_milestones, kill_strays),
        cmocka_unit_test_teardown(test_smooth_ndjson_live, kill_strays),
        cmocka_unit_test_teardown(test_async_job, kill_strays),
        cmocka_unit_test_teardown(test_cancel, kill_strays),
        cmocka_unit_test_teardown(test_page, kill_strays),
        cmocka_unit_test_teardown(test_fields, kill_strays),
        cmocka_unit_test_teardown(test_errors, kill_strays),
        cmocka_unit_test_teardown(test_metrics_same_as_cli, kill_strays),
        cmocka_unit_test_teardown(test_metrics_light_unless_asked, kill_strays),
        cmocka_unit_test_teardown(test_metrics_stream_volume_open, kill_strays),
        cmocka_unit_test_teardown(test_metrics_warnings, kill_strays),
    };
    /* MCF_TEST_FILTER=test_errors (a cmocka pattern) runs a subset. */
    if (getenv("MCF_TEST_FILTER") && *getenv("MCF_TEST_FILTER"))
        cmocka_set_test_filter(getenv("MCF_TEST_FILTER"));
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
