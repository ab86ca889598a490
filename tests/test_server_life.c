/* SPDX-License-Identifier: MIT */
/*
 * test_server_life.c - integration tests of mcfd's life: the SIGTERM
 * drain, the checkpoint of running jobs, cancels that survive a shutdown,
 * `mcfd --probe` and the configuration. A real daemon on loopback, as in
 * test_server.c; the helpers are srvlib.c's.
 */
#include "srvlib.h"

/* SIGTERM while a job runs: readyz 503, new work 503, the job finishes and
 * its client gets the mesh, the process exits 0; the log is JSON lines. */
typedef struct {
    const daemon_t *d;
    resp_t r;
} sync_client_t;

static void *sync_client(void *arg)
{
    sync_client_t *s = arg;
    upload_t up = {.mesh = "sphere_cgal.obj"};
    http(s->d, "POST", "/smooth?scheme=desbrun2&iterations=2500&dt=4e-6", NULL,
         &up, &s->r);
    return NULL;
}

static void *short_client(void *arg)
{
    sync_client_t *s = arg;
    upload_t up = {.mesh = "sphere_cgal.obj"};
    http(s->d, "POST", "/smooth?scheme=desbrun2&iterations=5", NULL, &up,
         &s->r);
    return NULL;
}

static void test_sigterm_drain(void **state)
{
    /* a drain timeout the running job meets also under TSan on a loaded
     * machine (2500 steps took over 25 s there; about 1 s in a normal
     * build): this test is about a drain that finishes the job */
    static const char *const flags[] = {"--workers", "1", "--log-level",
                                        "debug", "--drain-timeout", "120",
                                        NULL};
    daemon_t d;
    char spool[600];
    sync_client_t sc, qc;
    pthread_t th, qth;
    resp_t r;
    int st, requests = 0, jobs = 0;
    char queued_id[SRV_ID_BUF];
    char *log = NULL, *line, *save = NULL;
    size_t len;

    (void)state;
    snprintf(spool, sizeof spool, "%s/term", g_tmp);
    assert_int_equal(start_daemon(&d, "term", spool, flags), 0);
    memset(&sc, 0, sizeof sc);
    memset(&qc, 0, sizeof qc);
    sc.d = qc.d = &d;
    assert_int_equal(pthread_create(&th, NULL, sync_client, &sc), 0);
    wait_gauge(&d, "mcfd_workers_busy", 1);
    /* a second synchronous job waits in the queue behind it */
    assert_int_equal(pthread_create(&qth, NULL, short_client, &qc), 0);
    wait_gauge(&d, "mcfd_queue_depth", 1);
    kill(d.pid, SIGTERM);
    /* the queued job's client hears at once: 503, the job stays on disk */
    pthread_join(qth, NULL);
    expect_problem(&d, &qc.r, 503, "EDRAINING", "after the restart",
                   "queued sync job at SIGTERM");
    {
        cJSON *j = body_json(&qc.r, "queued sync job");
        snprintf(queued_id, sizeof queued_id, "%s", jstr(j, "job"));
        cJSON_Delete(j);
    }
    resp_free(&qc.r);
    sleep_ms(50);
    http(&d, "GET", "/readyz", NULL, NULL, &r);
    expect_problem(&d, &r, 503, "EDRAINING", NULL, "readyz while draining");
    resp_free(&r);
    http(&d, "GET", "/healthz", NULL, NULL, &r);
    expect_status(&d, &r, 200, "healthz while draining");
    resp_free(&r);
    {
        upload_t up = {.mesh = "sphere_cgal.obj"};
        http(&d, "POST", "/smooth", NULL, &up, &r);
        expect_problem(&d, &r, 503, "EDRAINING", NULL, "POST while draining");
        resp_free(&r);
    }
    pthread_join(th, NULL);
    expect_status(&d, &sc.r, 200, "the job running at SIGTERM");
    {
        api_format fmt;
        mcf_mesh *m = decode_body(&sc.r, &fmt);
        assert_int_equal(mcf_mesh_nvertices(m), 812);
        mcf_mesh_free(m);
    }
    resp_free(&sc.r);
    assert_true(wait_exit(d.pid, 150, &st));
    d.pid = 0;
    assert_true(WIFEXITED(st));
    assert_int_equal(WEXITSTATUS(st), 0);

    /* one JSON object per line, one per request and one per job */
    assert_int_equal(tl_read_file(d.log, &log, &len), 0);
    for (line = strtok_r(log, "\n", &save); line;
         line = strtok_r(NULL, "\n", &save)) {
        cJSON *j = cJSON_Parse(line);
        const char *type;
        if (!j)
            fail_msg("log line is not JSON: %s", line);
        type = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(j, "type"));
        requests += type && !strcmp(type, "request");
        jobs += type && !strcmp(type, "job");
        assert_non_null(cJSON_GetObjectItemCaseSensitive(j, "ts"));
        assert_non_null(cJSON_GetObjectItemCaseSensitive(j, "level"));
        cJSON_Delete(j);
    }
    /* at least the metrics poll, readyz, healthz and the three POSTs */
    assert_true(requests >= 6);
    assert_int_equal(jobs, 1);
    free(log);

    /* the restart runs the job that was queued at SIGTERM */
    assert_int_equal(start_daemon(&d, "term2", spool, flags), 0);
    {
        cJSON *j = poll_job(&d, queued_id, "succeeded", 30);
        assert_int_equal((int)jnum(j, "metrics.flow.steps"), 5);
        cJSON_Delete(j);
    }
    stop_daemon(&d);
}

/* --drain-timeout: a job still running then is checkpointed back to
 * `queued`, its ndjson follower gets a final line saying so, the process
 * exits 0, and the restart runs the job again under the same ID. */
typedef struct {
    const daemon_t *d;
    resp_t r;
} stream_client_t;

static void *long_stream_client(void *arg)
{
    stream_client_t *s = arg;
    upload_t up = {.mesh = "sphere_cgal.obj"};
    http(s->d, "POST", "/smooth?iterations=100000&dt=1e-7&max_steps=100000&stream=ndjson", NULL,
         &up, &s->r);
    return NULL;
}

static void test_drain_checkpoint(void **state)
{
    static const char *const flags[] = {"--workers", "1", "--drain-timeout",
                                        "0.3", NULL};
    daemon_t d;
    char spool[600], id[64], path[160];
    stream_client_t sc;
    pthread_t th;
    const char *last;
    cJSON *j;
    resp_t r;

    (void)state;
    snprintf(spool, sizeof spool, "%s/checkpoint", g_tmp);
    assert_int_equal(start_daemon(&d, "ckpt", spool, flags), 0);
    memset(&sc, 0, sizeof sc);
    sc.d = &d;
    assert_int_equal(pthread_create(&th, NULL, long_stream_client, &sc), 0);
    wait_gauge(&d, "mcfd_workers_busy", 1);
    sleep_ms(100);
    stop_daemon(&d); /* SIGTERM, exit 0 well before the job could finish */
    pthread_join(th, NULL);
    expect_status(&d, &sc.r, 200, "stream at checkpoint");
    assert_non_null(header(&sc.r, "X-Job-Id", id, sizeof id));
    assert_true(sc.r.body.len > 0 &&
                sc.r.body.data[sc.r.body.len - 1] == '\n');
    sc.r.body.data[sc.r.body.len - 1] = '\0';
    last = strrchr(sc.r.body.data, '\n');
    last = last ? last + 1 : sc.r.body.data;
    j = cJSON_Parse(last);
    assert_non_null(j);
    assert_false(cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(j, "done")));
    assert_string_equal(jstr(j, "status"), "queued");
    assert_string_equal(jstr(cJSON_GetObjectItemCaseSensitive(j, "error"), "code"),
                        "EDRAINING");
    cJSON_Delete(j);
    resp_free(&sc.r);

    assert_int_equal(start_daemon(&d, "ckpt2", spool, flags), 0);
    wait_running(&d, id);
    snprintf(path, sizeof path, "/v1/jobs/%s", id);
    http(&d, "DELETE", path, NULL, NULL, &r);
    expect_status(&d, &r, 202, "cancel the re-run job");
    resp_free(&r);
    j = poll_job(&d, id, "canceled", 10);
    cJSON_Delete(j);
    stop_daemon(&d);
}

/* Issue 9 item 7: DELETE a running job, then SIGTERM while its current
 * step (richardson on the armadillo, about 0.3 s) outlasts --drain-timeout
 * 0.02: the checkpoint used to overwrite the cancel, and the job ran again
 * after the restart. It stays canceled. */
static void test_cancel_survives_shutdown(void **state)
{
    static const char *const flags[] = {"--workers", "1", "--drain-timeout",
                                        "0.02", NULL};
    upload_t up = {.mesh = "armadillo.obj"};
    daemon_t d;
    char spool[600], id[SRV_ID_BUF], path[160];
    cJSON *j;
    resp_t r;

    (void)state;
    snprintf(spool, sizeof spool, "%s/cancel-term", g_tmp);
    assert_int_equal(start_daemon(&d, "cancel-term", spool, flags), 0);
    http(&d, "POST", "/v1/jobs?scheme=richardson&iterations=1000", NULL, &up, &r);
    expect_status(&d, &r, 202, "submit the armadillo");
    j = body_json(&r, "submit");
    snprintf(id, sizeof id, "%s", jstr(j, "id"));
    cJSON_Delete(j);
    resp_free(&r);
    wait_running(&d, id);
    snprintf(path, sizeof path, "/v1/jobs/%s", id);
    http(&d, "DELETE", path, NULL, NULL, &r);
    expect_status(&d, &r, 202, "DELETE the running job");
    resp_free(&r);
    stop_daemon(&d); /* SIGTERM at once: the step is still running */

    assert_int_equal(start_daemon(&d, "cancel-term2", spool, flags), 0);
    j = poll_job(&d, id, NULL, 5);
    if (strcmp(jstr(j, "status"), "canceled") != 0)
        fail_msg("after the restart job %s is %s, not canceled", id,
                 jstr(j, "status"));
    assert_string_equal(jstr(cJSON_GetObjectItemCaseSensitive(j, "error"),
                             "code"), "ECANCELED");
    cJSON_Delete(j);
    wait_gauge_within(&d, "mcfd_workers_busy", 0, 1, "nothing runs again");
    stop_daemon(&d);
}

/* mcfd --probe: 0 against a live daemon, 1 against a closed port. */
static int run_probe(int port)
{
    char p[16];
    pid_t pid;
    int st = 0;

    snprintf(p, sizeof p, "%d", port);
    pid = fork();
    if (pid == 0) {
        int nul = open("/dev/null", O_WRONLY);
        dup2(nul, 1);
        dup2(nul, 2);
        execl(g_bin, g_bin, "--probe", "--bind", "127.0.0.1", "--port", p,
              (char *)NULL);
        _exit(127);
    }
    if (!wait_exit(pid, 15, &st)) {
        kill(pid, SIGKILL);
        waitpid(pid, NULL, 0);
        return -1;
    }
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

static void test_probe(void **state)
{
    struct sockaddr_in sa;
    socklen_t sl = sizeof sa;
    int fd, closed_port;

    (void)state;
    assert_int_equal(run_probe(g_main.port), 0);
    /* a port nobody listens on: bind one, note it, close it */
    fd = socket(AF_INET, SOCK_STREAM, 0);
    memset(&sa, 0, sizeof sa);
    sa.sin_family = AF_INET;
    sa.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    assert_int_equal(bind(fd, (struct sockaddr *)&sa, sizeof sa), 0);
    assert_int_equal(getsockname(fd, (struct sockaddr *)&sa, &sl), 0);
    closed_port = ntohs(sa.sin_port);
    close(fd);
    assert_int_equal(run_probe(closed_port), 1);
}

/* Runs mcfd with argv (and the current environment); returns the exit
 * status and the first bytes of stderr in err. */
static int run_mcfd(const char *const *args, char *err, size_t errsize)
{
    const char *argv[16];
    int pfd[2], n = 0, st = 0;
    size_t got = 0;
    pid_t pid;

    argv[n++] = g_bin;
    while (*args && n < 15)
        argv[n++] = *args++;
    argv[n] = NULL;
    if (pipe(pfd) != 0)
        return -1;
    pid = fork();
    if (pid == 0) {
        int nul = open("/dev/null", O_WRONLY);
        dup2(nul, 1);
        dup2(pfd[1], 2);
        close(pfd[0]);
        close(pfd[1]);
        execv(g_bin, (char *const *)(uintptr_t)argv);
        _exit(127);
    }
    close(pfd[1]);
    for (;;) {
        struct pollfd p = {pfd[0], POLLIN, 0};
        ssize_t r;
        if (poll(&p, 1, 10000) <= 0)
            break;
        r = read(pfd[0], err + got, errsize - 1 - got);
        if (r <= 0)
            break;
        got += (size_t)r;
        if (got == errsize - 1)
            break;
    }
    err[got] = '\0';
    close(pfd[0]);
    if (!wait_exit(pid, 15, &st)) {
        kill(pid, SIGKILL);
        waitpid(pid, NULL, 0);
        return -1;
    }
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

/* Flags win over MCFD_* variables; bad values stop the start with exit
 * status 2 and a message naming the flag or variable. */
static void test_config(void **state)
{
    static const char *const flags[] = {"--queue", "7", NULL};
    daemon_t d;
    char spool[600], err[1024];
    resp_t r;

    (void)state;
    snprintf(spool, sizeof spool, "%s/config", g_tmp);
    setenv("MCFD_WORKERS", "3", 1);
    setenv("MCFD_QUEUE", "5", 1);
    setenv("MCFD_MAX_UPLOAD", "1K", 1);
    assert_int_equal(start_daemon(&d, "config", spool, flags), 0);
    unsetenv("MCFD_WORKERS");
    unsetenv("MCFD_QUEUE");
    unsetenv("MCFD_MAX_UPLOAD");
    http(&d, "GET", "/metrics", NULL, NULL, &r);
    expect_status(&d, &r, 200, "metrics");
    assert_true(metric(r.body.data, "mcfd_workers") == 3);        /* env */
    assert_true(metric(r.body.data, "mcfd_queue_capacity") == 7); /* flag */
    resp_free(&r);
    {
        upload_t up = {.mesh = "sphere_cgal.obj"}; /* 72 KB > 1K */
        http(&d, "POST", "/smooth", NULL, &up, &r);
        expect_problem(&d, &r, 413, "ELIMIT", "1024", "MCFD_MAX_UPLOAD");
        resp_free(&r);
    }
    stop_daemon(&d);

    {
        static const char *const a[] = {"--port", "70000", NULL};
        assert_int_equal(run_mcfd(a, err, sizeof err), 2);
        assert_non_null(strstr(err, "--port"));
    }
    {
        static const char *const a[] = {"--no-such-flag", NULL};
        assert_int_equal(run_mcfd(a, err, sizeof err), 2);
        assert_non_null(strstr(err, "--no-such-flag"));
    }
    {
        static const char *const a[] = {"--help", NULL};
        setenv("MCFD_LOG_LEVEL", "loud", 1);
        assert_int_equal(run_mcfd(a, err, sizeof err), 2);
        assert_non_null(strstr(err, "MCFD_LOG_LEVEL"));
        unsetenv("MCFD_LOG_LEVEL");
        assert_int_equal(run_mcfd(a, err, sizeof err), 0);
    }
    {
        char tok[600];
        const char *a[] = {"--token-file", tok, NULL};
        snprintf(tok, sizeof tok, "%s/no-such-token", g_tmp);
        assert_int_equal(run_mcfd(a, err, sizeof err), 2);
        assert_non_null(strstr(err, "no-such-token"));
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_teardown(test_sigterm_drain, kill_strays),
        cmocka_unit_test_teardown(test_drain_checkpoint, kill_strays),
        cmocka_unit_test_teardown(test_cancel_survives_shutdown, kill_strays),
        cmocka_unit_test_teardown(test_probe, kill_strays),
        cmocka_unit_test_teardown(test_config, kill_strays),
    };
    /* MCF_TEST_FILTER=test_errors (a cmocka pattern) runs a subset. */
    if (getenv("MCF_TEST_FILTER") && *getenv("MCF_TEST_FILTER"))
        cmocka_set_test_filter(getenv("MCF_TEST_FILTER"));
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
