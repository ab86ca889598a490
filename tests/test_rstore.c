/* SPDX-License-Identifier: MIT */
/*
 * test_rstore.c - the job store in Redis (server/store/redis/rstore*.c) against a real
 * redis-server (tests/redisd.c: AOF on, its own directory, a free loopback
 * port), each test with two or three "replicas" (stores with their own
 * consumer names) on one server, as mcfd replicas share it. Checks the
 * semantics rstore.h writes down: atomic records and their TTLs, sizes
 * the server reports never trusted, the queue's order and admission,
 * takeover of a job whose replica stopped heartbeating with its old
 * runner fenced off, heartbeats keeping a long job, dead letters, a full
 * queue refused, progress seen from another replica, Redis down and back
 * with what was acknowledged kept, and many claimers taking each job once.
 * A second group runs the tests that matter again with the large blobs
 * in files (--blob-dir), plus the directory's own: bytes not in Redis,
 * a fenced-off runner's files removed, expired jobs' files swept, a
 * missing directory refused at open.
 */
#include <dirent.h>
#include <sys/stat.h>
#include <unistd.h>
#include <errno.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"
#include "redisd.h"
#include "../server/store/redis/rstore.h"

static redisd S;
static char blob_dir[256];       /* "": blobs in Redis */
static char files_root[200];     /* the tests' blob directory */

static int group_setup(void **state)
{
    (void)state;
    (void)redisd_start(&S);
    return 0;
}

static int group_teardown(void **state)
{
    (void)state;
    redisd_cleanup(&S);
    return 0;
}

/* Before each test: an empty database. */
static int setup(void **state)
{
    rds_config cfg = redisd_config(&S);
    rds *c = rds_new(&cfg);
    redisReply *r = rds_cmdl(c, "FLUSHALL", NULL);
    (void)state;
    rds_reply_free(r);
    rds_free(c);
    blob_dir[0] = 0;
    return 0;
}

/* A replica named name; claim_idle and max_runs as given. */
static rstore *replica(const char *name, double claim_idle, int max_runs)
{
    rds_config rc;
    rstore_config cfg;
    rstore *s;
    char msg[256];

    if (S.why[0] || !S.pid)
        fail_msg("%s", S.why[0] ? S.why : "redis-server is down");
    rc = redisd_config(&S);
    rstore_config_default(&cfg);
    snprintf(cfg.consumer, sizeof cfg.consumer, "%s", name);
    cfg.claim_idle = claim_idle;
    cfg.max_runs = max_runs;
    cfg.block = 0.1;
    cfg.ttl = 3600;
    snprintf(cfg.blob_dir, sizeof cfg.blob_dir, "%s", blob_dir);
    if (!(s = rstore_open(&rc, &cfg, msg, sizeof msg)))
        fail_msg("rstore_open: %s", msg);
    return s;
}

/* A direct connection for looking at the keys. */
static rds *peek(void)
{
    rds_config cfg = redisd_config(&S);
    return rds_new(&cfg);
}

static long long peek_int(rds *c, const char *a0, const char *a1,
                          const char *a2)
{
    redisReply *r = rds_cmdl(c, a0, a1, a2, NULL);
    long long v = -99;
    if (!r || rds_reply_ll(r, &v) != 0)
        fail_msg("%s %s: %s", a0, a1, r ? "not a number" : rds_errmsg(c));
    rds_reply_free(r);
    return v;
}

static void must_ok(int rc, const char *what)
{
    if (rc != 0)
        fail_msg("%s: %s", what, strerror(errno));
}

static void make_job(rstore *s, const char *id, size_t input_len)
{
    char *input = malloc(input_len);
    size_t i;
    rstore_blob b[3] = {
        {"input", input, input_len},
        {"request.json", "{\"scheme\":\"desbrun2\"}", 21},
        {"state.json", "{\"status\":\"queued\"}", 19},
    };

    for (i = 0; i < input_len; i++)
        input[i] = (char)(i * 7919 >> 3);
    must_ok(rstore_create(s, id, b, 3), "create");
    free(input);
}

static int claim(rstore *s, char id[RSTORE_ID_MAX], int *runs)
{
    int rc = rstore_claim(s, NULL, NULL, id, runs);
    if (rc < 0)
        fail_msg("claim: %s", strerror(errno));
    return rc;
}

/* ------------------------------------------------------------- records */

static void count_id(const char *id, void *ctx)
{
    (void)id;
    (*(int *)ctx)++;
}

static void test_records(void **state)
{
    rstore *s = replica("a", 30, 3);
    rds *c = peek();
    size_t big = (size_t)20 << 20, n = 0, i;   /* 3 GETRANGE slices */
    char *data = NULL, slice[100];
    int count = 0;
    (void)state;

    make_job(s, "j1", big);
    errno = 0;
    assert_int_equal(rstore_create(s, "j1", NULL, 0), -1);
    assert_int_equal(errno, EEXIST);
    must_ok(rstore_get(s, "j1", "input", &data, &n), "get input");
    assert_int_equal(n, big);
    for (i = 0; i < big; i += 4099)
        assert_int_equal(data[i], (char)(i * 7919 >> 3));
    assert_int_equal(data[big], 0);
    free(data);
    must_ok(rstore_get_at(s, "j1", "input", big - 100, slice, 100), "get_at");
    assert_int_equal(slice[99], (char)((big - 1) * 7919 >> 3));
    assert_int_equal(rstore_get_at(s, "j1", "input", big - 99, slice, 100),
                     -1);
    must_ok(rstore_get(s, "j1", "state.json", &data, &n), "get state");
    assert_string_equal(data, "{\"status\":\"queued\"}");
    free(data);
    must_ok(rstore_put(s, "j1", "state.json", "{\"status\":\"done\"}", 17, 0),
            "put state");
    must_ok(rstore_put(s, "j1", "result.drc", "RESULT", 6, 0), "put result");
    must_ok(rstore_stat(s, "j1", "result.drc", &n), "stat");
    assert_int_equal(n, 6);
    must_ok(rstore_stat(s, "j1", "state.json", &n), "stat");
    assert_int_equal(n, 17);
    assert_int_equal(rstore_stat(s, "j1", "metrics.json", &n), -1);
    assert_int_equal(errno, ENOENT);
    assert_int_equal(rstore_get(s, "j1", "fields.bin", &data, &n), -1);
    assert_int_equal(errno, ENOENT);
    assert_int_equal(rstore_usage(s, "j1"), big + 6 + 21 + 17);
    /* every key of the job expires: the hash, each blob, the events */
    must_ok(rstore_progress(s, "j1", "{\"step\":1}", 10), "progress");
    assert_true(peek_int(c, "PTTL", "mcfd:job:j1", NULL) > 3000000);
    assert_true(peek_int(c, "PTTL", "mcfd:blob:j1:input", NULL) > 3000000);
    assert_true(peek_int(c, "PTTL", "mcfd:blob:j1:result.drc", NULL) >
                3000000);
    assert_true(peek_int(c, "PTTL", "mcfd:ev:j1", NULL) > 3000000);
    /* names become keys: nothing outside [A-Za-z0-9._-] */
    assert_int_equal(rstore_put(s, "j1", "a:b", "x", 1, 0), -1);
    assert_int_equal(errno, EINVAL);
    assert_int_equal(rstore_put(s, "j*", "x", "x", 1, 0), -1);
    assert_int_equal(rstore_put(s, "nojob", "x", "x", 1, 0), -1);
    assert_int_equal(errno, ENOENT);
    make_job(s, "j2", 10);
    make_job(s, "j3", 10);
    must_ok(rstore_scan(s, count_id, &count), "scan");
    assert_int_equal(count, 3);
    must_ok(rstore_remove(s, "j2"), "remove");
    assert_int_equal(peek_int(c, "EXISTS", "mcfd:blob:j2:input", NULL), 0);
    must_ok(rstore_quarantine(s, "j3"), "quarantine");
    assert_int_equal(peek_int(c, "EXISTS", "mcfd:quarantine:mcfd:blob:j3:input",
                              NULL), 1);
    assert_int_equal(rstore_get(s, "j3", "state.json", &data, &n), -1);
    assert_int_equal(errno, ENOENT);
    /* an expired job leaves the set at the next scan */
    rds_reply_free(rds_cmdl(c, "DEL", "mcfd:job:j1", NULL));
    count = 0;
    must_ok(rstore_scan(s, count_id, &count), "scan");
    assert_int_equal(count, 0);
    assert_int_equal(peek_int(c, "SCARD", "mcfd:jobs", NULL), 0);
    rds_free(c);
    rstore_close(s);
}

/* Sizes and bytes the server reports are checked, never trusted. */
static void test_server_sizes_not_trusted(void **state)
{
    rstore *s = replica("a", 30, 3);
    rds *c = peek();
    char *data = NULL;
    size_t n = 0;
    (void)state;

    make_job(s, "j", 1000);
    /* a size far above max_blob: refused before anything is allocated */
    rds_reply_free(rds_cmdl(c, "HSET", "mcfd:job:j", "s:input",
                            "99999999999999", NULL));
    assert_int_equal(rstore_get(s, "j", "input", &data, &n), -1);
    assert_int_equal(errno, EIO);
    rds_reply_free(rds_cmdl(c, "HSET", "mcfd:job:j", "s:input", "12x", NULL));
    assert_int_equal(rstore_get(s, "j", "input", &data, &n), -1);
    assert_int_equal(errno, EIO);
    /* more than the bytes there are: a short read, not garbage */
    rds_reply_free(rds_cmdl(c, "HSET", "mcfd:job:j", "s:input", "1001",
                            NULL));
    assert_int_equal(rstore_get(s, "j", "input", &data, &n), -1);
    assert_int_equal(errno, EIO);
    assert_null(data);
    rds_free(c);
    rstore_close(s);
}

/* A blob over max_blob (the smaller of the configuration's and the
 * server's proto-max-bulk-len) is refused before it is sent. */
static void test_blob_limit(void **state)
{
    rds_config rc = redisd_config(&S);
    rstore_config cfg;
    rstore *s;
    rds *c = peek();
    char msg[256], *big;
    (void)state;

    rds_reply_free(rds_cmdl(c, "CONFIG", "SET", "proto-max-bulk-len",
                            "1048576", NULL));
    rstore_config_default(&cfg);
    if (!(s = rstore_open(&rc, &cfg, msg, sizeof msg)))
        fail_msg("%s", msg);
    make_job(s, "j", 10);
    big = calloc(1, 1 << 20);
    assert_int_equal(rstore_put(s, "j", "result.drc", big, 1 << 20, 0), -1);
    assert_int_equal(errno, EFBIG);
    must_ok(rstore_put(s, "j", "result.drc", big, (1 << 20) - 1024, 0),
            "put under the limit");
    free(big);
    rds_reply_free(rds_cmdl(c, "CONFIG", "SET", "proto-max-bulk-len",
                            "536870912", NULL));
    rds_free(c);
    rstore_close(s);
}

/* -------------------------------------------------------------- queue */

static int refuse_all(void *ctx, const char *id)
{
    (void)id;
    ++*(int *)ctx;
    return 0;
}

static void test_queue_order_and_ack(void **state)
{
    rstore *a = replica("a", 30, 3), *b = replica("b", 30, 3);
    rds *c = peek();
    char id[RSTORE_ID_MAX];
    int runs = 0, offers = 0;
    (void)state;

    make_job(a, "j1", 10);
    make_job(a, "j2", 10);
    make_job(a, "j3", 10);
    must_ok(rstore_push(a, "j1", 0), "push");
    must_ok(rstore_push(a, "j2", 0), "push");
    must_ok(rstore_push(b, "j3", 1), "push front");   /* put back first */
    assert_int_equal(claim(b, id, &runs), RSTORE_TAKEN);
    assert_string_equal(id, "j3");
    assert_int_equal(runs, 1);
    /* the head does not fit: nothing taken, and it stays the head */
    assert_int_equal(rstore_claim(a, refuse_all, &offers, id, NULL),
                     RSTORE_EMPTY);
    assert_int_equal(offers, 1);
    assert_int_equal(rstore_claim(a, refuse_all, &offers, id, NULL),
                     RSTORE_EMPTY);
    assert_int_equal(offers, 2);
    assert_int_equal(claim(a, id, &runs), RSTORE_TAKEN);
    assert_string_equal(id, "j1");
    assert_int_equal(claim(a, id, &runs), RSTORE_TAKEN);
    assert_string_equal(id, "j2");
    assert_int_equal(claim(a, id, &runs), RSTORE_EMPTY);
    /* acknowledged entries leave the streams */
    must_ok(rstore_ack(a, "j1"), "ack");
    must_ok(rstore_ack(a, "j2"), "ack");
    must_ok(rstore_ack(b, "j3"), "ack");
    must_ok(rstore_ack(b, "j3"), "ack again: nothing running");
    assert_int_equal(peek_int(c, "XLEN", "mcfd:queue", NULL), 0);
    assert_int_equal(peek_int(c, "XLEN", "mcfd:front", NULL), 0);
    /* a queued job canceled: dropped, never claimed */
    make_job(a, "j4", 10);
    must_ok(rstore_push(a, "j4", 0), "push");
    must_ok(rstore_drop(a, "j4"), "drop");
    assert_int_equal(claim(b, id, &runs), RSTORE_EMPTY);
    /* the group lost (a Redis without its AOF): made again */
    rds_reply_free(rds_cmdl(c, "XGROUP", "DESTROY", "mcfd:queue", "workers",
                            NULL));
    must_ok(rstore_push(a, "j4", 0), "push");
    assert_int_equal(claim(b, id, &runs), RSTORE_TAKEN);
    assert_string_equal(id, "j4");
    rds_free(c);
    rstore_close(a);
    rstore_close(b);
}

static void test_queue_full(void **state)
{
    rds_config rc = redisd_config(&S);
    rstore_config cfg;
    rstore *s;
    char msg[256];
    (void)state;

    rstore_config_default(&cfg);
    cfg.queue_max = 2;
    if (!(s = rstore_open(&rc, &cfg, msg, sizeof msg)))
        fail_msg("%s", msg);
    make_job(s, "j1", 1);
    make_job(s, "j2", 1);
    make_job(s, "j3", 1);
    must_ok(rstore_push(s, "j1", 0), "push");
    must_ok(rstore_push(s, "j2", 0), "push");
    assert_int_equal(rstore_push(s, "j3", 0), -1);
    assert_int_equal(errno, EAGAIN);      /* 503 + Retry-After, no trim */
    rstore_close(s);
}

/* A replica stops heartbeating (kill -9): another takes its job over
 * under the same id, and the old runner can write nothing any more. */
static void test_takeover_fences_the_old_runner(void **state)
{
    rstore *a = replica("a", 0.3, 3), *b = replica("b", 0.3, 3);
    char id[RSTORE_ID_MAX], *data;
    size_t n;
    int runs = 0;
    (void)state;

    make_job(a, "j", 10);
    must_ok(rstore_push(a, "j", 0), "push");
    assert_int_equal(claim(a, id, &runs), RSTORE_TAKEN);
    must_ok(rstore_put(a, "j", "state.json", "{\"status\":\"running\"}", 20,
                       1), "put while running");
    assert_int_equal(claim(b, id, &runs), RSTORE_EMPTY);  /* not idle yet */
    redisd_sleep(0.4);
    assert_int_equal(rstore_reap(b, -1), 1);
    assert_int_equal(claim(b, id, &runs), RSTORE_RETAKEN);
    assert_string_equal(id, "j");
    assert_int_equal(runs, 2);
    /* a, back from the dead, is fenced off */
    assert_int_equal(rstore_put(a, "j", "result.drc", "OLD", 3, 1), -1);
    assert_int_equal(errno, ESTALE);
    assert_int_equal(rstore_heartbeat(a, "j"), -1);
    assert_int_equal(errno, ESTALE);
    assert_int_equal(rstore_ack(a, "j"), -1);
    assert_int_equal(errno, ESTALE);
    must_ok(rstore_put(b, "j", "result.drc", "NEW", 3, 1), "put");
    must_ok(rstore_ack(b, "j"), "ack");
    must_ok(rstore_get(b, "j", "result.drc", &data, &n), "get");
    assert_string_equal(data, "NEW");
    free(data);
    assert_int_equal(claim(a, id, &runs), RSTORE_EMPTY);
    rstore_close(a);
    rstore_close(b);
}

/* A cancel of a queued job and a start by another replica race: the
 * store decides. A put RSTORE_UNCLAIMED lands only while no replica runs
 * the job; once one took it, ESTALE (that replica ends and counts it). */
static void test_cancel_of_queued_races_a_start(void **state)
{
    rstore *a = replica("a", 30, 3), *b = replica("b", 30, 3);
    char id[RSTORE_ID_MAX], *data;
    size_t n;
    int runs = 0;
    (void)state;

    make_job(a, "j1", 10);
    make_job(a, "j2", 10);
    must_ok(rstore_push(a, "j1", 0), "push");
    must_ok(rstore_push(a, "j2", 0), "push");
    /* b cancels j1 before anyone takes it */
    must_ok(rstore_put(b, "j1", "state.json", "{\"status\":\"canceled\"}",
                       21, RSTORE_UNCLAIMED), "cancel while queued");
    /* j1 still has its entry (the service drops it next; a replica taking
     * it meanwhile reads it canceled and acks); a takes j2 before b's
     * cancel of it, which is refused, nothing written */
    assert_int_equal(claim(a, id, &runs), RSTORE_TAKEN);
    assert_string_equal(id, "j1");
    must_ok(rstore_ack(a, "j1"), "ack");
    assert_int_equal(claim(a, id, &runs), RSTORE_TAKEN);
    assert_string_equal(id, "j2");
    must_ok(rstore_put(a, "j2", "state.json", "{\"status\":\"running\"}", 20,
                       1), "put while running");
    assert_int_equal(rstore_put(b, "j2", "state.json",
                                "{\"status\":\"canceled\"}", 21,
                                RSTORE_UNCLAIMED), -1);
    assert_int_equal(errno, ESTALE);
    must_ok(rstore_get(b, "j2", "state.json", &data, &n), "get");
    assert_string_equal(data, "{\"status\":\"running\"}");
    free(data);
    /* the runner's own puts are not refused */
    must_ok(rstore_put(a, "j2", "result.drc", "NEW", 3, 1), "put");
    rstore_close(a);
    rstore_close(b);
}

/* The end of a run in one script: blobs and ack together, by the runner
 * only; a runner taken over writes none of them. */
static void test_finish_is_one_step(void **state)
{
    rstore *a = replica("a", 0.3, 3), *b = replica("b", 0.3, 3);
    char id[RSTORE_ID_MAX], *data;
    size_t n;
    int runs = 0;
    rds *c = peek();
    rstore_blob end[3] = {
        {"result.obj", "v 0 0 0\n", 8},
        {"metrics.json", "{\"rms\":1}", 9},
        {"state.json", "{\"status\":\"succeeded\"}", 22},
    };
    (void)state;

    make_job(a, "j", 10);
    must_ok(rstore_push(a, "j", 0), "push");
    assert_int_equal(claim(a, id, &runs), RSTORE_TAKEN);
    redisd_sleep(0.4);
    assert_int_equal(rstore_reap(b, -1), 1);
    assert_int_equal(claim(b, id, &runs), RSTORE_RETAKEN);
    /* a, taken over: nothing written, nothing acknowledged */
    assert_int_equal(rstore_finish(a, "j", end, 3), -1);
    assert_int_equal(errno, ESTALE);
    assert_int_equal(rstore_stat(a, "j", "result.obj", &n), -1);
    assert_int_equal(errno, ENOENT);
    assert_int_equal(peek_int(c, "XLEN", "mcfd:queue", NULL), 1);
    /* b: all of it, and the queue is empty */
    must_ok(rstore_finish(b, "j", end, 3), "finish");
    /* its reply lost, b tries again: done already, not STALE */
    must_ok(rstore_finish(b, "j", end, 3), "finish again");
    must_ok(rstore_get(a, "j", "result.obj", &data, &n), "get result");
    assert_int_equal(n, 8);
    free(data);
    must_ok(rstore_get(a, "j", "state.json", &data, &n), "get state");
    assert_string_equal(data, "{\"status\":\"succeeded\"}");
    free(data);
    assert_int_equal(peek_int(c, "XLEN", "mcfd:queue", NULL), 0);
    assert_int_equal(claim(a, id, &runs), RSTORE_EMPTY);
    rds_free(c);
    rstore_close(a);
    rstore_close(b);
}

/* A job held by a replica without room for it (the head did not fit)
 * goes to a replica with room after claim_idle; the first one, given room
 * later, does not take it too. */
static void test_held_job_goes_to_a_replica_with_room(void **state)
{
    rstore *a = replica("a", 0.3, 3), *b = replica("b", 0.3, 3);
    char id[RSTORE_ID_MAX];
    int runs = 0, offers = 0;
    (void)state;

    make_job(a, "j", 10);
    must_ok(rstore_push(a, "j", 0), "push");
    assert_int_equal(rstore_claim(a, refuse_all, &offers, id, NULL),
                     RSTORE_EMPTY);
    assert_int_equal(offers, 1);
    redisd_sleep(0.4);
    assert_int_equal(rstore_reap(b, -1), 1);
    assert_int_equal(claim(b, id, &runs), RSTORE_TAKEN);
    assert_int_equal(runs, 1);            /* held is not run */
    assert_int_equal(claim(a, id, &runs), RSTORE_EMPTY);
    must_ok(rstore_ack(b, "j"), "ack");
    rstore_close(a);
    rstore_close(b);
}

/* A job is queued once; queued again while it runs (a replica's restart
 * recovering it), the second entry is dropped while the run heartbeats. */
static void test_no_duplicate_runs(void **state)
{
    rstore *a = replica("a", 30, 3), *b = replica("b", 30, 3);
    rds *c = peek();
    char id[RSTORE_ID_MAX];
    int runs;
    (void)state;

    make_job(a, "j", 10);
    must_ok(rstore_push(a, "j", 0), "push");
    must_ok(rstore_push(b, "j", 0), "push again");
    assert_int_equal(peek_int(c, "XLEN", "mcfd:queue", NULL), 1);
    assert_int_equal(claim(a, id, &runs), RSTORE_TAKEN);
    must_ok(rstore_push(b, "j", 0), "push while running");
    assert_int_equal(claim(b, id, &runs), RSTORE_EMPTY);
    assert_int_equal(peek_int(c, "XLEN", "mcfd:queue", NULL), 1);
    must_ok(rstore_put(a, "j", "result.drc", "R", 1, 1), "put");
    must_ok(rstore_ack(a, "j"), "ack");
    assert_int_equal(peek_int(c, "XLEN", "mcfd:queue", NULL), 0);
    rds_free(c);
    rstore_close(a);
    rstore_close(b);
}

/* A long job whose runner heartbeats is never taken over. What is
 * asserted depends on no scheduling: a reap may take the job only when
 * more than claim_idle passed between the start of the last heartbeat and
 * the end of the reap (a stalled machine, as under ASan on a loaded CI
 * host), so the check is made on the clock's measure of that gap; with
 * 0.1 s heartbeats against a 1 s limit a stall of 0.9 s is needed. */
static void test_heartbeat_keeps_a_long_job(void **state)
{
    const double idle = 1.0;
    rstore *a = replica("a", idle, 3), *b = replica("b", idle, 3);
    char id[RSTORE_ID_MAX];
    int i, runs, checked = 0;
    (void)state;

    make_job(a, "j", 10);
    must_ok(rstore_push(a, "j", 0), "push");
    assert_int_equal(claim(a, id, &runs), RSTORE_TAKEN);
    for (i = 0; i < 30; i++) {          /* 3 s, three times claim_idle */
        double t0;
        int reaped;
        redisd_sleep(0.1);
        t0 = rds_monotonic();
        must_ok(rstore_heartbeat(a, "j"), "heartbeat");
        reaped = rstore_reap(b, -1);
        if (rds_monotonic() - t0 >= idle) {
            print_message("    stalled %.2f s between a heartbeat and a "
                          "reap: the rest is not checked\n",
                          rds_monotonic() - t0);
            break;
        }
        assert_int_equal(reaped, 0);
        checked++;
    }
    if (i == 30)   /* never stalled: the job is still a's alone */
        assert_int_equal(claim(b, id, &runs), RSTORE_EMPTY);
    assert_true(checked >= 1);
    rstore_ack(a, "j");
    rstore_close(a);
    rstore_close(b);
}

/* A job whose runner dies every time goes to the dead letters. */
static void test_dead_letter(void **state)
{
    rstore *a = replica("a", 0.2, 2), *b = replica("b", 0.2, 2);
    rds *c = peek();
    redisReply *r;
    char id[RSTORE_ID_MAX];
    int runs = 0;
    (void)state;

    make_job(a, "j", 10);
    must_ok(rstore_push(a, "j", 0), "push");
    assert_int_equal(claim(a, id, &runs), RSTORE_TAKEN);   /* dies */
    redisd_sleep(0.3);
    assert_int_equal(rstore_reap(b, -1), 1);
    assert_int_equal(claim(b, id, &runs), RSTORE_RETAKEN); /* dies */
    assert_int_equal(runs, 2);
    redisd_sleep(0.3);
    assert_int_equal(rstore_reap(a, -1), 1);
    assert_int_equal(claim(a, id, &runs), RSTORE_DEAD);
    assert_string_equal(id, "j");
    assert_int_equal(runs, 2);
    r = rds_cmdl(c, "XRANGE", "mcfd:dead", "-", "+", NULL);
    assert_non_null(r);
    assert_int_equal(r->elements, 1);
    assert_string_equal(rds_reply_field(r->element[0]->element[1], "job")->str,
                        "j");
    assert_non_null(strstr(rds_reply_field(r->element[0]->element[1],
                                           "reason")->str, "2 runs"));
    rds_reply_free(r);
    assert_int_equal(peek_int(c, "XLEN", "mcfd:queue", NULL), 0);
    assert_int_equal(claim(b, id, &runs), RSTORE_EMPTY);
    rds_free(c);
    rstore_close(a);
    rstore_close(b);
}

/* ----------------------------------------------------------- progress */

typedef struct {
    char text[1024];
    int n;
} lines;

static void add_line(const char *line, size_t len, void *ctx)
{
    lines *l = ctx;
    size_t at = strlen(l->text);
    snprintf(l->text + at, sizeof l->text - at, "%.*s|", (int)len, line);
    l->n++;
}

static void *publish_later(void *arg)
{
    redisd_sleep(0.2);
    if (rstore_progress(arg, "j", "late", 4) != 0)
        return (void *)1;
    return NULL;
}

static void test_progress_seen_from_another_replica(void **state)
{
    rstore *a = replica("a", 30, 3), *b = replica("b", 30, 3);
    char after[RSTORE_ID_MAX] = "0";
    lines l = {"", 0};
    pthread_t t;
    void *bad;
    double t0;
    (void)state;

    make_job(a, "j", 10);
    must_ok(rstore_progress(a, "j", "one", 3), "progress");
    must_ok(rstore_progress(a, "j", "two", 3), "progress");
    assert_int_equal(rstore_events(b, "j", after, 1, add_line, &l), 2);
    assert_string_equal(l.text, "one|two|");
    /* nothing new: the wait ends at its bound */
    t0 = rds_monotonic();
    assert_int_equal(rstore_events(b, "j", after, 0.2, add_line, &l), 0);
    assert_true(rds_monotonic() - t0 >= 0.15);
    /* a line published while B waits arrives */
    pthread_create(&t, NULL, publish_later, a);
    assert_int_equal(rstore_events(b, "j", after, 5, add_line, &l), 1);
    pthread_join(t, &bad);
    assert_null(bad);
    assert_string_equal(l.text, "one|two|late|");
    rstore_close(a);
    rstore_close(b);
}

/* What watch() gave, per job: "line|" or "*|" (a mark); text[2]: the
 * control stream's cancels, "id|". */
typedef struct {
    char text[3][256];
} watched;

static void add_watched(void *ctx, int i, const char *line, size_t len)
{
    watched *w = ctx;
    char *t = w->text[i < 0 ? 2 : i];
    size_t at = strlen(t);

    snprintf(t + at, sizeof w->text[0] - at, "%.*s|", line ? (int)len : 1,
             line ? line : "*");
}

static void *put_state_later(void *arg)
{
    redisd_sleep(0.2);
    if (rstore_put(arg, "k", "state.json", "{}", 2, 0) != 0)
        return (void *)1;
    return NULL;
}

/* One blocking XREAD over the streams of several jobs (the follower
 * thread's): each job's lines in order, a mark where its state.json or
 * cancel.json was written (put or finish), never for another blob; a
 * write to any of them ends the wait; a cancel of a job a replica runs
 * reaches that replica's watch. */
static void test_watch_several_jobs(void **state)
{
    rstore *a = replica("a", 30, 3), *b = replica("b", 30, 3);
    const char *ids[2] = {"j", "k"};
    char after[2][RSTORE_ID_MAX] = {"0", "0"}, id[RSTORE_ID_MAX];
    watched w = {{"", "", ""}}, wa = {{"", "", ""}};
    rstore_blob end[1] = {{"state.json", "{\"status\":\"succeeded\"}", 22}};
    pthread_t t;
    void *bad;
    int runs = 0;
    (void)state;

    make_job(a, "j", 10);
    make_job(a, "k", 10);
    must_ok(rstore_push(a, "j", 0), "push");
    assert_int_equal(claim(a, id, &runs), RSTORE_TAKEN);
    must_ok(rstore_put(a, "j", "state.json", "{}", 2, 1), "put state");
    must_ok(rstore_progress(a, "j", "one", 3), "progress");
    must_ok(rstore_put(a, "j", "metrics.json", "{}", 2, 1), "put other");
    must_ok(rstore_progress(a, "j", "two", 3), "progress");
    must_ok(rstore_put(b, "k", "cancel.json", "{}", 2, 0), "put cancel");
    assert_int_equal(rstore_watch(b, 2, ids, after, 1, add_watched, &w), 4);
    assert_string_equal(w.text[0], "*|one|two|");
    assert_string_equal(w.text[1], "*|");
    /* nothing new: nothing given */
    assert_int_equal(rstore_watch(b, 2, ids, after, 0, add_watched, &w), 0);
    /* the end of j's run: a mark */
    must_ok(rstore_finish(a, "j", end, 1), "finish");
    assert_int_equal(rstore_watch(b, 2, ids, after, 1, add_watched, &w), 1);
    assert_string_equal(w.text[0], "*|one|two|*|");
    /* a write on k while B waits ends the wait */
    pthread_create(&t, NULL, put_state_later, a);
    assert_int_equal(rstore_watch(b, 2, ids, after, 5, add_watched, &w), 1);
    pthread_join(t, &bad);
    assert_null(bad);
    assert_string_equal(w.text[1], "*|*|");
    /* the single-stream read skips the marks */
    {
        char one[RSTORE_ID_MAX] = "0";
        lines l = {"", 0};
        assert_int_equal(rstore_events(b, "j", one, 0, add_line, &l), 2);
        assert_string_equal(l.text, "one|two|");
    }
    /* a cancel of k, which a runs, put on b: told to a's control stream
     * (a watches no job), not to b's */
    must_ok(rstore_push(a, "k", 0), "push");
    assert_int_equal(claim(a, id, &runs), RSTORE_TAKEN);
    must_ok(rstore_put(b, "k", "cancel.json", "{}", 2, 0), "put cancel");
    {   /* a's sweep reading k's stream meanwhile leaves it to the watch */
        char one[RSTORE_ID_MAX] = "0";
        lines l = {"", 0};
        assert_int_equal(rstore_events(a, "k", one, 0, add_line, &l), 0);
    }
    assert_int_equal(rstore_watch(a, 0, NULL, NULL, 1, add_watched, &wa), 1);
    assert_string_equal(wa.text[2], "k|");
    assert_int_equal(rstore_watch(b, 2, ids, after, 0, add_watched, &w), 1);
    assert_string_equal(w.text[1], "*|*|*|");
    assert_string_equal(w.text[2], "");
    rstore_close(a);
    rstore_close(b);
}

/* ------------------------------------------------------ Redis down */

static void test_redis_down_and_back(void **state)
{
    rstore *a = replica("a", 30, 3);
    char why[256], id[RSTORE_ID_MAX], *data;
    size_t n;
    int runs;
    double t0, end;
    (void)state;

    make_job(a, "j1", 1000);
    make_job(a, "j2", 1000);
    must_ok(rstore_push(a, "j1", 0), "push");
    must_ok(rstore_push(a, "j2", 0), "push");
    assert_int_equal(claim(a, id, &runs), RSTORE_TAKEN);   /* j1 running */
    redisd_stop(&S, SIGKILL);
    t0 = rds_monotonic();
    assert_int_equal(rstore_ready(a, why, sizeof why), -1);
    assert_non_null(strstr(why, "redis 127.0.0.1:"));
    assert_int_equal(rstore_push(a, "j2", 0), -1);
    assert_int_equal(errno, EAGAIN);
    assert_int_equal(rstore_put(a, "j1", "result.drc", "R", 1, 1), -1);
    assert_int_equal(errno, EAGAIN);
    assert_int_equal(rstore_claim(a, NULL, NULL, id, NULL), -1);
    assert_int_equal(errno, EAGAIN);
    /* nothing waits for a dead server: connection refused is at once */
    assert_true(rds_monotonic() - t0 < 1.5);
    if (redisd_start(&S) != 0)
        fail_msg("redis-server did not come back: %s", S.why);
    /* within the backoff (at most 2 s per connection) every call works */
    for (end = rds_monotonic() + 10;
         rstore_ready(a, why, sizeof why) != 0 && rds_monotonic() < end;)
        redisd_sleep(0.05);
    for (end = rds_monotonic() + 10;
         rstore_put(a, "j1", "result.drc", "R", 1, 1) != 0 &&
         rds_monotonic() < end;)
        redisd_sleep(0.05);
    /* what was acknowledged before the kill -9 is there: the jobs, j1
     * still ours, j2 still waiting */
    must_ok(rstore_get(a, "j2", "input", &data, &n), "get");
    assert_int_equal(n, 1000);
    free(data);
    must_ok(rstore_ack(a, "j1"), "ack j1");
    for (end = rds_monotonic() + 10; rds_monotonic() < end;) {
        int rc = rstore_claim(a, NULL, NULL, id, &runs);
        if (rc == RSTORE_TAKEN)
            break;
        redisd_sleep(0.05);
    }
    assert_string_equal(id, "j2");
    rstore_close(a);
}

/* ------------------------------------------------ many claimers */

#define JOBS 60
#define CLAIMERS 4

static struct {
    pthread_mutex_t mu;
    int taken[JOBS];
} T = {PTHREAD_MUTEX_INITIALIZER, {0}};

static void *claimer(void *arg)
{
    rstore *s = arg;
    char id[RSTORE_ID_MAX];
    int idle = 0;

    while (idle < 3) {
        int rc = rstore_claim(s, NULL, NULL, id, NULL), k;
        if (rc < 0)
            return (void *)1;
        if (rc == RSTORE_EMPTY) {
            idle++;
            continue;
        }
        idle = 0;
        k = atoi(id + 1);
        pthread_mutex_lock(&T.mu);
        if (k >= 0 && k < JOBS)
            T.taken[k]++;
        pthread_mutex_unlock(&T.mu);
        if (rstore_put(s, id, "result.drc", "R", 1, 1) != 0 ||
            rstore_ack(s, id) != 0)
            return (void *)1;
    }
    return NULL;
}

static void test_many_claimers_take_each_job_once(void **state)
{
    rstore *r[2] = {replica("a", 30, 3), replica("b", 30, 3)};
    rds *c = peek();
    pthread_t t[CLAIMERS];
    char id[16];
    int i;
    (void)state;

    memset(T.taken, 0, sizeof T.taken);   /* the test runs twice */
    for (i = 0; i < JOBS; i++) {
        snprintf(id, sizeof id, "j%d", i);
        make_job(r[0], id, 100);
        must_ok(rstore_push(r[i % 2], id, 0), "push");
    }
    for (i = 0; i < CLAIMERS; i++)
        pthread_create(&t[i], NULL, claimer, r[i % 2]);
    for (i = 0; i < CLAIMERS; i++) {
        void *bad;
        pthread_join(t[i], &bad);
        assert_null(bad);
    }
    for (i = 0; i < JOBS; i++)
        if (T.taken[i] != 1)
            fail_msg("j%d taken %d times", i, T.taken[i]);
    assert_int_equal(peek_int(c, "XLEN", "mcfd:queue", NULL), 0);
    rds_free(c);
    rstore_close(r[0]);
    rstore_close(r[1]);
}

/* ------------------------------------------------- the blob directory */

/* Before each test of the blob directory: an empty database, the
 * replicas' large blobs in files under a new directory. */
static int setup_files(void **state)
{
    static int n;
    int rc = setup(state);

    snprintf(blob_dir, sizeof blob_dir, "%s/%d", files_root, ++n);
    return rc != 0 || mkdir(blob_dir, 0755) != 0;
}

/* Files in the job's directory whose name starts with prefix (-1: no
 * directory). */
static int files_of(const char *id, const char *prefix)
{
    char dir[400];
    DIR *d;
    struct dirent *de;
    int n = 0;

    snprintf(dir, sizeof dir, "%s/mcfd/%s", blob_dir, id);
    if (!(d = opendir(dir)))
        return -1;
    while ((de = readdir(d)))
        if (de->d_name[0] != '.' &&
            strncmp(de->d_name, prefix, strlen(prefix)) == 0)
            n++;
    closedir(d);
    return n;
}

static void test_files_hold_the_bytes_not_redis(void **state)
{
    rstore *a = replica("a", 30, 3);
    rds *c = peek();
    char id[RSTORE_ID_MAX], *data, part[100];
    size_t n, i;
    int runs;
    rstore_blob res[2] = {{"result.obj", NULL, 300000},
                          {"metrics.json", "{}", 2}};
    (void)state;

    make_job(a, "f", 200000);
    assert_int_equal(peek_int(c, "EXISTS", "mcfd:blob:f:input", NULL), 0);
    assert_int_equal(files_of("f", "input."), 1);
    must_ok(rstore_get(a, "f", "input", &data, &n), "get");
    assert_int_equal(n, 200000);
    for (i = 0; i < n; i++)
        if (data[i] != (char)(i * 7919 >> 3))
            fail_msg("input byte %zu differs", i);
    free(data);
    must_ok(rstore_get_at(a, "f", "input", 1000, part, 100), "get_at");
    assert_int_equal(part[7], (char)(1007 * 7919 >> 3));
    must_ok(rstore_stat(a, "f", "input", &n), "stat");
    assert_int_equal(n, 200000);
    /* the Redis side holds records only: far less than the bytes */
    {
        redisReply *r = rds_cmdl(c, "MEMORY", "USAGE", "mcfd:job:f", NULL);
        long long m = 0;
        assert_non_null(r);
        (void)rds_reply_ll(r, &m);
        rds_reply_free(r);
        assert_true(m > 0 && m < 4096);
    }
    must_ok(rstore_push(a, "f", 0), "push");
    assert_int_equal(claim(a, id, &runs), RSTORE_TAKEN);
    res[0].data = data = calloc(1, 300000);
    data[299999] = 'Z';
    must_ok(rstore_finish(a, "f", res, 2), "finish");
    free(data);
    must_ok(rstore_get(a, "f", "result.obj", &data, &n), "get result");
    assert_int_equal(n, 300000);
    assert_int_equal(data[299999], 'Z');
    free(data);
    assert_int_equal(peek_int(c, "EXISTS", "mcfd:blob:f:result.obj", NULL),
                     0);
    must_ok(rstore_remove(a, "f"), "remove");
    assert_int_equal(files_of("f", ""), -1);
    rds_free(c);
    rstore_close(a);
}

/* A runner taken over: its result's file never becomes visible and is
 * removed at once; the new runner's is the one result. */
static void test_files_of_a_fenced_runner_go(void **state)
{
    rstore *a = replica("a", 0.3, 3), *b = replica("b", 0.3, 3);
    char id[RSTORE_ID_MAX], *data;
    size_t n;
    int runs;
    rstore_blob old = {"result.drc", "OLD-RESULT", 10},
                new = {"result.drc", "NEW-RESULT", 10};
    (void)state;

    make_job(a, "t", 1000);
    must_ok(rstore_push(a, "t", 0), "push");
    assert_int_equal(claim(a, id, &runs), RSTORE_TAKEN);
    redisd_sleep(0.4);
    assert_int_equal(rstore_reap(b, -1), 1);
    assert_int_equal(claim(b, id, &runs), RSTORE_RETAKEN);
    assert_int_equal(rstore_finish(a, "t", &old, 1), -1);
    assert_int_equal(errno, ESTALE);
    assert_int_equal(files_of("t", "result.drc."), 0);
    must_ok(rstore_finish(b, "t", &new, 1), "finish");
    assert_int_equal(files_of("t", "result.drc."), 1);
    must_ok(rstore_get(a, "t", "result.drc", &data, &n), "get");
    assert_string_equal(data, "NEW-RESULT");
    free(data);
    rstore_close(a);
    rstore_close(b);
}

/* The sweep: an expired job's files go, a replaced blob's old file goes,
 * the files a record names stay. */
static void test_sweep_removes_expired_and_unnamed_files(void **state)
{
    rds_config rc = redisd_config(&S);
    rstore_config cfg;
    rstore *s;
    char msg[256], *data;
    size_t n;
    (void)state;

    rstore_config_default(&cfg);
    snprintf(cfg.blob_dir, sizeof cfg.blob_dir, "%s", blob_dir);
    cfg.ttl = 1;
    cfg.blob_grace = 0;
    if (!(s = rstore_open(&rc, &cfg, msg, sizeof msg)))
        fail_msg("rstore_open: %s", msg);
    make_job(s, "old", 5000);
    redisd_sleep(1.3);               /* its keys expire after 1 s */
    make_job(s, "live", 5000);
    must_ok(rstore_put(s, "live", "result.obj", "v1", 2, 0), "put");
    must_ok(rstore_put(s, "live", "result.obj", "v2", 2, 0), "put");
    assert_int_equal(files_of("old", "input."), 1);
    assert_int_equal(files_of("live", "result.obj."), 2);
    assert_int_equal(rstore_sweep(s), 2);
    assert_int_equal(files_of("old", ""), -1);
    assert_int_equal(files_of("live", "input."), 1);
    assert_int_equal(files_of("live", "result.obj."), 1);
    must_ok(rstore_get(s, "live", "result.obj", &data, &n), "get");
    assert_string_equal(data, "v2");
    free(data);
    rstore_close(s);
}

static void test_missing_blob_dir_refused_at_open(void **state)
{
    rds_config rc = redisd_config(&S);
    rstore_config cfg;
    char msg[256] = "";
    (void)state;

    rstore_config_default(&cfg);
    snprintf(cfg.blob_dir, sizeof cfg.blob_dir, "%s/no/such/dir", blob_dir);
    assert_null(rstore_open(&rc, &cfg, msg, sizeof msg));
    assert_non_null(strstr(msg, "--blob-dir"));
    assert_non_null(strstr(msg, "No such file"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(test_records, setup),
        cmocka_unit_test_setup(test_server_sizes_not_trusted, setup),
        cmocka_unit_test_setup(test_blob_limit, setup),
        cmocka_unit_test_setup(test_queue_order_and_ack, setup),
        cmocka_unit_test_setup(test_queue_full, setup),
        cmocka_unit_test_setup(test_takeover_fences_the_old_runner, setup),
        cmocka_unit_test_setup(test_cancel_of_queued_races_a_start, setup),
        cmocka_unit_test_setup(test_finish_is_one_step, setup),
        cmocka_unit_test_setup(test_held_job_goes_to_a_replica_with_room,
                               setup),
        cmocka_unit_test_setup(test_no_duplicate_runs, setup),
        cmocka_unit_test_setup(test_heartbeat_keeps_a_long_job, setup),
        cmocka_unit_test_setup(test_dead_letter, setup),
        cmocka_unit_test_setup(test_watch_several_jobs, setup),
        cmocka_unit_test_setup(test_progress_seen_from_another_replica,
                               setup),
        cmocka_unit_test_setup(test_redis_down_and_back, setup),
        cmocka_unit_test_setup(test_many_claimers_take_each_job_once, setup),
        /* the same store with the bytes in files (--blob-dir) */
        cmocka_unit_test_setup(test_takeover_fences_the_old_runner,
                               setup_files),
        cmocka_unit_test_setup(test_finish_is_one_step, setup_files),
        cmocka_unit_test_setup(test_redis_down_and_back, setup_files),
        cmocka_unit_test_setup(test_many_claimers_take_each_job_once,
                               setup_files),
        cmocka_unit_test_setup(test_files_hold_the_bytes_not_redis,
                               setup_files),
        cmocka_unit_test_setup(test_files_of_a_fenced_runner_go, setup_files),
        cmocka_unit_test_setup(test_sweep_removes_expired_and_unnamed_files,
                               setup_files),
        cmocka_unit_test_setup(test_missing_blob_dir_refused_at_open,
                               setup_files),
    };
    char cmd[300];
    int rc;

    snprintf(files_root, sizeof files_root, "/tmp/mcfd-blobs-XXXXXX");
    if (!mkdtemp(files_root)) {
        perror("mkdtemp");
        return 1;
    }
    rc = cmocka_run_group_tests(tests, group_setup, group_teardown);
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", files_root);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", files_root);
    return rc;
}
