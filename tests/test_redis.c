/* SPDX-License-Identifier: MIT */
/*
 * test_redis.c - mcfd's Redis client (server/store/redis/rds.c) against a real
 * redis-server: Debian's 7.0, which `make deps` installs, started by this
 * binary on a free loopback port with the append-only file on (fsync at
 * every write) in its own temporary directory, and stopped at the end
 * (tl_track_child: also when a test fails or the binary is killed). When
 * redis-server cannot start, every test that needs it fails with the
 * reason: `make test` runs `make deps` first, so a missing redis-server is
 * a broken set-up, not a machine without an optional tool.
 *
 * What is checked: URLs, binary-safe values, the reply shapes of the
 * commands the job store uses (streams and their consumer group: XADD
 * MAXLEN ~, XREADGROUP BLOCK, XACK, XCLAIM JUSTID as a heartbeat,
 * XAUTOCLAIM's three-part 7.0 reply, XPENDING's delivery counts), replies
 * bounded in bytes, deadlines, reconnection with backoff after the server
 * went away and came back, AUTH from a password file, SELECT, pipelines,
 * Lua scripts surviving SCRIPT FLUSH, a pool shared by threads (whose
 * connections stop backing off once one reaches the server again), a
 * subscriber's idle waits, and that a write acknowledged before a kill -9
 * is still there after the restart (AOF).
 */
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "testlib.h"
#include "redisd.h"

static redisd S;

static double now_s(void) { return rds_monotonic(); }

static void sleep_s(double s) { redisd_sleep(s); }

static int free_port(void) { return redisd_free_port(); }
static rds_config cfg_of(int port)
{
    rds_config c = redisd_config(&S);
    c.port = port;
    return c;
}
static int server_start(void) { return redisd_start(&S); }
static void server_stop(int sig) { redisd_stop(&S, sig); }

static int group_setup(void **state)
{
    (void)state;
    (void)server_start();
    return 0;
}

static int group_teardown(void **state)
{
    (void)state;
    redisd_cleanup(&S);
    return 0;
}

/* Fails the test when redis-server is not up; else a new connection. */
static rds *need_server(void)
{
    rds_config cfg;
    if (S.why[0] || !S.pid)
        fail_msg("%s", S.why[0] ? S.why : "redis-server is down");
    cfg = cfg_of(S.port);
    return rds_new(&cfg);
}

/* A command that must succeed: its reply. */
static redisReply *must(rds *c, redisReply *r)
{
    if (!r)
        fail_msg("%s", rds_errmsg(c));
    return r;
}

static void expect_int(rds *c, redisReply *r, long long want)
{
    long long v = -1;
    must(c, r);
    if (rds_reply_ll(r, &v) != 0 || v != want)
        fail_msg("expected %lld, got type %d value %lld", want, r->type, v);
    rds_reply_free(r);
}

/* ------------------------------------------------------------- tests */

static void test_url(void **state)
{
    rds_config c;
    char msg[256];
    (void)state;

    rds_config_default(&c);
    assert_int_equal(rds_url_parse("redis://10.0.0.7:6390/3", &c, msg,
                                   sizeof msg), 0);
    assert_string_equal(c.host, "10.0.0.7");
    assert_int_equal(c.port, 6390);
    assert_int_equal(c.db, 3);
    assert_int_equal(rds_url_parse("redis://cache", &c, msg, sizeof msg), 0);
    assert_string_equal(c.host, "cache");
    assert_int_equal(c.port, 6379);
    assert_int_equal(c.db, 0);
    assert_int_equal(rds_url_parse("redis://[::1]:7000/", &c, msg,
                                   sizeof msg), 0);
    assert_string_equal(c.host, "::1");
    assert_int_equal(c.port, 7000);
    /* refused, each with its reason */
    assert_int_equal(rds_url_parse("redis://:hunter2@cache:6379", &c, msg,
                                   sizeof msg), -1);
    assert_non_null(strstr(msg, "password"));
    assert_null(strstr(msg, "hunter2"));
    assert_int_equal(rds_url_parse("http://cache", &c, msg, sizeof msg), -1);
    assert_int_equal(rds_url_parse("redis://cache:0", &c, msg, sizeof msg),
                     -1);
    assert_int_equal(rds_url_parse("redis://cache:70000", &c, msg,
                                   sizeof msg), -1);
    assert_int_equal(rds_url_parse("redis://cache:63x9", &c, msg,
                                   sizeof msg), -1);
    assert_int_equal(rds_url_parse("redis://:6379", &c, msg, sizeof msg), -1);
    assert_int_equal(rds_url_parse("redis://cache/x", &c, msg, sizeof msg),
                     -1);
    assert_int_equal(rds_url_parse("redis://[::1", &c, msg, sizeof msg), -1);
}

static void test_binary_values(void **state)
{
    static const char val[] = "a\0b\r\n$3\r\nc";   /* NULs and RESP */
    const char *argv[3] = {"SET", "bin", val};
    size_t lens[3] = {3, 3, sizeof val};
    rds *c = need_server();
    redisReply *r;
    (void)state;

    rds_reply_free(must(c, rds_cmd(c, 3, argv, lens)));
    r = must(c, rds_cmdl(c, "GET", "bin", NULL));
    assert_int_equal(r->type, REDIS_REPLY_STRING);
    assert_int_equal(r->len, sizeof val);
    assert_memory_equal(r->str, val, sizeof val);
    rds_reply_free(r);
    r = must(c, rds_cmdl(c, "GET", "no-such-key", NULL));
    assert_int_equal(r->type, REDIS_REPLY_NIL);
    rds_reply_free(r);
    /* an error reply keeps the connection */
    assert_null(rds_cmdl(c, "INCR", "bin", NULL));
    assert_int_equal(rds_status_of(c), RDS_EREPLY);
    assert_true(rds_error_is(c, "ERR"));
    assert_non_null(strstr(rds_errmsg(c), "INCR"));
    assert_true(rds_connected(c));
    rds_reply_free(must(c, rds_cmdl(c, "HSET", "h", "a", "1", "b", "22",
                                    NULL)));
    r = must(c, rds_cmdl(c, "HGETALL", "h", NULL));
    {
        long long v = 0;
        assert_int_equal(rds_reply_ll(rds_reply_field(r, "b"), &v), 0);
        assert_int_equal(v, 22);
        assert_null(rds_reply_field(r, "c"));
    }
    rds_reply_free(r);
    rds_free(c);
}

/* The stream commands of the job queue, and the shapes of their replies. */
static void test_stream_group(void **state)
{
    rds *c = need_server(), *d = need_server();
    redisReply *r, *e;
    long long idle1 = 0, idle2 = -1, n = 0;
    char id[64];
    int i;
    (void)state;

    rds_reply_free(must(c, rds_cmdl(c, "XGROUP", "CREATE", "q", "g", "0",
                                    "MKSTREAM", NULL)));
    assert_null(rds_cmdl(c, "XGROUP", "CREATE", "q", "g", "0", "MKSTREAM",
                         NULL));
    assert_true(rds_error_is(c, "BUSYGROUP"));
    for (i = 0; i < 3; i++) {
        char job[16];
        snprintf(job, sizeof job, "j%d", i);
        r = must(c, rds_cmdl(c, "XADD", "q", "MAXLEN", "~", "1000", "*",
                             "job", job, NULL));
        assert_int_equal(r->type, REDIS_REPLY_STRING);
        rds_reply_free(r);
    }
    /* [[stream, [[id, [field, value]]]]] */
    r = must(c, rds_cmd_block(c, 1, 9, (const char *[]){"XREADGROUP",
             "GROUP", "g", "alice", "COUNT", "1", "STREAMS", "q", ">"},
             NULL));
    assert_true(rds_reply_is(c, r, REDIS_REPLY_ARRAY, "XREADGROUP"));
    e = r->element[0]->element[1]->element[0];
    assert_int_equal(e->element[0]->type, REDIS_REPLY_STRING);
    snprintf(id, sizeof id, "%s", e->element[0]->str);
    assert_string_equal(rds_reply_field(e->element[1], "job")->str, "j0");
    rds_reply_free(r);
    /* an idle wait: nil after BLOCK */
    rds_reply_free(must(c, rds_cmdl(c, "XREADGROUP", "GROUP", "g", "bob",
                                    "COUNT", "5", "STREAMS", "q", ">",
                                    NULL)));
    r = must(c, rds_cmd_block(c, 0.1, 11, (const char *[]){"XREADGROUP",
             "GROUP", "g", "bob", "COUNT", "1", "BLOCK", "100", "STREAMS",
             "q", ">"}, NULL));
    assert_int_equal(r->type, REDIS_REPLY_NIL);
    rds_reply_free(r);
    /* the heartbeat: XCLAIM ... JUSTID by the owner resets the idle time
     * and not the delivery count */
    sleep_s(0.2);
    r = must(c, rds_cmdl(c, "XPENDING", "q", "g", "-", "+", "10", "alice",
                         NULL));
    assert_int_equal(rds_reply_ll(r->element[0]->element[2], &idle1), 0);
    rds_reply_free(r);
    assert_true(idle1 >= 150);
    rds_reply_free(must(c, rds_cmdl(c, "XCLAIM", "q", "g", "alice", "0", id,
                                    "JUSTID", NULL)));
    r = must(c, rds_cmdl(c, "XPENDING", "q", "g", "-", "+", "10", "alice",
                         NULL));
    assert_int_equal(rds_reply_ll(r->element[0]->element[2], &idle2), 0);
    assert_int_equal(rds_reply_ll(r->element[0]->element[3], &n), 0);
    rds_reply_free(r);
    assert_true(idle2 < idle1);
    assert_int_equal(n, 1);
    /* the reaper on another connection: XAUTOCLAIM takes what is idle
     * above the bound: [next, [[id, fields]...], [deleted ids]] (7.0) */
    sleep_s(0.2);
    r = must(d, rds_cmdl(d, "XAUTOCLAIM", "q", "g", "carol", "100", "0-0",
                         "COUNT", "10", NULL));
    assert_int_equal(r->type, REDIS_REPLY_ARRAY);
    assert_int_equal(r->elements, 3);
    assert_int_equal(r->element[1]->elements, 3);  /* alice's and bob's */
    rds_reply_free(r);
    r = must(c, rds_cmdl(c, "XPENDING", "q", "g", "-", "+", "10", NULL));
    for (i = 0; i < (int)r->elements; i++) {
        assert_string_equal(r->element[i]->element[1]->str, "carol");
        assert_int_equal(rds_reply_ll(r->element[i]->element[3], &n), 0);
        assert_int_equal(n, 2);  /* delivered twice */
    }
    rds_reply_free(r);
    expect_int(c, rds_cmdl(c, "XACK", "q", "g", id, NULL), 1);
    expect_int(c, rds_cmdl(c, "XACK", "q", "g", id, NULL), 0);
    rds_reply_free(must(c, rds_cmdl(c, "DEL", "q", NULL)));
    rds_free(c);
    rds_free(d);
}

/* A reply over max_reply fails cleanly and the connection comes back. */
static void test_bounded_reply(void **state)
{
    rds_config cfg;
    rds *c = need_server(), *small;
    redisReply *r;
    size_t big = (size_t)1 << 20;
    char *val = malloc(big);
    const char *argv[3] = {"SET", "big", val};
    size_t lens[3] = {3, 3, big};
    int i;
    (void)state;

    memset(val, 'x', big);
    rds_reply_free(must(c, rds_cmd(c, 3, argv, lens)));
    free(val);
    for (i = 0; i < 2000; i++) {   /* 2000 small elements: 128 KiB of objects */
        char v[16];
        snprintf(v, sizeof v, "%d", i);
        rds_reply_free(must(c, rds_cmdl(c, "RPUSH", "list", v, NULL)));
    }
    cfg = cfg_of(S.port);
    cfg.max_reply = 64 << 10;
    small = rds_new(&cfg);
    assert_null(rds_cmdl(small, "GET", "big", NULL));
    assert_int_equal(rds_status_of(small), RDS_EPROTO);
    assert_non_null(strstr(rds_errmsg(small), "reply over 65536 bytes"));
    assert_false(rds_connected(small));
    assert_null(rds_cmdl(small, "LRANGE", "list", "0", "-1", NULL));
    assert_int_equal(rds_status_of(small), RDS_EPROTO);
    /* slices fit */
    r = must(small, rds_cmdl(small, "GETRANGE", "big", "0", "32767", NULL));
    assert_int_equal(r->len, 32768);
    rds_reply_free(r);
    r = must(small, rds_cmdl(small, "LRANGE", "list", "0", "99", NULL));
    assert_int_equal(r->elements, 100);
    rds_reply_free(r);
    rds_reply_free(must(c, rds_cmdl(c, "DEL", "big", "list", NULL)));
    rds_free(small);
    rds_free(c);
}

/* A reply that does not come within the deadline fails the call. */
static void test_deadline(void **state)
{
    rds_config cfg;
    rds *c;
    redisReply *r;
    (void)state;

    rds_free(need_server());
    cfg = cfg_of(S.port);
    cfg.command_timeout = 0.2;
    c = rds_new(&cfg);
    /* the server blocks for 2 s; the client gives up after 0.2 */
    assert_null(rds_cmdl(c, "BLPOP", "nothing", "2", NULL));
    assert_int_equal(rds_status_of(c), RDS_EDOWN);
    assert_non_null(strstr(rds_errmsg(c), "no answer within 0.2 s"));
    assert_false(rds_connected(c));
    /* with the block's time added it waits */
    r = must(c, rds_cmd_block(c, 0.5, 3, (const char *[]){"BLPOP", "nothing",
                                                           "0.4"}, NULL));
    assert_int_equal(r->type, REDIS_REPLY_NIL);
    rds_reply_free(r);
    rds_free(c);
}

/* Nothing listens: the call fails at once with the reason, and the next
 * one before the backoff is over does not even try. */
static void test_unreachable_backoff(void **state)
{
    rds_config cfg = cfg_of(free_port());
    rds *c = rds_new(&cfg);
    (void)state;

    assert_null(rds_cmdl(c, "PING", NULL));
    assert_int_equal(rds_status_of(c), RDS_EDOWN);
    assert_non_null(strstr(rds_errmsg(c), "refused"));
    assert_null(rds_cmdl(c, "PING", NULL));
    assert_int_equal(rds_status_of(c), RDS_EDOWN);
    assert_non_null(strstr(rds_errmsg(c), "refused"));
    assert_non_null(strstr(rds_errmsg(c), "next attempt in"));
    rds_free(c);
}

/* AUTH with a password from a file; the password is in no message. */
static void test_auth(void **state)
{
    char path[128], msg[512];
    rds_config cfg;
    rds *admin = need_server(), *c;
    FILE *f;
    (void)state;

    snprintf(path, sizeof path, "%s/password", S.dir);
    f = fopen(path, "w");
    fputs("s3cret-pw\n", f);    /* a trailing newline, as editors leave */
    fclose(f);
    rds_reply_free(must(admin, rds_cmdl(admin, "CONFIG", "SET", "requirepass",
                                        "s3cret-pw", NULL)));
    cfg = cfg_of(S.port);
    c = rds_new(&cfg);                               /* no password */
    assert_null(rds_cmdl(c, "GET", "k", NULL));
    assert_true(rds_error_is(c, "NOAUTH"));
    rds_free(c);
    snprintf(cfg.password_file, sizeof cfg.password_file, "%s", path);
    c = rds_new(&cfg);                               /* the file's */
    rds_reply_free(must(c, rds_cmdl(c, "SET", "k", "v", NULL)));
    rds_free(c);
    f = fopen(path, "w");
    fputs("wrong-pw", f);
    fclose(f);
    c = rds_new(&cfg);
    assert_null(rds_cmdl(c, "GET", "k", NULL));
    snprintf(msg, sizeof msg, "%s", rds_errmsg(c));
    assert_true(rds_error_is(c, "WRONGPASS"));
    assert_null(strstr(msg, "wrong-pw"));
    rds_free(c);
    snprintf(cfg.password_file, sizeof cfg.password_file, "%s/none", S.dir);
    c = rds_new(&cfg);
    assert_null(rds_cmdl(c, "GET", "k", NULL));
    assert_int_equal(rds_status_of(c), RDS_ECONFIG);
    assert_non_null(strstr(rds_errmsg(c), "/none"));
    rds_free(c);
    /* back to no password: the admin connection is still authenticated */
    rds_reply_free(must(admin, rds_cmdl(admin, "CONFIG", "SET", "requirepass",
                                        "", NULL)));
    rds_free(admin);
}

static void test_select(void **state)
{
    rds_config cfg;
    rds *c0 = need_server(), *c3;
    redisReply *r;
    (void)state;

    cfg = cfg_of(S.port);
    cfg.db = 3;
    c3 = rds_new(&cfg);
    rds_reply_free(must(c3, rds_cmdl(c3, "SET", "in3", "x", NULL)));
    r = must(c0, rds_cmdl(c0, "EXISTS", "in3", NULL));
    assert_int_equal(r->integer, 0);
    rds_reply_free(r);
    rds_reply_free(must(c3, rds_cmdl(c3, "DEL", "in3", NULL)));
    rds_free(c3);
    rds_free(c0);
}

static void test_pipeline(void **state)
{
    rds *c = need_server();
    int i;
    (void)state;

    rds_reply_free(must(c, rds_cmdl(c, "DEL", "n", NULL)));
    for (i = 0; i < 100; i++)
        assert_int_equal(rds_pipe_add(c, 2, (const char *[]){"INCR", "n"},
                                      NULL), 0);
    assert_int_equal(rds_pipe_add(c, 2, (const char *[]){"LPOP", "n"}, NULL),
                     0);  /* WRONGTYPE, then the connection goes on */
    assert_int_equal(rds_pipe_add(c, 2, (const char *[]){"GET", "n"}, NULL),
                     0);
    for (i = 0; i < 100; i++)
        expect_int(c, rds_pipe_read(c), i + 1);
    assert_null(rds_pipe_read(c));
    assert_true(rds_error_is(c, "WRONGTYPE"));
    expect_int(c, rds_pipe_read(c), 100);
    assert_null(rds_pipe_read(c));                  /* nothing pending */
    rds_free(c);
}

static rds_script incr_by = {
    "return redis.call('INCRBY', KEYS[1], ARGV[1])", ""};

static void test_script(void **state)
{
    rds *c = need_server();
    (void)state;

    rds_reply_free(must(c, rds_cmdl(c, "SET", "s", "10", NULL)));
    expect_int(c, rds_eval(c, &incr_by, 1, 2, (const char *[]){"s", "5"},
                           NULL), 15);
    /* a restarted server forgets its scripts: loaded again */
    rds_reply_free(must(c, rds_cmdl(c, "SCRIPT", "FLUSH", NULL)));
    expect_int(c, rds_eval(c, &incr_by, 1, 2, (const char *[]){"s", "1"},
                           NULL), 16);
    rds_free(c);
}

#define POOL_THREADS 4
#define POOL_INCRS 200

static void *pool_worker(void *arg)
{
    rds_pool *p = arg;
    int i, bad = 0;

    for (i = 0; i < POOL_INCRS; i++) {
        rds *c = rds_pool_get(p);
        redisReply *r = rds_cmdl(c, "INCR", "pooled", NULL);
        bad += !r;
        rds_reply_free(r);
        rds_pool_put(p, c);
    }
    return (void *)(intptr_t)bad;
}

static void test_pool(void **state)
{
    rds_config cfg;
    rds *c = need_server();
    rds_pool *p;
    pthread_t t[POOL_THREADS];
    int i;
    (void)state;

    rds_reply_free(must(c, rds_cmdl(c, "DEL", "pooled", NULL)));
    cfg = cfg_of(S.port);
    p = rds_pool_new(&cfg, 2);
    assert_non_null(p);
    for (i = 0; i < POOL_THREADS; i++)
        pthread_create(&t[i], NULL, pool_worker, p);
    for (i = 0; i < POOL_THREADS; i++) {
        void *bad;
        pthread_join(t[i], &bad);
        assert_int_equal((intptr_t)bad, 0);
    }
    rds_pool_free(p);
    expect_int(c, rds_cmdl(c, "GET", "pooled", NULL),
               POOL_THREADS * POOL_INCRS);
    rds_free(c);
}

/* The server gone and back: once one pooled connection reaches it, the
 * others stop backing off. Before, a connection deep in its backoff (up to
 * 2.5 s) refused its caller although the server answered the other one:
 * /readyz said 200 and the next submission got 503 (test_replicas). */
static void test_pool_after_outage(void **state)
{
    redisd d = {0};
    rds_config cfg;
    rds_pool *p;
    rds *a, *b;
    redisReply *r = NULL;
    const char *m;
    double wait = 0;
    int i;
    (void)state;

    d.port = free_port();
    cfg = redisd_config(&d);
    p = rds_pool_new(&cfg, 2);
    assert_non_null(p);
    a = rds_pool_get(p);
    b = rds_pool_get(p);
    /* b fails until its next attempt is at least a second away (backoff
     * 0.05 s doubling, jitter 0.75-1.25: the sixth failure) */
    for (i = 0; i < 40 && wait < 1.0; i++) {
        assert_null(rds_cmdl(b, "PING", NULL));
        assert_int_equal(rds_status_of(b), RDS_EDOWN);
        m = strstr(rds_errmsg(b), "next attempt in ");
        wait = m ? atof(m + 16) : 0;
        if (m && wait < 1.0)
            sleep_s(wait + 0.01);
    }
    assert_true(wait >= 1.0);
    assert_null(rds_cmdl(a, "PING", NULL));   /* a backs off 0.05 s */
    if (redisd_start(&d) != 0)
        fail_msg("redis-server did not start: %s", d.why);
    /* b must still be backing off for the check to mean anything; a
     * start slower than its second (a loaded machine) proves nothing */
    if ((r = rds_cmdl(b, "PING", NULL)) != NULL) {
        rds_reply_free(r);
        rds_pool_put(p, a);
        rds_pool_put(p, b);
        rds_pool_free(p);
        redisd_cleanup(&d);
        skip();
    }
    rds_pool_put(p, b);
    for (i = 0; i < 100 && !(r = rds_cmdl(a, "PING", NULL)); i++)
        sleep_s(0.02);                         /* a's short backoff */
    assert_non_null(r);
    rds_reply_free(r);
    rds_pool_put(p, a);                        /* up: wakes b */
    assert_ptr_equal(rds_pool_get(p), a);      /* the pool is a stack */
    assert_ptr_equal(rds_pool_get(p), b);
    r = rds_cmdl(b, "PING", NULL);
    if (!r)
        fail_msg("b refused with the server back: %s", rds_errmsg(b));
    rds_reply_free(r);
    rds_pool_put(p, a);
    rds_pool_put(p, b);
    rds_pool_free(p);
    redisd_cleanup(&d);
}

/* The server restarted while the connection sat idle: its socket is at
 * end-of-file, and the next command connects again instead of failing on
 * it. Before, that command failed (RDS_EDOWN): a pooled connection that
 * had not been used during an outage refused the first submission after
 * /readyz said 200 (test_replicas, CI of 2026-11-29 under ASan). */
static void test_idle_across_restart(void **state)
{
    redisd d = {0};
    rds_config cfg;
    rds *c;
    redisReply *r;
    (void)state;

    d.port = free_port();
    if (redisd_start(&d) != 0)
        fail_msg("redis-server did not start: %s", d.why);
    cfg = redisd_config(&d);
    c = rds_new(&cfg);
    assert_non_null(c);
    rds_reply_free(must(c, rds_cmdl(c, "SET", "idle", "1", NULL)));
    redisd_stop(&d, SIGTERM);
    if (redisd_start(&d) != 0)
        fail_msg("redis-server did not come back: %s", d.why);
    assert_true(rds_connected(c));          /* the old socket, at EOF */
    r = rds_cmdl(c, "GET", "idle", NULL);
    if (!r)
        fail_msg("the first command after the restart failed: %s", rds_errmsg(c));
    assert_string_equal(r->str, "1");       /* the AOF kept it */
    rds_reply_free(r);
    rds_free(c);
    redisd_cleanup(&d);
}

static int resubscribe(rds *c, void *ctx)
{
    redisReply *r = rds_cmdl(c, "SUBSCRIBE", (const char *)ctx, NULL);
    rds_reply_free(r);
    return r ? 0 : -1;
}

/* A subscriber waits with a timeout and hears what is published. */
static void test_subscriber(void **state)
{
    rds *pub = need_server(), *sub = need_server();
    redisReply *r;
    (void)state;

    rds_set_on_connect(sub, resubscribe, "chan");
    assert_int_equal(rds_connect(sub), 0);
    assert_int_equal(rds_wait(sub, 0.05, &r), 1);   /* nothing yet */
    assert_true(rds_connected(sub));
    expect_int(pub, rds_cmdl(pub, "PUBLISH", "chan", "hello", NULL), 1);
    assert_int_equal(rds_wait(sub, 2, &r), 0);
    assert_int_equal(r->elements, 3);
    assert_string_equal(r->element[0]->str, "message");
    assert_string_equal(r->element[2]->str, "hello");
    rds_reply_free(r);
    /* the connection is killed: the hook subscribes again */
    rds_reply_free(must(pub, rds_cmdl(pub, "CLIENT", "KILL", "TYPE", "pubsub",
                                      NULL)));
    assert_int_equal(rds_wait(sub, 1, &r), -1);
    assert_int_equal(rds_status_of(sub), RDS_EDOWN);
    assert_int_equal(rds_wait(sub, 0.05, &r), 1);   /* reconnected */
    expect_int(pub, rds_cmdl(pub, "PUBLISH", "chan", "again", NULL), 1);
    assert_int_equal(rds_wait(sub, 2, &r), 0);
    assert_string_equal(r->element[2]->str, "again");
    rds_reply_free(r);
    rds_free(sub);
    rds_free(pub);
}

/* kill -9 of the server: what it acknowledged is in its append-only file
 * and back after the restart; the client reconnects by itself. */
static void test_restart_keeps_acknowledged(void **state)
{
    rds *c = need_server();
    redisReply *r = NULL;
    double end;
    (void)state;

    rds_reply_free(must(c, rds_cmdl(c, "XADD", "durable", "*", "job", "a",
                                    NULL)));
    rds_reply_free(must(c, rds_cmdl(c, "SET", "acked", "yes", NULL)));
    server_stop(SIGKILL);
    assert_null(rds_cmdl(c, "GET", "acked", NULL));
    assert_int_equal(rds_status_of(c), RDS_EDOWN);
    if (server_start() != 0)
        fail_msg("redis-server did not come back: %s", S.why);
    end = now_s() + 10;   /* the backoff is at most 2 s */
    while (!r && now_s() < end) {
        r = rds_cmdl(c, "GET", "acked", NULL);
        if (!r)
            sleep_s(0.05);
    }
    must(c, r);
    assert_string_equal(r->str, "yes");
    rds_reply_free(r);
    expect_int(c, rds_cmdl(c, "XLEN", "durable", NULL), 1);
    rds_free(c);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_url),
        cmocka_unit_test(test_binary_values),
        cmocka_unit_test(test_stream_group),
        cmocka_unit_test(test_bounded_reply),
        cmocka_unit_test(test_deadline),
        cmocka_unit_test(test_unreachable_backoff),
        cmocka_unit_test(test_auth),
        cmocka_unit_test(test_select),
        cmocka_unit_test(test_pipeline),
        cmocka_unit_test(test_script),
        cmocka_unit_test(test_pool),
        cmocka_unit_test(test_pool_after_outage),
        cmocka_unit_test(test_idle_across_restart),
        cmocka_unit_test(test_subscriber),
        cmocka_unit_test(test_restart_keeps_acknowledged),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
