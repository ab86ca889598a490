/* SPDX-License-Identifier: MIT */
/*
 * test_service.c - the job service (server/service.h) driven in-process,
 * with no door: two service objects at once, each with its own temporary
 * spool, through submit, cancel, drain and checkpoint, recovery after a
 * simulated crash, the spool quota and admission. The doors' behaviour
 * over HTTP and gRPC is test_server's and test_grpc's.
 *
 * The meshes are made here: a small grid with a bump (a job of a few
 * steps finishes in milliseconds) and the same grid run for 100,000
 * steps (a job that runs until it is stopped; the test never waits for
 * it to end by itself). The CPU budget counts a job's threads
 * (test_cpu_budget_counts_job_threads); the job timeout grows with the
 * job's memory estimate (test_job_timeout_grows_with_estimate); the
 * workers share the cores without oversubscribing them
 * (test_cores_shared).
 */
#include <errno.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <cmocka.h>

#include "sandbox.h"
#include "service.h"
#include "srv.h"
#include "testlib.h"

/* Wait bounds: hang guards only (a job of a few steps takes
 * milliseconds; under sanitizers on a loaded machine, seconds). */
#define WAIT_S 120.0

/* ---------------------------------------------------------------- helpers */

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void nap(void)
{
    struct timespec ts = {0, 10 * 1000 * 1000};
    nanosleep(&ts, NULL);
}

/* An n x n grid of the unit square with a bump, as OBJ text. */
static char *grid_obj(int n, size_t *len)
{
    const double pi = 3.14159265358979323846;
    api_buf b;
    int i, k;

    api_buf_init(&b, 0);
    for (k = 0; k < n; k++)
        for (i = 0; i < n; i++) {
            double x = (double)i / (n - 1), y = (double)k / (n - 1);
            assert_int_equal(api_buf_printf(&b, "v %.17g %.17g %.17g\n", x, y,
                                            0.2 * sin(pi * x) * sin(pi * y)),
                             MCF_OK);
        }
    for (k = 0; k + 1 < n; k++)
        for (i = 0; i + 1 < n; i++) {
            int a = k * n + i + 1, c = a + n;
            assert_int_equal(api_buf_printf(&b, "f %d %d %d\nf %d %d %d\n", a,
                                            a + 1, c + 1, a, c + 1, c),
                             MCF_OK);
        }
    return api_buf_detach(&b, len);
}

typedef struct {
    char dir[64];              /* the spool */
    svc_t *svc;
    svc_config cfg;
} svc_fixture;

static void config_init(svc_config *c, const char *spool)
{
    memset(c, 0, sizeof *c);
    c->workers = 1;
    c->queue = 8;
    snprintf(c->spool, sizeof c->spool, "%s", spool);
    c->spool_max_bytes = (size_t)1 << 30;
    api_limits_default(&c->lim);
    c->result_ttl = 3600;
    c->max_memory = (size_t)2 << 30;
    c->max_job_memory = (size_t)1 << 30;
    c->decode_cpu = API_DECODE_CPU_S;
    c->decode_memory = API_DECODE_MEMORY;
}

/* A service on a new temporary spool. */
static void fixture_start(svc_fixture *f, void (*tune)(svc_config *))
{
    char msg[256] = "";

    snprintf(f->dir, sizeof f->dir, "/tmp/mcfd-svc-XXXXXX");
    assert_non_null(mkdtemp(f->dir));
    config_init(&f->cfg, f->dir);
    if (tune)
        tune(&f->cfg);
    if (svc_start(&f->cfg, &f->svc, msg, sizeof msg) != 0)
        fail_msg("svc_start: %s", msg);
}

/* The same spool again, as a restart would find it. */
static void fixture_restart(svc_fixture *f)
{
    char msg[256] = "";

    svc_stop(f->svc);
    f->svc = NULL;
    if (svc_start(&f->cfg, &f->svc, msg, sizeof msg) != 0)
        fail_msg("svc_start again: %s", msg);
}

static void fixture_stop(svc_fixture *f)
{
    char cmd[128];

    svc_stop(f->svc);
    f->svc = NULL;
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", f->dir);
    assert_int_equal(system(cmd), 0);
}

/* Submits the grid with parameters (a JSON object): 0 and *out, or -1 and
 * *err. */
static int submit(svc_t *s, int n, const char *params, svc_job **out,
                  svc_error *err)
{
    svc_request rq;
    mcf_error me;
    mcf_status rc;

    svc_request_init(&rq);
    rc = api_params_parse_request(&rq.params, params, NULL, NULL, NULL, svc_limits(s), &me);
    if (rc != MCF_OK)
        fail_msg("parameters %s: %s", params, me.msg);
    rq.input = grid_obj(n, &rq.input_len);
    snprintf(rq.filename, sizeof rq.filename, "grid.obj");
    return svc_submit(s, &rq, out, err);
}

static svc_job *submit_ok(svc_t *s, int n, const char *params)
{
    svc_job *j = NULL;
    svc_error e;

    if (submit(s, n, params, &j, &e) != 0)
        fail_msg("submit %s: %s %s", params, svc_problem_name(e.problem), e.detail);
    return j;
}

/* A job that runs until it is stopped. */
#define LONG_JOB "{\"scheme\":\"desbrun2\",\"iterations\":100000}"
#define SHORT_JOB "{\"scheme\":\"desbrun2\",\"iterations\":3}"

/* Waits until pred(snapshot) holds; returns the snapshot. */
static svc_snap wait_for(svc_job *j, int (*pred)(const svc_snap *),
                         const char *what)
{
    double end = now_s() + WAIT_S;
    svc_snap s;

    for (;;) {
        svc_job_snapshot(j, &s);
        if (pred(&s))
            return s;
        if (now_s() > end)
            fail_msg("job %s: not %s within %g s (status %s, step %d)",
                     svc_job_id(j), what, WAIT_S, svc_job_status_name(s.status),
                     s.step);
        nap();
    }
}

static int is_terminal(const svc_snap *s)
{
    return svc_job_status_terminal(s->status);
}

/* Running and past its first step (decoded, in its flow). */
static int is_stepping(const svc_snap *s)
{
    return s->status == SVC_JOB_RUNNING && s->step > 0;
}

static int file_exists(const char *dir, const char *id, const char *name)
{
    char path[512];
    struct stat st;

    snprintf(path, sizeof path, "%s/jobs/%s/%s", dir, id, name);
    return stat(path, &st) == 0;
}

static void write_file(const char *path, const char *text)
{
    FILE *fp = fopen(path, "w");
    assert_non_null(fp);
    assert_int_equal(fputs(text, fp) >= 0, 1);
    assert_int_equal(fclose(fp), 0);
}

/* ------------------------------------------------------------------ tests */

/* Two services in one process, each with its own spool and workers: a job
 * of each runs to its result; neither knows the other's jobs. */
static void test_two_services(void **state)
{
    svc_fixture a, b;
    svc_job *ja, *jb;
    svc_snap s;
    char *data = NULL, *metrics = NULL;
    size_t len = 0, mlen = 0;
    svc_error e;

    (void)state;
    fixture_start(&a, NULL);
    fixture_start(&b, NULL);
    ja = submit_ok(a.svc, 8, SHORT_JOB);
    jb = submit_ok(b.svc, 9, "{\"scheme\":\"taubin\",\"iterations\":2,"
                            "\"format\":\"ply\"}");
    assert_string_not_equal(svc_job_id(ja), svc_job_id(jb));
    assert_null(svc_job_get(b.svc, svc_job_id(ja)));
    assert_null(svc_job_get(a.svc, svc_job_id(jb)));

    s = wait_for(ja, is_terminal, "finished");
    assert_int_equal(s.status, SVC_JOB_SUCCEEDED);
    assert_int_equal(s.step, 3);
    assert_string_equal(s.in_format, "obj");
    assert_string_equal(s.result_name, "result.obj");
    s = wait_for(jb, is_terminal, "finished");
    assert_int_equal(s.status, SVC_JOB_SUCCEEDED);
    assert_string_equal(s.out_format, "ply");

    /* each result is in its own service's spool, not the other's */
    assert_true(file_exists(a.dir, svc_job_id(ja), "result.obj"));
    assert_false(file_exists(b.dir, svc_job_id(ja), "result.obj"));
    assert_true(file_exists(b.dir, svc_job_id(jb), "result.ply"));
    assert_int_equal(svc_job_result(jb, 0, &data, &len, &e), 0);
    assert_true(len > 0 && strncmp(data, "ply", 3) == 0);
    /* the metrics document names the job and the upload */
    assert_int_equal(svc_job_metrics(ja, &metrics, &mlen, &e), 0);
    assert_non_null(strstr(metrics, svc_job_id(ja)));
    assert_non_null(strstr(metrics, "\"path\":\"grid.obj\""));
    free(data);
    free(metrics);

    /* the gauges are each service's */
    assert_int_equal(svc_get_gauges(a.svc).jobs_in_memory, 1);
    assert_int_equal(svc_get_gauges(b.svc).jobs_in_memory, 1);
    svc_job_unref(ja);
    svc_job_unref(jb);
    fixture_stop(&a);
    fixture_stop(&b);
}

/* Cancel: a queued job at once (1, then 0: already), a running one at its
 * next step; a finished one is forgotten by svc_delete (memory and spool). */
static void test_cancel(void **state)
{
    svc_fixture f;
    svc_job *run, *queued, *done;
    svc_delete_result res;
    svc_job_status before;
    svc_snap s;
    svc_error e;
    char id[SVC_ID_LEN + 1];

    (void)state;
    fixture_start(&f, NULL);
    run = submit_ok(f.svc, 20, LONG_JOB);
    wait_for(run, is_stepping, "stepping");
    queued = submit_ok(f.svc, 8, SHORT_JOB);  /* one worker: it waits */
    svc_job_snapshot(queued, &s);
    assert_int_equal(s.status, SVC_JOB_QUEUED);

    assert_int_equal(svc_cancel(queued, SVC_CANCEL_USER), 1);
    svc_job_snapshot(queued, &s);
    assert_int_equal(s.status, SVC_JOB_CANCELED);
    assert_int_equal(s.error.problem, SVC_P_CANCELED);
    assert_int_equal(svc_cancel(queued, SVC_CANCEL_USER), 0);

    assert_int_equal(svc_cancel(run, SVC_CANCEL_USER), 1);
    s = wait_for(run, is_terminal, "canceled");
    assert_int_equal(s.status, SVC_JOB_CANCELED);
    assert_int_equal(s.error.cancel, SVC_CANCEL_USER);
    assert_non_null(strstr(s.error.detail, "after step"));
    assert_true(s.step > 0 && s.step < 100000);

    /* the worker is free again: a new job runs to its end */
    done = submit_ok(f.svc, 8, SHORT_JOB);
    s = wait_for(done, is_terminal, "finished");
    assert_int_equal(s.status, SVC_JOB_SUCCEEDED);
    snprintf(id, sizeof id, "%s", svc_job_id(done));
    assert_int_equal(svc_delete(f.svc, id, &res, &before, &e), 0);
    assert_int_equal(res, SVC_DELETE_FORGOTTEN);
    assert_int_equal(before, SVC_JOB_SUCCEEDED);
    assert_null(svc_job_get(f.svc, id));
    assert_false(file_exists(f.dir, id, "state.json"));
    assert_int_equal(svc_delete(f.svc, id, &res, &before, &e), -1);
    assert_int_equal(e.problem, SVC_P_NOT_FOUND);

    svc_job_unref(run);
    svc_job_unref(queued);
    svc_job_unref(done);
    fixture_stop(&f);
}

/* Drain: new jobs refused (EDRAINING) while the running one goes on; past
 * the drain's patience it is checkpointed back to queued, and the next
 * start on the same spool runs it again under its ID. */
static void test_drain_and_restart(void **state)
{
    svc_fixture f;
    svc_job *run, *other, *again;
    svc_error e;
    svc_snap s;
    char id[SVC_ID_LEN + 1];

    (void)state;
    fixture_start(&f, NULL);
    run = submit_ok(f.svc, 20, LONG_JOB);
    snprintf(id, sizeof id, "%s", svc_job_id(run));
    wait_for(run, is_stepping, "stepping");

    svc_drain(f.svc);
    assert_true(svc_draining(f.svc));
    assert_false(svc_can_accept(f.svc));
    other = NULL;
    assert_int_equal(submit(f.svc, 8, SHORT_JOB, &other, &e), -1);
    assert_null(other);
    assert_int_equal(e.problem, SVC_P_DRAINING);
    assert_true(e.retry_after > 0);
    assert_int_equal(svc_wait_idle(f.svc, 0.2), 0); /* it still runs */

    svc_checkpoint_running(f.svc);
    assert_int_equal(svc_wait_idle(f.svc, WAIT_S), 1);
    svc_job_snapshot(run, &s);
    assert_int_equal(s.status, SVC_JOB_QUEUED);
    svc_job_unref(run);

    fixture_restart(&f);
    again = svc_job_get(f.svc, id);
    assert_non_null(again);
    s = wait_for(again, is_stepping, "running again");
    assert_int_equal(s.recovered, 1);
    assert_int_equal(svc_cancel(again, SVC_CANCEL_USER), 1);
    s = wait_for(again, is_terminal, "canceled");
    assert_int_equal(s.status, SVC_JOB_CANCELED);
    svc_job_unref(again);
    fixture_stop(&f);
}

/* Recovery after a crash: the spool as a process killed mid-run leaves it
 * (a copy of a running job's files, taken while it ran, next to a finished
 * job's), plus a job a crash cut short before it was acknowledged (no
 * state.json) and one whose state.json is damaged. A second service on
 * that copy, beside the first: the finished job is served again, the
 * running one runs again under its ID, the unacknowledged one is removed
 * and the damaged one quarantined. */
static void test_recovery_after_crash(void **state)
{
    svc_fixture a, b;
    svc_job *run, *done, *j;
    svc_snap s;
    char cmd[512], path[512], *data = NULL;
    size_t len = 0;
    svc_error e;
    char rid[SVC_ID_LEN + 1], did[SVC_ID_LEN + 1];
    const char *lost = "00112233445566778899aabbccddeeff",
               *bad = "ffeeddccbbaa99887766554433221100";
    struct stat st;

    (void)state;
    assert_int_equal((int)strlen(lost), SVC_ID_LEN);
    fixture_start(&a, NULL);
    fixture_start(&b, NULL);
    done = submit_ok(a.svc, 8, SHORT_JOB);
    wait_for(done, is_terminal, "finished");
    snprintf(did, sizeof did, "%s", svc_job_id(done));
    run = submit_ok(a.svc, 20, LONG_JOB);
    snprintf(rid, sizeof rid, "%s", svc_job_id(run));
    wait_for(run, is_stepping, "stepping");

    /* the crash: b's spool becomes a's disk as it is now */
    svc_stop(b.svc);
    b.svc = NULL;
    snprintf(cmd, sizeof cmd, "rm -rf '%s/jobs' && cp -a '%s/jobs' '%s/jobs'",
             b.dir, a.dir, b.dir);
    assert_int_equal(system(cmd), 0);
    snprintf(path, sizeof path, "%s/jobs/%s", b.dir, lost);
    assert_int_equal(mkdir(path, 0700), 0);
    snprintf(path, sizeof path, "%s/jobs/%s/input", b.dir, lost);
    write_file(path, "v 0 0 0\n");
    snprintf(path, sizeof path, "%s/jobs/%s", b.dir, bad);
    assert_int_equal(mkdir(path, 0700), 0);
    snprintf(path, sizeof path, "%s/jobs/%s/request.json", b.dir, bad);
    write_file(path, "{}");
    snprintf(path, sizeof path, "%s/jobs/%s/state.json", b.dir, bad);
    write_file(path, "{\"status\": \"succ");
    fixture_restart(&b);

    /* a goes on meanwhile: its job is its own */
    svc_job_snapshot(run, &s);
    assert_int_equal(s.status, SVC_JOB_RUNNING);
    assert_int_equal(svc_cancel(run, SVC_CANCEL_USER), 1);

    j = svc_job_get(b.svc, did);
    assert_non_null(j);
    svc_job_snapshot(j, &s);
    assert_int_equal(s.status, SVC_JOB_SUCCEEDED);
    assert_int_equal(s.recovered, 1);
    assert_int_equal(svc_job_result(j, 0, &data, &len, &e), 0);
    assert_true(len > 0);
    free(data);
    svc_job_unref(j);

    j = svc_job_get(b.svc, rid);
    assert_non_null(j);
    s = wait_for(j, is_stepping, "running again");
    assert_int_equal(s.recovered, 1);
    assert_int_equal(svc_cancel(j, SVC_CANCEL_USER), 1);
    wait_for(j, is_terminal, "canceled");
    svc_job_unref(j);

    assert_null(svc_job_get(b.svc, lost));
    snprintf(path, sizeof path, "%s/jobs/%s", b.dir, lost);
    assert_int_equal(stat(path, &st), -1);
    assert_null(svc_job_get(b.svc, bad));
    snprintf(path, sizeof path, "%s/quarantine/%s/state.json", b.dir, bad);
    assert_int_equal(stat(path, &st), 0);

    wait_for(run, is_terminal, "canceled");
    svc_job_unref(run);
    svc_job_unref(done);
    fixture_stop(&a);
    fixture_stop(&b);
}

static void two_jobs_kept(svc_config *c)
{
    c->spool_max_jobs = 2;
}

/* The spool quota: jobs kept count until they are deleted (EQUOTA, with a
 * retry delay); a DELETE makes room. */
static void test_quota(void **state)
{
    svc_fixture f;
    svc_job *j1, *j2, *j3 = NULL;
    svc_delete_result res;
    svc_job_status before;
    svc_error e;

    (void)state;
    fixture_start(&f, two_jobs_kept);
    j1 = submit_ok(f.svc, 8, SHORT_JOB);
    j2 = submit_ok(f.svc, 8, SHORT_JOB);
    wait_for(j1, is_terminal, "finished");
    wait_for(j2, is_terminal, "finished");
    assert_int_equal(submit(f.svc, 8, SHORT_JOB, &j3, &e), -1);
    assert_int_equal(e.problem, SVC_P_SPOOL_FULL);
    assert_int_equal(svc_problem_http(e.problem), 503);
    assert_true(e.retry_after > 0);
    assert_non_null(strstr(e.detail, "--spool-max-jobs 2"));

    assert_int_equal(svc_delete(f.svc, svc_job_id(j1), &res, &before, &e), 0);
    assert_int_equal(res, SVC_DELETE_FORGOTTEN);
    j3 = submit_ok(f.svc, 8, SHORT_JOB);
    wait_for(j3, is_terminal, "finished");
    svc_job_unref(j1);
    svc_job_unref(j2);
    svc_job_unref(j3);
    fixture_stop(&f);
}

static void small_queue(svc_config *c)
{
    c->queue = 1;
    c->max_job_memory = (size_t)64 << 20;
}

/* Admission: one worker and one queue place hold two jobs, the third is
 * refused EBUSY until one leaves; a job whose estimated memory alone
 * passes --max-job-memory is refused at once, also when there is room;
 * parameters whose step count passes max_iterations are the request's
 * fault. */
static void test_admission(void **state)
{
    svc_fixture f;
    svc_job *run, *queued, *next = NULL;
    svc_error e;

    (void)state;
    fixture_start(&f, small_queue);
    run = submit_ok(f.svc, 20, LONG_JOB);
    wait_for(run, is_stepping, "stepping");
    queued = submit_ok(f.svc, 8, SHORT_JOB);
    assert_false(svc_can_accept(f.svc));
    assert_int_equal(submit(f.svc, 8, SHORT_JOB, &next, &e), -1);
    assert_int_equal(e.problem, SVC_P_BUSY);
    assert_true(e.retry_after > 0);

    assert_int_equal(svc_cancel(queued, SVC_CANCEL_USER), 1);
    next = submit_ok(f.svc, 8, SHORT_JOB);
    svc_job_unref(next);
    next = NULL;

    /* 350 x 350 vertices with the 100,000-step log: over 64 MiB */
    assert_int_equal(submit(f.svc, 350, LONG_JOB, &next, &e), -1);
    assert_int_equal(e.problem, SVC_P_MESH_LIMIT);
    assert_non_null(strstr(e.detail, "max-job-memory"));
    assert_int_equal(submit(f.svc, 8, "{\"scheme\":\"desbrun2\",\"time\":1,"
                                      "\"dt\":1e-6}", &next, &e), -1);
    assert_int_equal(e.problem, SVC_P_PARAM_LIMIT);

    assert_int_equal(svc_cancel(run, SVC_CANCEL_USER), 1);
    wait_for(run, is_terminal, "canceled");
    svc_job_unref(run);
    svc_job_unref(queued);
    fixture_stop(&f);
}

/* The per-job CPU budget (issue 28) counts the threads a job's flow
 * starts (mcf_flow_params.threads: the explicit passes), not only the
 * worker's thread that runs it. 2,000 explicit passes over a 200 x 200
 * grid (40,000 vertices, over MCF_PAR_MIN; about 15 s of CPU in all on 8
 * threads, two thirds of it the worker's: the step's area and log) under
 * a budget of 1.5 s: the job is stopped at the step where its worker's
 * thread and its threads together passed the budget, its worker's share
 * then still under it (measured about 0.77 of the whole, so 1.15 s; the
 * decode and set-up before the first step, all the worker's, are 0.1-0.2
 * s, more under sanitizers, hence a budget well above them). Counting
 * the worker's thread alone (before), a stop can only come with that
 * share over the budget. No time bound: the shares are the job's own CPU
 * clocks at one step. */
static void cpu_budget_config(svc_config *c)
{
    c->cores = 8;
    c->job_cpu = 1.5;
    c->job_cpu_per_mib = 0;
}

static void test_cpu_budget_counts_job_threads(void **state)
{
    svc_fixture f;
    svc_job *j;
    svc_snap s;

    (void)state;
    fixture_start(&f, cpu_budget_config);
    j = submit_ok(f.svc, 200, "{\"scheme\":\"fairing_explicit\",\"iterations\":2000}");
    s = wait_for(j, is_terminal, "finished");
    print_message("    2,000 passes on 8 threads under a CPU budget of 1.5 s: %s at step %d, "
                  "%.3f s of CPU, %.3f s of it on the job's threads\n",
                  svc_job_status_name(s.status), s.step, s.cpu_s, s.cpu_threads_s);
    assert_int_equal(s.status, SVC_JOB_FAILED);
    assert_non_null(strstr(s.error.detail, "CPU budget"));
    assert_true(s.step < 2000);
    assert_true(s.cpu_s > 1.5);
    assert_true(s.cpu_threads_s > 0);
    assert_true(s.cpu_s - s.cpu_threads_s < 1.5); /* the worker's share */
    svc_job_unref(j);
    fixture_stop(&f);
}

/* The cores (svc_config.cores, workers.c): two workers sharing two
 * cores. A lone job of 22,500 vertices (over MCF_THREADS_MIN) holds both
 * once its flow starts; a job submitted meanwhile waits queued (no core is
 * free, though a worker is), then runs when the first ends, on one core
 * when small (100 vertices); a big job starting beside it gets the one
 * core left, never a third. The cores held are read from snapshots taken
 * while the jobs step; the only wait on time is the queued job's 0.3 s,
 * which can only fail to catch a wrong start, never fail a right one. */
static void two_cores(svc_config *c)
{
    c->workers = 2;
    c->cores = 2;
}

static void test_cores_shared(void **state)
{
    svc_fixture f;
    svc_job *big, *small, *beside;
    svc_snap s;
    int i;

    (void)state;
    fixture_start(&f, two_cores);
    big = submit_ok(f.svc, 150, LONG_JOB);
    s = wait_for(big, is_stepping, "stepping");
    assert_int_equal(s.cores, 2);
    small = submit_ok(f.svc, 10, LONG_JOB);
    for (i = 0; i < 30; i++) {
        svc_job_snapshot(small, &s);
        assert_int_equal(s.status, SVC_JOB_QUEUED);
        nap();
    }
    assert_int_equal(svc_cancel(big, SVC_CANCEL_USER), 1);
    wait_for(big, is_terminal, "canceled");
    s = wait_for(small, is_stepping, "stepping");
    assert_int_equal(s.cores, 1);
    beside = submit_ok(f.svc, 150, LONG_JOB);
    s = wait_for(beside, is_stepping, "stepping");
    assert_int_equal(s.cores, 1);
    svc_job_snapshot(small, &s);
    assert_int_equal(s.cores, 1);
    assert_int_equal(svc_cancel(small, SVC_CANCEL_USER), 1);
    assert_int_equal(svc_cancel(beside, SVC_CANCEL_USER), 1);
    wait_for(small, is_terminal, "canceled");
    wait_for(beside, is_terminal, "canceled");
    svc_job_unref(big);
    svc_job_unref(small);
    svc_job_unref(beside);
    fixture_stop(&f);
}

/* The default job timeout grows with the job (issue 27: 10 minutes were
 * 584 s of a 7M-vertex scan's flow on a loaded machine): its deadline is
 * job_timeout + job_timeout_per_mib x the memory estimate in MiB. With no
 * slope, 0.05 s stops a job that runs until it is stopped, and the
 * detail gives the sum; with 1,000 s per MiB, a job of 50 implicit steps
 * on 3,600 vertices (0.5-2 s on a loaded machine, more under sanitizers) ends by
 * itself under the same 0.05 s. Only the first part depends on time, and
 * only on the job never ending by itself; the second asserts success and
 * states how long the job ran (when it ran under 0.05 s the case proves
 * nothing, and says so). */
static void no_slope(svc_config *c)
{
    c->job_timeout = 0.05;
    c->job_timeout_per_mib = 0;
}

static void big_slope(svc_config *c)
{
    c->job_timeout = 0.05;
    c->job_timeout_per_mib = 1000;
}

static void test_job_timeout_grows_with_estimate(void **state)
{
    svc_fixture f;
    svc_job *j;
    svc_snap s;

    (void)state;
    fixture_start(&f, no_slope);
    j = submit_ok(f.svc, 8, LONG_JOB);
    s = wait_for(j, is_terminal, "finished");
    print_message("    --job-timeout 0.05 s, no slope: %s\n", s.error.detail);
    assert_int_equal(s.status, SVC_JOB_FAILED);
    assert_non_null(strstr(s.error.detail, "timeout, 0.05 s (--job-timeout "
                                           "0.05 s + 0 s per MiB"));
    svc_job_unref(j);
    fixture_stop(&f);

    fixture_start(&f, big_slope);
    j = submit_ok(f.svc, 60, "{\"scheme\":\"desbrun2\",\"iterations\":50}");
    s = wait_for(j, is_terminal, "finished");
    print_message("    --job-timeout 0.05 s + 1000 s per MiB: %s after %.3f s%s\n",
                  svc_job_status_name(s.status), s.finished - s.started,
                  s.finished - s.started > 0.05 ? "" : " (under 0.05 s: proves nothing)");
    if (s.status != SVC_JOB_SUCCEEDED)
        fail_msg("job failed: %s", s.error.detail);
    svc_job_unref(j);
    fixture_stop(&f);
}

int main(int argc, char **argv)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_two_services),
        cmocka_unit_test(test_cancel),
        cmocka_unit_test(test_drain_and_restart),
        cmocka_unit_test(test_recovery_after_crash),
        cmocka_unit_test(test_quota),
        cmocka_unit_test(test_admission),
        cmocka_unit_test(test_cpu_budget_counts_job_threads),
        cmocka_unit_test(test_job_timeout_grows_with_estimate),
        cmocka_unit_test(test_cores_shared),
    };

    /* a Draco input's decode runs in a child of this program (sandbox.c) */
    if (argc > 1 && strcmp(argv[1], SANDBOX_ARG) == 0)
        return sandbox_child(argc, argv);
    srv_metrics_init();
    srv_log_set_level(SRV_LOG_ERROR);
    if (getenv("MCF_TEST_FILTER") && *getenv("MCF_TEST_FILTER"))
        cmocka_set_test_filter(getenv("MCF_TEST_FILTER"));
    return cmocka_run_group_tests(tests, NULL, NULL);
}
