/* SPDX-License-Identifier: MIT */
/*
 * rstore_queue.c - the job store in Redis, its queue (rstore.h says the
 * semantics): pushing, claiming and taking a job, acknowledging, dropping,
 * heartbeats, the reaper, dead letters, and progress.
 */
#include <errno.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "rstore_internal.h"

/* --------------------------------------------------------- the scripts */

/* KEYS: stream, hash. ARGV: id, queue_max. A job already waiting keeps
 * its entry. */
static rds_script lua_push = {
    "if redis.call('EXISTS', KEYS[2]) == 0 then\n"
    "  return redis.error_reply('NOJOB no such job') end\n"
    "local q = redis.call('HMGET', KEYS[2], 'queued', 'qstream')\n"
    "if q[1] and #redis.call('XRANGE', q[2], q[1], q[1]) > 0 then\n"
    "  return q[1] end\n"
    "if redis.call('XLEN', KEYS[1]) >= tonumber(ARGV[2]) then\n"
    "  return redis.error_reply('FULL the shared queue is full') end\n"
    "local e = redis.call('XADD', KEYS[1], '*', 'job', ARGV[1])\n"
    "redis.call('HSET', KEYS[2], 'queued', e, 'qstream', KEYS[1])\n"
    "return e\n", ""};

/* KEYS: stream, hash, dead. ARGV: group, entry, consumer, max_runs,
 * dead_max, id, claim_idle in ms. {0}: not ours (any more), {-1}: gone
 * or a duplicate (acknowledged), {1, runs, retaken}, {2, runs}: dead. */
static rds_script lua_take = {
    "local function done()\n"
    "  redis.call('XACK', KEYS[1], ARGV[1], ARGV[2])\n"
    "  redis.call('XDEL', KEYS[1], ARGV[2])\n"
    "end\n"
    "local p = redis.call('XPENDING', KEYS[1], ARGV[1], ARGV[2], ARGV[2], 1)\n"
    "if #p == 0 or p[1][2] ~= ARGV[3] then return {0} end\n"
    "if redis.call('EXISTS', KEYS[2]) == 0 or\n"
    "   #redis.call('XRANGE', KEYS[1], ARGV[2], ARGV[2]) == 0 then\n"
    "  done() return {-1} end\n"
    /* another entry of the job is running and heartbeating: this one is
     * a duplicate (a job queued again while its old entry was pending) */
    "local cur = redis.call('HMGET', KEYS[2], 'entry', 'stream')\n"
    "if cur[1] and cur[1] ~= ARGV[2] then\n"
    "  local q = redis.call('XPENDING', cur[2], ARGV[1], cur[1], cur[1], 1)\n"
    "  if #q > 0 and q[1][3] < tonumber(ARGV[7]) then done() return {-1} end\n"
    "  if #q > 0 then\n"
    "    redis.call('XACK', cur[2], ARGV[1], cur[1])\n"
    "    redis.call('XDEL', cur[2], cur[1]) end\n"
    "end\n"
    "local runs = redis.call('HINCRBY', KEYS[2], 'runs', 1)\n"
    "if runs > tonumber(ARGV[4]) then\n"
    "  redis.call('XADD', KEYS[3], 'MAXLEN', '~', ARGV[5], '*', 'job', "
    "ARGV[6], 'runs', runs - 1, 'reason', 'its replica stopped during each "
    "of ' .. (runs - 1) .. ' runs')\n"
    "  redis.call('HDEL', KEYS[2], 'runner', 'entry', 'stream', 'queued', "
    "'qstream')\n"
    "  done() return {2, runs - 1} end\n"
    "local prev = redis.call('HGET', KEYS[2], 'runner')\n"
    "redis.call('HSET', KEYS[2], 'runner', ARGV[3], 'entry', ARGV[2], "
    "'stream', KEYS[1])\n"
    "redis.call('HDEL', KEYS[2], 'queued', 'qstream')\n"
    "return {1, runs, prev and 1 or 0}\n", ""};

/* KEYS: hash, events. ARGV: group, consumer. 1 acknowledged, 0 nothing
 * running. */
static rds_script lua_ack = {
    "local r = redis.call('HMGET', KEYS[1], 'runner', 'entry', 'stream')\n"
    "if not r[1] then return 0 end\n"
    "if r[1] ~= ARGV[2] then\n"
    "  return redis.error_reply('STALE another replica took the job over') "
    "end\n"
    "redis.call('XACK', r[3], ARGV[1], r[2])\n"
    "redis.call('XDEL', r[3], r[2])\n"
    "redis.call('HDEL', KEYS[1], 'runner', 'entry', 'stream')\n"
    "return 1\n", ""};

/* KEYS: hash, events. ARGV: group, consumer, blob prefix, ttl, then
 * name, data pairs. The end of a run in one step: its blobs written and
 * its entry acknowledged, only by its runner (else STALE, nothing
 * written). A retry of a finish whose reply was lost (nothing running,
 * the last blob, a small one, already these bytes) succeeds. */
static rds_script lua_finish = {
    LUA_TOUCH LUA_WRITE
    "local r = redis.call('HMGET', KEYS[1], 'runner', 'entry', 'stream')\n"
    "if redis.call('EXISTS', KEYS[1]) == 0 then\n"
    "  return redis.error_reply('NOJOB no such job') end\n"
    "if not r[1] and #ARGV >= 6 and redis.call('HGET', KEYS[1], 'b:' .. "
    "ARGV[#ARGV - 1]) == ARGV[#ARGV] then return 1 end\n"
    "if r[1] ~= ARGV[2] then\n"
    "  return redis.error_reply('STALE another replica took the job over') "
    "end\n"
    "for i = 5, #ARGV, 2 do write(KEYS[1], ARGV[3], ARGV[i], ARGV[i + 1]) "
    "end\n"
    "redis.call('XACK', r[3], ARGV[1], r[2])\n"
    "redis.call('XDEL', r[3], r[2])\n"
    "redis.call('HDEL', KEYS[1], 'runner', 'entry', 'stream')\n"
    LUA_MARK("'state.json'")
    "touch(KEYS[1], ARGV[3], KEYS[2], ARGV[4])\n"
    "return 1\n", ""};

/* KEYS: hash, events. 1 dropped, 0 not queued. */
static rds_script lua_drop = {
    "local r = redis.call('HMGET', KEYS[1], 'queued', 'qstream')\n"
    "if not r[1] then return 0 end\n"
    "redis.call('XDEL', r[2], r[1])\n"
    "redis.call('HDEL', KEYS[1], 'queued', 'qstream')\n"
    "return 1\n", ""};

/* KEYS: hash, events. ARGV: group, consumer, blob prefix, ttl. A job
 * whose record is gone (a Redis restarted without persistence, an
 * eviction, a deletion) is NOJOB, not STALE: no replica took it. */
static rds_script lua_heartbeat = {
    LUA_TOUCH
    "if redis.call('EXISTS', KEYS[1]) == 0 then\n"
    "  return redis.error_reply('NOJOB no such job') end\n"
    "local r = redis.call('HMGET', KEYS[1], 'runner', 'entry', 'stream')\n"
    "if r[1] ~= ARGV[2] then\n"
    "  return redis.error_reply('STALE another replica took the job over') "
    "end\n"
    "redis.call('XCLAIM', r[3], ARGV[1], ARGV[2], 0, r[2], 'JUSTID')\n"
    "touch(KEYS[1], ARGV[3], KEYS[2], ARGV[4])\n"
    "return 1\n", ""};

/* KEYS: events. ARGV: line, ev_max, ttl. */
static rds_script lua_progress = {
    "local e = redis.call('XADD', KEYS[1], 'MAXLEN', '~', ARGV[2], '*', "
    "'l', ARGV[1])\n"
    "redis.call('PEXPIRE', KEYS[1], ARGV[3])\n"
    "return e\n", ""};

/* ------------------------------------------------------------ queue */

int rstore_push(rstore *s, const char *id, int front)
{
    job_keys k;
    char max[24];
    const char *argv[4];
    redisReply *r;

    if (rstore__keys(s, id, &k) != 0)
        return -1;
    snprintf(max, sizeof max, "%ld", s->cfg.queue_max);
    argv[0] = front ? s->k_front : s->k_queue;
    argv[1] = k.hash;
    argv[2] = id;
    argv[3] = max;
    if (!(r = rstore__eval(s, &lua_push, 2, 4, argv, NULL)))
        return -1;
    rds_reply_free(r);
    return 0;
}

/* Appends an entry read from a stream to the held list (once). */
static void hold(rstore *s, const char *id, const char *entry, int front)
{
    int i;

    pthread_mutex_lock(&s->mu);
    for (i = 0; i < s->nheld; i++)
        if (strcmp(s->held[i].entry, entry) == 0)
            break;
    if (i == s->nheld && s->nheld < HELD_MAX) {
        held_entry *h = &s->held[s->nheld++];
        snprintf(h->id, sizeof h->id, "%s", id);
        snprintf(h->entry, sizeof h->entry, "%s", entry);
        h->front = front;
    }
    /* beyond HELD_MAX the entry stays pending on this consumer and the
     * reaper of some replica takes it after claim_idle */
    pthread_mutex_unlock(&s->mu);
}

/* Stream entries [[entry, [field, value...]], ...] into the held list;
 * the number of them. */
static int hold_entries(rstore *s, const redisReply *list, int front)
{
    size_t i;
    int n = 0;

    if (!list || list->type != REDIS_REPLY_ARRAY)
        return 0;
    for (i = 0; i < list->elements; i++) {
        const redisReply *e = list->element[i], *job;
        if (e->type != REDIS_REPLY_ARRAY || e->elements != 2 ||
            e->element[0]->type != REDIS_REPLY_STRING ||
            e->element[0]->len >= RSTORE_ID_MAX)
            continue;
        job = rds_reply_field(e->element[1], "job");
        if (!job || job->type != REDIS_REPLY_STRING ||
            !rstore__name_ok(job->str))
            continue;                  /* the reaper acknowledges it */
        hold(s, job->str, e->element[0]->str, front);
        n++;
    }
    return n;
}

/* XAUTOCLAIM of one stream, a few pages: entries taken over. */
static int reap_stream(rstore *s, const char *stream, int front,
                       double min_idle)
{
    char idle[24], start[RSTORE_ID_MAX] = "0-0";
    int pages, n = 0;

    snprintf(idle, sizeof idle, "%lld", (long long)(min_idle * 1000));
    for (pages = 0; pages < 8; pages++) {
        const char *argv[8] = {"XAUTOCLAIM", stream, GROUP,
                               s->cfg.consumer, idle, start, "COUNT", "32"};
        rds *c = rds_pool_get(s->pool);
        redisReply *r = rds_cmd(c, 8, argv, NULL);
        int e = r ? 0 : rstore__errno(c);

        rds_pool_put(s->pool, c);
        if (!r) {
            errno = e;
            return -1;
        }
        /* [next, [[entry, fields]...], [deleted...]] (7.0) */
        if (r->type != REDIS_REPLY_ARRAY || r->elements < 2 ||
            r->element[0]->type != REDIS_REPLY_STRING ||
            r->element[0]->len >= sizeof start) {
            rds_reply_free(r);
            errno = EIO;
            return -1;
        }
        n += hold_entries(s, r->element[1], front);
        snprintf(start, sizeof start, "%s", r->element[0]->str);
        rds_reply_free(r);
        if (strcmp(start, "0-0") == 0)
            break;
    }
    return n;
}

int rstore_reap(rstore *s, double min_idle)
{
    int a, b;

    if (min_idle < 0)
        min_idle = s->cfg.claim_idle;
    if ((a = reap_stream(s, s->k_front, 1, min_idle)) < 0)
        return -1;
    b = reap_stream(s, s->k_queue, 0, min_idle);
    return b < 0 ? -1 : a + b;
}

/* XREADGROUP of one entry from stream: 1 held, 0 none, -1. */
static int read_new(rstore *s, const char *stream, int front, double block)
{
    char ms[24];
    const char *argv[11] = {"XREADGROUP", "GROUP", GROUP, s->cfg.consumer,
                            "COUNT", "1", "BLOCK", ms, "STREAMS", stream,
                            ">"};
    rds *c = rds_pool_get(s->pool);
    redisReply *r;
    int n = 0, e = 0, again;

    snprintf(ms, sizeof ms, "%lld", (long long)(block * 1000));
    for (again = 0; again < 2; again++) {
        r = block > 0 ? rds_cmd_block(c, block, 11, argv, NULL)
                      : rds_cmd(c, 9, (const char *[]){argv[0], argv[1],
                                argv[2], argv[3], argv[4], argv[5], argv[8],
                                argv[9], argv[10]}, NULL);
        /* a Redis that lost the group (no AOF, or FLUSHALL): again */
        if (r || !rds_error_is(c, "NOGROUP") ||
            rstore__make_group(c, stream) != 0)
            break;
    }
    if (!r)
        e = rstore__errno(c);
    rds_pool_put(s->pool, c);
    if (!r) {
        errno = e;
        return -1;
    }
    /* nil, or [[stream, [[entry, fields]]]] */
    if (r->type == REDIS_REPLY_ARRAY && r->elements == 1 &&
        r->element[0]->type == REDIS_REPLY_ARRAY &&
        r->element[0]->elements == 2)
        n = hold_entries(s, r->element[0]->element[1], front);
    rds_reply_free(r);
    return n > 0;
}

/* The take script for h: RSTORE_*, 0 for "not ours", -1. */
static int take(rstore *s, const held_entry *h, char id[RSTORE_ID_MAX],
                int *runs)
{
    job_keys k;
    char max[16], dmax[24], idle[24];
    const char *argv[10];
    redisReply *r;
    long long code = 0, n = 0, retaken = 0;

    rstore__keys(s, h->id, &k);
    snprintf(max, sizeof max, "%d", s->cfg.max_runs);
    snprintf(dmax, sizeof dmax, "%ld", s->cfg.dead_max);
    argv[0] = h->front ? s->k_front : s->k_queue;
    argv[1] = k.hash;
    argv[2] = s->k_dead;
    argv[3] = GROUP;
    argv[4] = h->entry;
    argv[5] = s->cfg.consumer;
    argv[6] = max;
    argv[7] = dmax;
    argv[8] = h->id;
    argv[9] = idle;
    snprintf(idle, sizeof idle, "%lld",
             (long long)(s->cfg.claim_idle * 1000));
    if (!(r = rstore__eval(s, &lua_take, 3, 10, argv, NULL)))
        return -1;
    if (r->type != REDIS_REPLY_ARRAY || r->elements < 1 ||
        rds_reply_ll(r->element[0], &code) != 0 ||
        (r->elements > 1 && rds_reply_ll(r->element[1], &n) != 0) ||
        (r->elements > 2 && rds_reply_ll(r->element[2], &retaken) != 0)) {
        rds_reply_free(r);
        errno = EIO;
        return -1;
    }
    rds_reply_free(r);
    if (code != 1 && code != 2)
        return 0;
    snprintf(id, RSTORE_ID_MAX, "%s", h->id);
    if (runs)
        *runs = (int)n;
    return code == 2 ? RSTORE_DEAD : retaken ? RSTORE_RETAKEN : RSTORE_TAKEN;
}

/* The held head if fits() takes it: 1 and *out (removed from the list),
 * 0 when none or it does not fit. */
static int offer_head(rstore *s, int (*fits)(void *ctx, const char *id),
                      void *ctx, held_entry *out)
{
    int got = 0;

    pthread_mutex_lock(&s->mu);
    if (s->nheld > 0 && (!fits || fits(ctx, s->held[0].id))) {
        *out = s->held[0];
        memmove(&s->held[0], &s->held[1],
                (size_t)(--s->nheld) * sizeof *s->held);
        got = 1;
    }
    pthread_mutex_unlock(&s->mu);
    return got;
}

/* Whether *next has passed (then it is set period seconds on). */
static int due(rstore *s, double *next, double period)
{
    double now = rds_monotonic();
    int d;

    pthread_mutex_lock(&s->mu);
    d = now >= *next;
    if (d)
        *next = now + period;
    pthread_mutex_unlock(&s->mu);
    return d;
}

int rstore_claim(rstore *s, int (*fits)(void *ctx, const char *id),
                 void *ctx, char id[RSTORE_ID_MAX], int *runs)
{
    int step;

    /* a bounded number of rounds: entries that turn out not to be ours
     * (taken over, removed) are skipped, a few at a time */
    for (step = 0; step < 16; step++) {
        held_entry h;
        int rc, nheld;

        if (offer_head(s, fits, ctx, &h)) {
            rc = take(s, &h, id, runs);
            if (rc != 0)
                return rc;
            continue;
        }
        pthread_mutex_lock(&s->mu);
        nheld = s->nheld;
        pthread_mutex_unlock(&s->mu);
        if (nheld > 0)
            return RSTORE_EMPTY;       /* the head does not fit */
        if (due(s, &s->next_reap, s->cfg.claim_idle / 4) &&
            rstore_reap(s, -1) > 0)
            continue;
        if (s->cfg.blob_dir[0] &&
            due(s, &s->next_sweep, s->cfg.blob_sweep))
            (void)rstore_sweep(s);
        if ((rc = read_new(s, s->k_front, 1, 0)) < 0)
            return -1;
        if (rc == 0 && (rc = read_new(s, s->k_queue, 0, s->cfg.block)) < 0)
            return -1;
        if (rc == 0)
            return RSTORE_EMPTY;
    }
    return RSTORE_EMPTY;
}

/* A script on the job's hash, as this consumer (KEYS: hash, events;
 * ARGV: group, consumer, blob prefix, ttl): 0 or -1. */
static int job_script(rstore *s, rds_script *sc, const char *id)
{
    job_keys k;
    const char *argv[6];

    if (rstore__keys(s, id, &k) != 0)
        return -1;
    argv[0] = k.hash;
    argv[1] = k.ev;
    argv[2] = GROUP;
    argv[3] = s->cfg.consumer;
    argv[4] = k.blobs;
    argv[5] = s->ttl_ms;
    return rstore__eval_int(s, sc, 2, 6, argv, NULL, NULL);
}

int rstore_ack(rstore *s, const char *id)
{
    return job_script(s, &lua_ack, id);
}

int rstore_finish(rstore *s, const char *id, const rstore_blob *b, int n)
{
    const char *argv[32];
    size_t lens[32];
    job_keys k;
    rstore_files f;
    int argc = 0;

    if (rstore__keys(s, id, &k) != 0 || n < 0 || 6 + 2 * n > 32) {
        errno = EINVAL;
        return -1;
    }
    argv[argc++] = k.hash;
    argv[argc++] = k.ev;
    argv[argc++] = GROUP;
    argv[argc++] = s->cfg.consumer;
    argv[argc++] = k.blobs;
    argv[argc++] = s->ttl_ms;
    if (rstore__blob_args(s, id, b, n, argv, lens, &argc, &f) != 0)
        return -1;
    return rstore__files_end(
        s, &f,
        rstore__eval_int(s, &lua_finish, 2, argc, argv, lens, NULL) < 0 ? -1
                                                                        : 0);
}

int rstore_drop(rstore *s, const char *id)
{
    return job_script(s, &lua_drop, id);
}

int rstore_heartbeat(rstore *s, const char *id)
{
    return job_script(s, &lua_heartbeat, id);
}

/* ---------------------------------------------------------- progress */

int rstore_progress(rstore *s, const char *id, const char *line,
                    size_t len)
{
    job_keys k;
    char max[24];
    const char *argv[4];
    size_t lens[4];
    redisReply *r;

    if (rstore__keys(s, id, &k) != 0)
        return -1;
    snprintf(max, sizeof max, "%ld", s->cfg.ev_max);
    argv[0] = k.ev;
    argv[1] = line;
    argv[2] = max;
    argv[3] = s->ttl_ms;
    lens[0] = strlen(k.ev);
    lens[1] = len;
    lens[2] = strlen(max);
    lens[3] = strlen(s->ttl_ms);
    if (!(r = rstore__eval(s, &lua_progress, 1, 4, argv, lens)))
        return -1;
    rds_reply_free(r);
    return 0;
}

/* The entries of one stream of an XREAD reply ([[entry, [field, value
 * ...]]...]) after *after: fn(ctx, i, line) per progress line, fn(ctx,
 * i, NULL) per mark (a state change); i -1, the control stream: fn(ctx,
 * -1, id) per cancel; the cursor advanced. The number of entries. */
static int stream_entries(const redisReply *list, int i, char *after,
                          rstore_watch_fn fn, void *ctx)
{
    size_t e;
    int n = 0;

    for (e = 0; e < list->elements; e++) {
        const redisReply *x = list->element[e], *l;
        if (x->type != REDIS_REPLY_ARRAY || x->elements != 2 ||
            x->element[0]->type != REDIS_REPLY_STRING ||
            x->element[0]->len >= RSTORE_ID_MAX)
            continue;
        snprintf(after, RSTORE_ID_MAX, "%s", x->element[0]->str);
        l = rds_reply_field(x->element[1], i < 0 ? "job" : "l");
        if (l && l->type == REDIS_REPLY_STRING)
            fn(ctx, i, l->str, l->len);
        else if (rds_reply_field(x->element[1], "s"))
            fn(ctx, i, NULL, 0);
        else
            continue;
        n++;
    }
    return n;
}

/* rstore_watch, and with ctl 0 without the control stream (its cursor
 * is the watching thread's alone). */
static int read_streams(rstore *s, int n, const char *const *ids,
                        char (*after)[RSTORE_ID_MAX], int ctl, double block,
                        rstore_watch_fn fn, void *ctx)
{
    char ms[24];
    const char **argv;
    job_keys *k;
    redisReply *r = NULL;
    size_t i;
    int a = 0, j, got = 0, e = EIO;

    if (n < 0 || n > RSTORE_WATCH_MAX) {
        errno = EINVAL;
        return -1;
    }
    argv = calloc((size_t)(8 + 2 * n), sizeof *argv);
    k = calloc((size_t)n + 1, sizeof *k);
    if (!argv || !k) {
        free(argv);
        free(k);
        errno = ENOMEM;
        return -1;
    }
    argv[a++] = "XREAD";
    argv[a++] = "COUNT";
    argv[a++] = "256";
    /* block <= 0: what is there now (XREAD BLOCK 0 would wait for ever) */
    if (block > 0) {
        snprintf(ms, sizeof ms, "%lld", (long long)(block * 1000));
        argv[a++] = "BLOCK";
        argv[a++] = ms;
    }
    argv[a++] = "STREAMS";
    for (j = 0; j < n; j++) {
        if (rstore__keys(s, ids[j], &k[j]) != 0) {
            e = errno;
            goto out;
        }
        argv[a + j] = k[j].ev;
        argv[a + n + ctl + j] = after[j];
    }
    if (ctl) {                 /* this replica's control stream, last */
        argv[a + n] = s->k_ctl;
        argv[a + 2 * n + 1] = s->ctl_after;
    }
    if (!(r = rstore__cmd(s, block > 0 ? block : 0, a + 2 * (n + ctl),
                          argv))) {
        e = errno;
        goto out;
    }
    /* nil: nothing within the block; else [[stream, [entry...]]...] */
    if (r->type != REDIS_REPLY_NIL && r->type != REDIS_REPLY_ARRAY)
        goto out;
    for (i = 0; r->type == REDIS_REPLY_ARRAY && i < r->elements; i++) {
        const redisReply *st = r->element[i];
        if (st->type != REDIS_REPLY_ARRAY || st->elements != 2 ||
            st->element[0]->type != REDIS_REPLY_STRING ||
            st->element[1]->type != REDIS_REPLY_ARRAY)
            goto out;
        if (ctl && !strcmp(s->k_ctl, st->element[0]->str)) {
            got += stream_entries(st->element[1], -1, s->ctl_after, fn, ctx);
            continue;
        }
        for (j = 0; j < n && strcmp(k[j].ev, st->element[0]->str); j++)
            ;
        if (j < n)
            got += stream_entries(st->element[1], j, after[j], fn, ctx);
    }
    e = 0;
out:
    rds_reply_free(r);
    free(argv);
    free(k);
    errno = e;
    return e ? -1 : got;
}

int rstore_watch(rstore *s, int n, const char *const *ids,
                 char (*after)[RSTORE_ID_MAX], double block,
                 rstore_watch_fn fn, void *ctx)
{
    return read_streams(s, n, ids, after, 1, block, fn, ctx);
}

typedef struct {
    void (*fn)(const char *line, size_t len, void *ctx);
    void *ctx;
    int lines;
} lines_only;

static void line_of(void *ctx, int i, const char *line, size_t len)
{
    lines_only *o = ctx;

    (void)i;
    if (line) {
        o->fn(line, len, o->ctx);
        o->lines++;
    }
}

int rstore_events(rstore *s, const char *id, char after[RSTORE_ID_MAX],
                  double block,
                  void (*fn)(const char *line, size_t len, void *ctx),
                  void *ctx)
{
    lines_only o = {fn, ctx, 0};

    return read_streams(s, 1, &id, (char (*)[RSTORE_ID_MAX])after, 0, block,
                        line_of, &o) < 0
               ? -1
               : o.lines;
}
