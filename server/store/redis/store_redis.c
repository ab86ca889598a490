/* SPDX-License-Identifier: MIT */
/*
 * store_redis.c - the job service's store (store.h) in Redis: the
 * operations of rstore.h behind the store's table, plus what the service
 * does not do itself for a shared queue: the fence on the writes of the
 * jobs this replica runs (a replica whose run was taken over writes
 * nothing more).
 *
 * Any number of mcfd replicas share one store (the service's part is
 * svc_shared.c). A replica that dies leaves its running jobs pending on
 * its consumer: the reaper of another replica takes them after
 * claim_idle seconds without heartbeat (MCFD_REDIS_CLAIM_IDLE, 30 s by
 * default; tests set it short); a job whose replica stopped during each
 * of max_runs runs (MCFD_REDIS_MAX_RUNS, 3) is failed, not run again.
 */
#include <errno.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "rstore.h"
#include "srv.h"
#include "store.h"

#define RUNNING_MAX 1024       /* jobs one mcfd runs at once: --workers' most */

typedef struct {
    svc_store base;
    rstore *rs;
    pthread_mutex_t mu;        /* running */
    char running[RUNNING_MAX][SVC_ID_LEN + 1];
    int nrunning;
} rstore_st;

static rstore_st *of(svc_store *st) { return (rstore_st *)st; }

/* ------------------------------------------------- the jobs it runs */

static int running_index_locked(const rstore_st *r, const char *id)
{
    int i;
    for (i = 0; i < r->nrunning; i++)
        if (strcmp(r->running[i], id) == 0)
            return i;
    return -1;
}

static int is_running(rstore_st *r, const char *id)
{
    int i;
    pthread_mutex_lock(&r->mu);
    i = running_index_locked(r, id);
    pthread_mutex_unlock(&r->mu);
    return i >= 0;
}

static void set_running(rstore_st *r, const char *id, int on)
{
    int i;

    pthread_mutex_lock(&r->mu);
    i = running_index_locked(r, id);
    if (on && i < 0 && r->nrunning < RUNNING_MAX)
        snprintf(r->running[r->nrunning++], SVC_ID_LEN + 1, "%s", id);
    else if (!on && i >= 0)
        memcpy(r->running[i], r->running[--r->nrunning], SVC_ID_LEN + 1);
    pthread_mutex_unlock(&r->mu);
}

/* ------------------------------------------------------- the table */

static void rd_close(svc_store *st)
{
    rstore_st *r = of(st);

    rstore_close(r->rs);
    pthread_mutex_destroy(&r->mu);
    free(r);
}

static int rd_ready(svc_store *st, char *why, size_t size)
{
    return rstore_ready(of(st)->rs, why, size);
}

#define BLOBS_MAX 12            /* blobs of one create or finish */

/* The store's blobs as rstore's: 0, or -1 (EINVAL: too many). */
static int to_rstore(const svc_blob *blobs, int n, rstore_blob *b)
{
    int i;

    if (n < 0 || n > BLOBS_MAX) {
        errno = EINVAL;
        return -1;
    }
    for (i = 0; i < n; i++)
        b[i] = (rstore_blob){blobs[i].name, blobs[i].data, blobs[i].len};
    return 0;
}

static int rd_create(svc_store *st, const char *id, const svc_blob *blobs,
                     int n)
{
    rstore_blob b[BLOBS_MAX];

    if (to_rstore(blobs, n, b) != 0)
        return -1;
    return rstore_create(of(st)->rs, id, b, n);
}

static int rd_put(svc_store *st, const char *id, const char *name,
                  const void *data, size_t len, int durable)
{
    rstore_st *r = of(st);
    int fence = durable == SVC_PUT_UNCLAIMED ? RSTORE_UNCLAIMED
                                             : is_running(r, id);

    /* every acknowledged write is in Redis's append-only file */
    if (rstore_put(r->rs, id, name, data, len, fence) == 0)
        return 0;
    if (errno == ESTALE)
        set_running(r, id, 0);
    return -1;
}

static int rd_get(svc_store *st, const char *id, const char *name,
                  char **data, size_t *len)
{
    return rstore_get(of(st)->rs, id, name, data, len);
}

static int rd_get_at(svc_store *st, const char *id, const char *name,
                     size_t off, void *buf, size_t len)
{
    return rstore_get_at(of(st)->rs, id, name, off, buf, len);
}

static int rd_stat(svc_store *st, const char *id, const char *name,
                   size_t *size)
{
    return rstore_stat(of(st)->rs, id, name, size);
}

static int rd_open(svc_store *st, const char *id, const char *name, int *fd,
                   size_t *size)
{
    (void)st;
    (void)id;
    (void)name;
    (void)fd;
    (void)size;
    errno = ENOTSUP;
    return -1;
}

static int rd_remove(svc_store *st, const char *id)
{
    return rstore_remove(of(st)->rs, id);
}

static int rd_quarantine(svc_store *st, const char *id)
{
    return rstore_quarantine(of(st)->rs, id);
}

static size_t rd_usage(svc_store *st, const char *id)
{
    return rstore_usage(of(st)->rs, id);
}

static int rd_scan(svc_store *st, void (*fn)(const char *id, void *ctx),
                   void *ctx)
{
    return rstore_scan(of(st)->rs, fn, ctx);
}

static int rd_push(svc_store *st, const char *id, int front)
{
    return rstore_push(of(st)->rs, id, front);
}

static int rd_claim(svc_store *st, int (*fits)(void *ctx, const char *id),
                    void *ctx, char id[SVC_ID_LEN + 1])
{
    rstore_st *r = of(st);
    char got[RSTORE_ID_MAX];
    int runs = 0, rc = rstore_claim(r->rs, fits, ctx, got, &runs);

    if (rc != RSTORE_TAKEN && rc != RSTORE_RETAKEN && rc != RSTORE_DEAD)
        return 0;
    if (strlen(got) > SVC_ID_LEN) {      /* not an id this service made */
        if (rc != RSTORE_DEAD)
            rstore_ack(r->rs, got);
        return 0;
    }
    memcpy(id, got, strlen(got) + 1);
    if (rc == RSTORE_DEAD) {
        srv_logf(SRV_LOG_ERROR, "job %s: dead-lettered after %d runs whose "
                 "replica stopped each time", got, runs);
        return 3;
    }
    set_running(r, id, 1);
    return rc == RSTORE_RETAKEN ? 2 : 1;
}

static int rd_ack(svc_store *st, const char *id)
{
    rstore_st *r = of(st);
    int rc = rstore_ack(r->rs, id);

    set_running(r, id, 0);
    return rc;
}

static int rd_drop(svc_store *st, const char *id)
{
    return rstore_drop(of(st)->rs, id);
}

/* A job taken over (ESTALE) leaves the set: its writes are refused from
 * now. */
static int rd_heartbeat(svc_store *st, const char *id)
{
    rstore_st *r = of(st);

    if (rstore_heartbeat(r->rs, id) == 0)
        return 0;
    if (errno == ENOENT && is_running(r, id)) {
        srv_logf(SRV_LOG_ERROR, "job %s: its records are gone from Redis "
                 "while it runs here (a restart of a Redis without "
                 "persistence, an eviction, or a deletion): its outcome "
                 "cannot be recorded", id);
        set_running(r, id, 0);
        errno = ENOENT;
    } else if (errno == ESTALE && is_running(r, id)) {
        srv_logf(SRV_LOG_WARN, "job %s: another replica took it over (no "
                 "heartbeat for too long); its writes from here are refused",
                 id);
        set_running(r, id, 0);
        errno = ESTALE;
    }
    return -1;
}

static int rd_progress(svc_store *st, const char *id, const char *line,
                       size_t len)
{
    return rstore_progress(of(st)->rs, id, line, len);
}

static int rd_follow(svc_store *st, const char *id, char *after,
                     void (*fn)(const char *line, size_t len, void *ctx),
                     void *ctx)
{
    _Static_assert(SVC_CURSOR_LEN == RSTORE_ID_MAX, "a follow cursor");
    return rstore_events(of(st)->rs, id, after, 0, fn, ctx);
}

static int rd_watch(svc_store *st, int n, const char *const *ids,
                    char (*after)[SVC_CURSOR_LEN], double block,
                    void (*fn)(void *ctx, int i, const char *line,
                               size_t len),
                    void *ctx)
{
    _Static_assert(SVC_WATCH_MAX == RSTORE_WATCH_MAX, "a watch");
    return rstore_watch(of(st)->rs, n, ids, after, block, fn, ctx);
}

/* The run's end: its blobs and the ack in one script (rstore_finish). */
static int rd_finish(svc_store *st, const char *id, const svc_blob *blobs,
                     int n)
{
    rstore_st *r = of(st);
    rstore_blob b[BLOBS_MAX];
    int rc, e;

    if (to_rstore(blobs, n, b) != 0)
        return -1;
    rc = rstore_finish(r->rs, id, b, n);
    e = errno;
    if (rc == 0 || e == ESTALE)
        set_running(r, id, 0);
    errno = e;
    return rc;
}

static const svc_store_ops redis_ops = {
    "redis", rd_close, rd_ready,
    rd_create, rd_put, rd_get, rd_get_at, rd_stat, rd_open, rd_remove,
    rd_quarantine, rd_usage, rd_scan,
    rd_push, rd_claim, rd_ack, rd_drop,
    rd_heartbeat, rd_progress, rd_follow, rd_finish, rd_watch,
    0.25,                          /* claim blocks 1 s in XREADGROUP too */
    1,                             /* shared by replicas */
};

svc_store *store_redis_open(const char *url, const char *password_file,
                            const char *blob_dir, int workers, double ttl,
                            int allow_eviction, char *msg, size_t msgsize)
{
    rds_config rc;
    rstore_config cfg;
    const char *idle = getenv("MCFD_REDIS_CLAIM_IDLE"),
               *runs = getenv("MCFD_REDIS_MAX_RUNS");
    rstore_st *r;

    rds_config_default(&rc);
    if (rds_url_parse(url, &rc, msg, msgsize) != 0)
        return NULL;
    if (password_file && password_file[0])
        snprintf(rc.password_file, sizeof rc.password_file, "%s",
                 password_file);
    rstore_config_default(&cfg);
    /* a claim holds one while it blocks, and the follower thread one
     * while its watch blocks */
    cfg.pool = workers + 5;
    if (blob_dir && blob_dir[0])
        snprintf(cfg.blob_dir, sizeof cfg.blob_dir, "%s", blob_dir);
    if (ttl > cfg.ttl)
        cfg.ttl = ttl;
    /* seconds without heartbeat before another replica takes a running
     * job over; the sweep heartbeats every second, so 3 s is the least
     * that never steals a live replica's job */
    if (idle && atof(idle) >= 3)
        cfg.claim_idle = atof(idle);
    /* runs of a job whose replica stops each time before it is failed
     * (dead letter; 3 by default) */
    if (runs && atoi(runs) >= 1)
        cfg.max_runs = atoi(runs);
    cfg.allow_eviction = allow_eviction;
    if (!(r = calloc(1, sizeof *r))) {
        snprintf(msg, msgsize, "out of memory");
        return NULL;
    }
    r->base.ops = &redis_ops;
    pthread_mutex_init(&r->mu, NULL);
    if (!(r->rs = rstore_open(&rc, &cfg, msg, msgsize))) {
        pthread_mutex_destroy(&r->mu);
        free(r);
        return NULL;
    }
    {
        int warn;
        const char *notes = rstore_notes(r->rs, &warn);
        srv_logf(warn ? SRV_LOG_WARN : SRV_LOG_INFO, "%s", notes);
    }
    return &r->base;
}
