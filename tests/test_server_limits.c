/* SPDX-License-Identifier: MIT */
/*
 * test_server_limits.c - integration tests of mcfd's memory and CPU
 * bounds: the step log and the events of long runs, the quantization cap,
 * the Draco decode sandbox, memory admission and uploads in flight. A real
 * daemon on loopback, as in test_server.c; the helpers are srvlib.c's.
 */
#include "srvlib.h"

static long rss_kib(pid_t pid)
{
    return status_kib(pid, "VmRSS");
}

/* An octahedron (6 vertices, 8 faces) as an OBJ body: steps cost
 * microseconds, so tens of thousands of them take a second or two. */
static const char k_octa[] =
    "v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n"
    "f 1 3 5\nf 3 2 5\nf 2 4 5\nf 4 1 5\nf 3 1 6\nf 2 3 6\nf 4 2 6\nf 1 4 6\n";

/* Issue 17 item 6: a 72 KB mesh run for 100,000 steps was admitted at
 * 4.9 MB but kept a 15 MB metrics document (every step in flow.log) in
 * memory for its whole TTL; 20 such jobs held 663 MiB against a bound of
 * 124 MiB. Now admission counts the steps' memory (the step log and the
 * progress events), the document's flow.log keeps at most 1000 entries
 * (first, last and evenly between, each with its step), and a finished
 * job's metrics are on disk only. */
static void test_step_log_memory(void **state)
{
    static const char *const flags[] = {"--workers", "1", "--max-job-memory",
                                        "12M", NULL};
    upload_t up = {.mesh = "sphere_cgal.obj"};
    upload_t octa = {.raw = k_octa, .raw_len = sizeof k_octa - 1};
    daemon_t d;
    char spool[600], id[SRV_ID_BUF], path[200], file[900];
    struct stat st;
    resp_t r;
    cJSON *j;
    const cJSON *log;
    int n;

    (void)state;
    snprintf(spool, sizeof spool, "%s/steplog", g_tmp);
    assert_int_equal(start_daemon(&d, "steplog", spool, flags), 0);
    /* 100,000 steps of the sphere: 4.9 MB of mesh work, ~17 MB of log
     * and events. main: admitted (202). */
    http(&d, "POST", "/v1/jobs?iterations=100000&scheme=euler", NULL, &up, &r);
    print_message("    100,000 steps of a 72 KB mesh, --max-job-memory 12M: "
                  "HTTP %ld (main: 202)\n", r.code);
    if (r.code == 202) {
        cJSON *k = body_json(&r, "POST");
        snprintf(path, sizeof path, "/v1/jobs/%s", jstr(k, "id"));
        cJSON_Delete(k);
        resp_free(&r);
        http(&d, "DELETE", path, NULL, NULL, &r);
        resp_free(&r);
        fail_msg("a job whose steps' log exceeds --max-job-memory was admitted");
    }
    expect_problem(&d, &r, 422, "ELIMIT", "--max-job-memory", "100,000 steps");
    resp_free(&r);

    http(&d, "POST", "/v1/jobs?iterations=20000&scheme=euler&dt=1e-6&measures=true", NULL,
         &octa, &r);
    expect_status(&d, &r, 202, "20,000 steps of an octahedron");
    j = body_json(&r, "POST");
    snprintf(id, sizeof id, "%s", jstr(j, "id"));
    cJSON_Delete(j);
    resp_free(&r);
    cJSON_Delete(poll_job(&d, id, "succeeded", 60));
    snprintf(file, sizeof file, "%s/jobs/%s/metrics.json", spool, id);
    assert_int_equal(stat(file, &st), 0);
    print_message("    metrics.json of 20,000 steps: %.0f KB (main: 2,900 KB)\n",
                  st.st_size / 1e3);
    snprintf(path, sizeof path, "/v1/jobs/%s/metrics", id);
    http(&d, "GET", path, NULL, NULL, &r);
    expect_status(&d, &r, 200, "the metrics");
    j = body_json(&r, "metrics");
    log = cJSON_GetObjectItemCaseSensitive(
        cJSON_GetObjectItemCaseSensitive(j, "flow"), "log");
    n = cJSON_GetArraySize(log);
    assert_int_equal(n, 1000);
    assert_int_equal((int)jnum(cJSON_GetArrayItem(log, 0), "step"), 1);
    assert_int_equal((int)jnum(cJSON_GetArrayItem(log, n - 1), "step"), 20000);
    assert_int_equal((int)jnum(j, "flow.steps"), 20000);
    cJSON_Delete(j);
    resp_free(&r);
    /* the job's own document has them too, read back from the spool */
    snprintf(path, sizeof path, "/v1/jobs/%s", id);
    http(&d, "GET", path, NULL, NULL, &r);
    j = body_json(&r, "GET job");
    assert_int_equal((int)jnum(j, "metrics.flow.steps"), 20000);
    cJSON_Delete(j);
    resp_free(&r);
    stop_daemon(&d);
}

/* Issue 17, memory outside admission: a finished job kept its progress
 * events (an ndjson line a step, up to 16 MiB) in memory for 10 s after
 * it finished, and for as long as anyone held it, while admission had
 * let its memory go: 8 jobs of 100,000 steps of an octahedron, two at a
 * time under --max-memory 64M, peaked at rest + 119 MiB. Now a finished
 * job's events are on the spool (events.ndjson and its index), read back
 * for late followers, so the peak holds (rest + --max-memory) and a late
 * follower gets every step, for the job's whole TTL, also after a
 * restart (before: none 10 s after the end). */
static void test_events_memory(void **state)
{
    static const char *const flags[] = {"--workers", "2", "--max-memory",
                                        "64M", NULL};
    upload_t octa = {.raw = k_octa, .raw_len = sizeof k_octa - 1};
    daemon_t d;
    char spool[600], ids[8][SRV_ID_BUF], path[200];
    long rest, hwm = -1;
    resp_t r;
    int i;

    (void)state;
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
    tl_skip("test_events_memory", "RSS is meaningless under a sanitizer "
            "(its quarantine, shadow and allocator caches)");
    return;
#endif
    snprintf(spool, sizeof spool, "%s/events-mem", g_tmp);
    assert_int_equal(start_daemon(&d, "events-mem", spool, flags), 0);
    rest = status_kib(d.pid, "VmRSS");
    for (i = 0; i < 8; i++) {
        cJSON *j;
        http(&d, "POST", "/v1/jobs?iterations=100000&scheme=euler&dt=1e-6",
             NULL, &octa, &r);
        expect_status(&d, &r, 202, "100,000 steps of an octahedron");
        j = body_json(&r, "POST");
        snprintf(ids[i], sizeof ids[i], "%s", jstr(j, "id"));
        cJSON_Delete(j);
        resp_free(&r);
    }
    for (i = 0; i < 8; i++)
        cJSON_Delete(poll_job(&d, ids[i], "succeeded", 120));
    hwm = status_kib(d.pid, "VmHWM");
    print_message("    8 jobs of 100,000 steps, 2 at a time, --max-memory 64M: "
                  "peak RSS rest + %ld MiB (main: + 119 MiB)\n",
                  (hwm - rest) / 1024);
    /* a late follower gets every step, from the spool; Last-Event-ID
     * resumes in the middle of the index */
    snprintf(path, sizeof path, "/v1/jobs/%s/events", ids[0]);
    http(&d, "GET", path, NULL, NULL, &r);
    expect_status(&d, &r, 200, "the events of a finished job");
    if (count_of(r.body.data, "event: progress") != 100000 ||
        !strstr(r.body.data, "id: 100000\nevent: progress\ndata: {\"step\":100000,"))
        fail_msg("a late follower got %d progress events of 100000",
                 count_of(r.body.data, "event: progress"));
    resp_free(&r);
    {
        static const char *const h[] = {"Last-Event-ID: 99990", NULL};
        http(&d, "GET", path, h, NULL, &r);
        if (count_of(r.body.data, "event: progress") != 10 ||
            !strstr(r.body.data, "id: 99991\nevent: progress\ndata: {\"step\":99991,"))
            fail_msg("Last-Event-ID 99990: %.300s", r.body.data);
        resp_free(&r);
    }
    stop_daemon(&d);
    /* and after a restart */
    assert_int_equal(start_daemon(&d, "events-mem2", spool, flags), 0);
    http(&d, "GET", path, NULL, NULL, &r);
    if (count_of(r.body.data, "event: progress") != 100000)
        fail_msg("after a restart, a late follower got %d progress events "
                 "of 100000", count_of(r.body.data, "event: progress"));
    resp_free(&r);
    stop_daemon(&d);
    if (hwm > rest + 64 * 1024)
        fail_msg("peak RSS %ld KiB exceeds rest %ld KiB + --max-memory 64M",
                 hwm, rest);
}

/* Issue 9 item 4, in part: format=draco&quantization_bits=30 on a
 * 649-byte mesh peaked at 2.75 GB (Draco's encoder memory doubles per
 * bit). quantization_bits stops at 24 (58 MB on the sphere). */
static void test_quantization_cap(void **state)
{
    upload_t up = {.mesh = "sphere_cgal.obj"};
    resp_t r;

    (void)state;
    http(&g_main, "POST", "/smooth?format=draco&quantization_bits=30", NULL,
         &up, &r);
    expect_problem(&g_main, &r, 400, "EINVAL", "quantization_bits",
                   "30 quantization bits");
    resp_free(&r);
    http(&g_main, "POST", "/smooth?format=draco&quantization_bits=24", NULL,
         &up, &r);
    expect_status(&g_main, &r, 200, "24 quantization bits");
    {
        api_format fmt;
        mcf_mesh *m = decode_body(&r, &fmt);
        assert_int_equal(fmt, API_FMT_DRACO);
        mcf_mesh_free(m);
    }
    resp_free(&r);
}

/* ---------------------------------------------- issue 9: sandbox, memory */

/* Child processes of pid now (from /proc/PID/task/TID/children). */
static int count_children(pid_t pid)
{
    char path[384], buf[4096];
    DIR *dir;
    struct dirent *e;
    int n = 0;

    snprintf(path, sizeof path, "/proc/%d/task", (int)pid);
    if (!(dir = opendir(path)))
        return -1;
    while ((e = readdir(dir)) != NULL) {
        FILE *f;
        size_t got;
        char *p;
        if (e->d_name[0] == '.')
            continue;
        snprintf(path, sizeof path, "/proc/%d/task/%s/children", (int)pid,
                 e->d_name);
        if (!(f = fopen(path, "r")))
            continue;
        got = fread(buf, 1, sizeof buf - 1, f);
        fclose(f);
        buf[got] = '\0';
        for (p = strtok(buf, " \n"); p; p = strtok(NULL, " \n"))
            n++;
    }
    closedir(dir);
    return n;
}

/* Open descriptors of pid. */
static int count_fds(pid_t pid)
{
    char path[64];
    DIR *dir;
    struct dirent *e;
    int n = 0;
    snprintf(path, sizeof path, "/proc/%d/fd", (int)pid);
    if (!(dir = opendir(path)))
        return -1;
    while ((e = readdir(dir)) != NULL)
        n += e->d_name[0] != '.';
    closedir(dir);
    return n;
}

/* Issue 9 item 4: libdraco 1.5.5 trusts a texcoord orientation count
 * inside the stream. draco_texcoord_orientations.drc (210 bytes: a 4x4
 * grid with texcoords, draco_encoder -cl 10 -qt 10, the int32 count at
 * byte 180 set to 2^31-1) makes it allocate 256 MiB and spin 8.8 s, then
 * "succeed". Decoded in the daemon's sandbox it is a 422 naming the
 * limit: memory (64 MiB) by default, CPU (2 s) with --decode-memory 1G;
 * a DELETE kills the decoder at once; no child or descriptor is left. */
static void test_draco_sandbox(void **state)
{
    static const char *const cpu_flags[] = {"--decode-memory", "1G", NULL};
    static const char *const cancel_flags[] = {"--decode-memory", "1G",
                                               "--decode-cpu", "120s", NULL};
    const char *bomb = "draco_texcoord_orientations.drc";
    daemon_t d;
    char spool[600], id[SRV_ID_BUF], path[160];
    int fds0, fds1;
    double t0, dt;
    resp_t r;
    cJSON *j;

    (void)state;
    snprintf(spool, sizeof spool, "%s/sandbox", g_tmp);
    assert_int_equal(start_daemon(&d, "sandbox", spool, NULL), 0);
    post_file(&d, "/smooth", "meshes/bunny.drc", &r); /* warm: first spawn */
    expect_status(&d, &r, 200, "bunny.drc through the sandbox");
    resp_free(&r);
    sleep_ms(300); /* the warm-up's connection closes on MHD's next turn */
    fds0 = count_fds(d.pid);
    t0 = mcf_now();
    post_file(&d, "/smooth", bomb, &r);
    dt = mcf_now() - t0;
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
    /* no address-space limit under ASan or TSan (sandbox.c): the CPU one stops it */
    expect_problem(&d, &r, 422, "ELIMIT", "to decode: refused", "orientation bomb");
#else
    expect_problem(&d, &r, 422, "ELIMIT", "needs more than 64 MiB to decode",
                   "orientation bomb");
#endif
    resp_free(&r);
    print_message("    210-byte orientation bomb, default limits: 422 in %.2f s "
                  "(8.8 s and 256 MiB in-process)\n", dt);
    /* The 422's text names the limit that stopped it (that is the
     * behaviour); the time is printed, and bounded only as a hang guard:
     * a child under RLIMIT_CPU of 2 s stretches in wall time with the
     * machine's load (CI saw 6-8.6 s under sanitizers at load 10), while
     * the unbounded decode would spin for ever at 2^31 orientations. */
    assert_true(dt < 30);
    /* the same stream as a glTF's Draco primitive: the same sandbox */
    t0 = mcf_now();
    post_file(&d, "/smooth", "gltf/draco_bomb.glb", &r);
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
    expect_problem(&d, &r, 422, "ELIMIT", "to decode: refused", "orientation bomb in a GLB");
#else
    expect_problem(&d, &r, 422, "ELIMIT", "needs more than 64 MiB to decode",
                   "orientation bomb in a GLB");
#endif
    resp_free(&r);
    print_message("    the bomb as a GLB's Draco primitive: 422 in %.2f s\n", mcf_now() - t0);
    post_file(&d, "/smooth", "meshes/car.drc", &r);
    expect_status(&d, &r, 200, "car.drc after the bomb");
    resp_free(&r);
    assert_int_equal(count_children(d.pid), 0);
    /* the client's connections close on MHD's next turn */
    for (t0 = mcf_now(); (fds1 = count_fds(d.pid)) > fds0 && mcf_now() - t0 < 2;)
        sleep_ms(50);
    print_message("    descriptors %d -> %d, children 0\n", fds0, fds1);
    assert_true(fds1 <= fds0);
    stop_daemon(&d);

    snprintf(spool, sizeof spool, "%s/sandbox-cpu", g_tmp);
    assert_int_equal(start_daemon(&d, "sandbox-cpu", spool, cpu_flags), 0);
    t0 = mcf_now();
    post_file(&d, "/smooth", bomb, &r);
    dt = mcf_now() - t0;
    expect_problem(&d, &r, 422, "ELIMIT", "needs more than 2 s of CPU to decode",
                   "orientation bomb, --decode-memory 1G");
    resp_free(&r);
    print_message("    the same with --decode-memory 1G: 422 (CPU) in %.2f s\n", dt);
    assert_true(dt >= 1.9 && dt < 30); /* 2 s of CPU; hang guard as above */
    stop_daemon(&d);

    /* a DELETE while it decodes kills the child: under a 120 s CPU limit,
     * a cancel seen within the poll's 10 s can only be the kill (no wall
     * bound of the scheduler's: the old check, < 1.9 s against a 2 s
     * limit, measured the machine's load as much as the kill) */
    snprintf(spool, sizeof spool, "%s/sandbox-cancel", g_tmp);
    assert_int_equal(start_daemon(&d, "sandbox-cancel", spool, cancel_flags), 0);
    post_file(&d, "/v1/jobs", bomb, &r);
    expect_status(&d, &r, 202, "async orientation bomb");
    j = body_json(&r, "POST /v1/jobs");
    snprintf(id, sizeof id, "%s", jstr(j, "id"));
    cJSON_Delete(j);
    resp_free(&r);
    cJSON_Delete(poll_job(&d, id, "running", 10));
    sleep_ms(300);
    snprintf(path, sizeof path, "/v1/jobs/%s", id);
    t0 = mcf_now();
    http(&d, "DELETE", path, NULL, NULL, &r);
    resp_free(&r);
    j = poll_job(&d, id, NULL, 10);
    dt = mcf_now() - t0;
    assert_string_equal(jstr(j, "status"), "canceled");
    cJSON_Delete(j);
    print_message("    DELETE during the decode: canceled after %.2f s\n", dt);
    assert_int_equal(count_children(d.pid), 0);
    stop_daemon(&d);
}

/* Issue 9 item 4: admission by estimated memory. A job whose estimate
 * exceeds --max-job-memory is a 422 naming both; with --max-memory room
 * for one bunny job, two never run at once; and under the worst admitted
 * set (strength=auto, the largest per-vertex peak, 2 workers) the
 * daemon's peak RSS (VmHWM) stays under its size at rest plus
 * --max-memory. */
static void test_memory_admission(void **state)
{
    static const char *const small[] = {"--max-job-memory", "20M", NULL};
    static const char *const one[] = {"--workers", "2", "--max-memory", "100M",
                                      NULL};
    daemon_t d;
    char spool[600], ids[3][SRV_ID_BUF], path[160];
    long rest = -1, hwm = -1;
    int i, both = 0, done;
    resp_t r;

    (void)state;
    snprintf(spool, sizeof spool, "%s/admit-small", g_tmp);
    assert_int_equal(start_daemon(&d, "admit-small", spool, small), 0);
    post_file(&d, "/smooth", "meshes/bunny.drc", &r);
    expect_problem(&d, &r, 422, "ELIMIT", "exceeds --max-job-memory 20 MiB",
                   "bunny.drc over --max-job-memory 20M");
    resp_free(&r);
    post_file(&d, "/smooth", "meshes/sphere_cgal.obj", &r);
    expect_status(&d, &r, 200, "the sphere under --max-job-memory 20M");
    resp_free(&r);
    stop_daemon(&d);

    snprintf(spool, sizeof spool, "%s/admit-budget", g_tmp);
    assert_int_equal(start_daemon(&d, "admit-budget", spool, one), 0);
    rest = status_kib(d.pid, "VmRSS");
    for (i = 0; i < 3; i++) {
        cJSON *j;
        post_file(&d, "/v1/jobs?scheme=desbrun2&strength=auto", "meshes/bunny.drc", &r);
        expect_status(&d, &r, 202, "bunny.drc job");
        j = body_json(&r, "POST /v1/jobs");
        snprintf(ids[i], sizeof ids[i], "%s", jstr(j, "id"));
        cJSON_Delete(j);
        resp_free(&r);
    }
    for (done = 0; done < 3;) {
        done = 0;
        for (i = 0; i < 3; i++) {
            cJSON *j;
            snprintf(path, sizeof path, "/v1/jobs/%s", ids[i]);
            http(&d, "GET", path, NULL, NULL, &r);
            j = body_json(&r, "GET job");
            resp_free(&r);
            done += !strcmp(jstr(j, "status"), "succeeded");
            if (!strcmp(jstr(j, "status"), "failed"))
                fail_msg("job %s failed", ids[i]);
            cJSON_Delete(j);
        }
        sleep_ms(50);
    }
    /* Two ran at once when their [started, finished) intervals overlap
     * (the daemon's own timestamps, RFC 3339 in ms, which compare as
     * text; a poll of the three statuses is no snapshot: under load a job
     * may finish and the next start between two GETs of one round). A
     * job starts only after the one before released its memory, which is
     * after its finished time was set. */
    {
        char st[3][40], fin[3][40];
        int k;
        for (i = 0; i < 3; i++) {
            cJSON *j;
            snprintf(path, sizeof path, "/v1/jobs/%s", ids[i]);
            http(&d, "GET", path, NULL, NULL, &r);
            j = body_json(&r, "GET job");
            resp_free(&r);
            snprintf(st[i], sizeof st[i], "%s", jstr(j, "started"));
            snprintf(fin[i], sizeof fin[i], "%s", jstr(j, "finished"));
            cJSON_Delete(j);
        }
        for (i = 0; i < 3; i++)
            for (k = i + 1; k < 3; k++)
                if (strcmp(st[i], fin[k]) < 0 && strcmp(st[k], fin[i]) < 0) {
                    print_message("    jobs %d [%s, %s) and %d [%s, %s) "
                                  "overlap\n", i, st[i], fin[i], k, st[k],
                                  fin[k]);
                    both = 1;
                }
    }
    hwm = status_kib(d.pid, "VmHWM");
    print_message("    3 bunny.drc strength=auto jobs, --max-memory 100M, 2 "
                  "workers: %s at once; RSS at rest %ld KiB, peak %ld KiB\n",
                  both ? "two" : "never two", rest, hwm);
    assert_false(both); /* each is estimated at 57.5 MiB */
    stop_daemon(&d);
#if defined(__SANITIZE_ADDRESS__)
    tl_skip("test_memory_admission", "RSS is meaningless under "
            "AddressSanitizer (freed memory stays in its quarantine)");
    return;
#elif defined(__SANITIZE_THREAD__)
    tl_skip("test_memory_admission", "RSS is meaningless under "
            "ThreadSanitizer (its shadow and its allocator's caches)");
    return;
#endif
    assert_true(rest > 0 && hwm > 0);
    if (hwm > rest + 100 * 1024)
        fail_msg("peak RSS %ld KiB exceeds rest %ld KiB + --max-memory 100M",
                 hwm, rest);
}

/* Sends n bytes of an OBJ-looking body to fd; how many went before the
 * daemon closed or answered (a refused upload is answered early). */
static size_t send_body(int fd, size_t n)
{
    static char block[64 * 1024];
    size_t sent = 0;
    if (!block[0])
        for (size_t i = 0; i < sizeof block; i += 8)
            memcpy(block + i, "v 0 0 0\n", 8);
    while (sent < n) {
        size_t k = n - sent < sizeof block ? n - sent : sizeof block;
        ssize_t w = send(fd, block, k, MSG_NOSIGNAL);
        if (w <= 0)
            break;
        sent += (size_t)w;
    }
    return sent;
}

/* What the REST door holds past --max-memory while uploads stream in:
 * the bound of docs/reliability.md is VmHWM <= rest + --max-memory + this
 * (test_grpc.py's UPLOAD_SLACK is gRPC's, 12 MiB). Each upload's
 * reservation is its bytes plus SVC_UPLOAD_AROUND (2 MiB), which covers
 * what it costs beside them: its connection's libmicrohttpd pool
 * (SRV_CONN_MEMORY, 64 KiB) and the page rounding of its buffer; the
 * body is read straight into that buffer (no copy in flight past 64 KiB)
 * and a refused one is discarded, never buffered. What no reservation
 * covers: the pools of connections that hold no upload (the 14 refused
 * here, 64 KiB each while open: 0.9 MiB) and the malloc arenas of the
 * two libmicrohttpd threads, grown by the first uploads. Measured
 * (2026-11-25, 2 cores shared with a sanitizer test run), 8 runs alike:
 * growth over rest +80.4 MiB for the two declared 40 MiB uploads (84 MiB
 * reserved, 80 of them bytes) and +95.5 MiB for the chunked one beside a
 * held 40 MiB one (100 MiB reserved, 96 of them bytes): REST's growth is
 * its bytes, the AROUND part unused, so it stays within the budget.
 * 4 MiB is the unreserved part above with room to spare (the arenas:
 * gRPC's grew 4 MiB, with more threads; 1 MiB of pools), a third of the
 * gRPC door's 12, whose slices and gate queues hold bytes in flight
 * that REST never does. */
#define REST_UPLOAD_SLACK_KIB (4 * 1024)

/* Sets VmHWM back to VmRSS (clear_refs 5, Linux 4.0): 0, or -1. */
static int reset_hwm(pid_t pid)
{
    char path[64];
    FILE *f;
    int ok;

    snprintf(path, sizeof path, "/proc/%d/clear_refs", (int)pid);
    if (!(f = fopen(path, "w")))
        return -1;
    ok = fputs("5", f) >= 0;
    return fclose(f) == 0 && ok ? 0 : -1;
}

/* Issue 17 item 7: uploads held open were outside the memory budget: 16
 * bodies of 40 MiB, each sent but for its last byte, took 665 MiB against
 * a documented peak of rest + --max-memory 100M (the ceiling was
 * connections x --max-upload). Now an upload's Content-Length is reserved
 * in --max-memory beside the running jobs before its body is read
 * (svc_upload_reserve): two fit, the others are answered 503 EBUSY with
 * Retry-After before their body; a body without a length reserves as it
 * comes, and is refused (read and discarded, never buffered) when the
 * budget is full. */
static void test_uploads_in_flight(void **state)
{
    static const char *const flags[] = {"--max-memory", "100M", "--max-upload", "64M",
                                        "--max-connections-per-ip", "0", NULL};
    const size_t body = (size_t)40 << 20;
    daemon_t d;
    char spool[600], head[256], buf[512] = "";
    int fds[16], held = 0, busy = 0, i, fd;
    long rest, hwm, hwm2 = 0;
    int reset;
    resp_t r;

    (void)state;
    snprintf(spool, sizeof spool, "%s/uploads", g_tmp);
    assert_int_equal(start_daemon(&d, "uploads", spool, flags), 0);
    rest = rss_kib(d.pid);
    snprintf(head, sizeof head, "POST /v1/jobs HTTP/1.1\r\nHost: x\r\nContent-Type: "
             "model/obj\r\nContent-Length: %zu\r\n\r\n", body);
    for (i = 0; i < 16; i++) {
        fds[i] = connect_from(&d, "127.0.0.1", head);
        if (send_body(fds[i], body - 1) == body - 1)
            held++;
    }
    sleep_ms(300);
    hwm = status_kib(d.pid, "VmHWM");
    for (i = 0; i < 16; i++) {
        struct pollfd p = {fds[i], POLLIN, 0};
        ssize_t k = poll(&p, 1, 0) > 0 ? read(fds[i], buf, sizeof buf - 1) : 0;
        buf[k > 0 ? k : 0] = '\0';
        busy += strstr(buf, " 503 ") && strstr(buf, "EBUSY") && strstr(buf, "Retry-After");
        close(fds[i]);
    }
    /* without a Content-Length (chunked): the budget fills as bytes come */
    sleep_ms(200);                     /* the closed uploads gave theirs back */
    reset = reset_hwm(d.pid) == 0;     /* its own peak */
    fd = connect_from(&d, "127.0.0.1", "POST /v1/jobs HTTP/1.1\r\nHost: x\r\nContent-Type: "
                      "model/obj\r\nTransfer-Encoding: chunked\r\n\r\n");
    {
        int fd2 = connect_from(&d, "127.0.0.1", head);
        size_t k = send_body(fd2, body - 1);   /* 40 MiB held, declared */
        char chunk[32];
        size_t sent = 0;
        ssize_t n;
        snprintf(chunk, sizeof chunk, "%x\r\n", 1 << 20);
        /* 70 MiB: past the 60 the budget has left, and within the 16 MiB a
         * refused body is still read for its answer */
        while (sent < ((size_t)70 << 20)) {
            if (send(fd, chunk, strlen(chunk), MSG_NOSIGNAL) <= 0 ||
                send_body(fd, (size_t)1 << 20) != (size_t)1 << 20 ||
                send(fd, "\r\n", 2, MSG_NOSIGNAL) != 2)
                break;
            sent += (size_t)1 << 20;
        }
        (void)!send(fd, "0\r\n\r\n", 5, MSG_NOSIGNAL);
        n = read(fd, buf, sizeof buf - 1);
        if (n > 0)
            buf[n] = '\0';
        else
            snprintf(buf, sizeof buf, "(no answer)");
        hwm2 = status_kib(d.pid, "VmHWM");
        print_message("    16 uploads of 40 MiB held open (--max-memory 100M): %d taken, %d "
                      "refused 503 EBUSY before their body; a chunked one beside a held "
                      "40 MiB one: %zu MiB sent, answered %.12s; VmHWM rest + %.1f then "
                      "+ %.1f MiB%s (rest %.1f MiB; bound + 100 + %d)\n", held, busy,
                      sent >> 20, buf + 9, (hwm - rest) / 1024.0, (hwm2 - rest) / 1024.0,
                      reset ? " (its own)" : "", rest / 1024.0, REST_UPLOAD_SLACK_KIB >> 10);
        assert_true(k == body - 1);
        assert_non_null(strstr(buf, " 503 "));
        close(fd2);
    }
    close(fd);
    assert_int_equal(held, 2);
    assert_int_equal(busy, 14);
    /* the budget is free again once the daemon has seen them go */
    for (i = 0; i < 40; i++) {
        if (post_file(&d, "/smooth", "meshes/sphere_cgal.obj", &r) != 503)
            break;
        resp_free(&r);
        sleep_ms(50);
    }
    expect_status(&d, &r, 200, "an upload after the held ones left");
    resp_free(&r);
    stop_daemon(&d);
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
    return;                            /* RSS means nothing there (test_memory_admission) */
#endif
    if (hwm > rest + 100 * 1024 + REST_UPLOAD_SLACK_KIB ||
        hwm2 > rest + 100 * 1024 + REST_UPLOAD_SLACK_KIB)
        fail_msg("peak RSS %ld KiB (declared), %ld KiB (chunked) exceeds rest %ld KiB + "
                 "--max-memory 100M + %d KiB", hwm, hwm2, rest, REST_UPLOAD_SLACK_KIB);
}

/* Issue 28 item 10: a job's CPU budget, --job-cpu plus
 * MCFD_JOB_CPU_PER_MIB s per MiB of its memory estimate (0.5 by default;
 * 0.2 s + 0.01 s/MiB here, so the test is short), on its worker's
 * thread: a job of 20,000 implicit steps of the 812-vertex sphere (about
 * 6 s of CPU here, all of them before) is stopped 422 ELIMIT naming the
 * budget, counted in mcfd_jobs_cpu_budget_exceeded_total, and logged with
 * its cpu_s and cpu_budget_s; a short job still succeeds. */
static void test_cpu_budget(void **state)
{
    static const char *const flags[] = {"--workers", "1", "--job-cpu", "0.2",
                                        NULL};
    upload_t up = {.mesh = "sphere_cgal.obj"};
    daemon_t d;
    char spool[600];
    resp_t r;
    const char *at;
    int step = -1;

    (void)state;
    snprintf(spool, sizeof spool, "%s/cpu-budget", g_tmp);
    setenv("MCFD_JOB_CPU_PER_MIB", "0.01", 1);
    assert_int_equal(start_daemon(&d, "cpu-budget", spool, flags), 0);
    unsetenv("MCFD_JOB_CPU_PER_MIB");
    http(&d, "POST", "/smooth?scheme=desbrun2&iterations=20000&dt=1e-7", NULL,
         &up, &r);
    expect_problem(&d, &r, 422, "ELIMIT", "CPU budget",
                   "a job past its CPU budget");
    if ((at = strstr(r.body.data, "stopped after step ")))
        step = atoi(at + strlen("stopped after step "));
    print_message("    20,000 steps under a CPU budget of 0.2 s + 0.01 s/MiB: 422 after "
                  "step %d (before: all 20,000 steps)\n", step);
    assert_true(step > 0 && step < 20000);
    resp_free(&r);
    http(&d, "GET", "/metrics", NULL, NULL, &r);
    expect_status(&d, &r, 200, "GET /metrics");
    assert_true(metric(r.body.data, "mcfd_jobs_cpu_budget_exceeded_total") == 1);
    resp_free(&r);
    http(&d, "POST", "/smooth?scheme=desbrun2&iterations=2", NULL, &up, &r);
    expect_status(&d, &r, 200, "a short job under the budget");
    resp_free(&r);
    stop_daemon(&d);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_teardown(test_step_log_memory, kill_strays),
        cmocka_unit_test_teardown(test_events_memory, kill_strays),
        cmocka_unit_test_teardown(test_quantization_cap, kill_strays),
        cmocka_unit_test_teardown(test_draco_sandbox, kill_strays),
        cmocka_unit_test_teardown(test_memory_admission, kill_strays),
        cmocka_unit_test_teardown(test_uploads_in_flight, kill_strays),
        cmocka_unit_test_teardown(test_cpu_budget, kill_strays),
    };
    /* MCF_TEST_FILTER=test_errors (a cmocka pattern) runs a subset. */
    if (getenv("MCF_TEST_FILTER") && *getenv("MCF_TEST_FILTER"))
        cmocka_set_test_filter(getenv("MCF_TEST_FILTER"));
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
