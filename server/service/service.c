/* SPDX-License-Identifier: MIT */
/*
 * service.c - the job service's life (service.h): the service object and
 * its lifecycle (start, drain, close, checkpoint, stop), admission and
 * submit, delete, the TTL sweep and the gauges. The table it fills is
 * svc_table.c's; a job's fields are written by svc_job.c.
 *
 * A job is accepted only after its input, request and state are in the
 * store (svc_store create), so an accepted job survives kill -9:
 * recovery.c queues it again at the next start. Capacity: a submission is
 * accepted while the jobs waiting for a worker stay within --queue plus
 * the idle workers; beyond that it is refused with EBUSY (REST: 503 and
 * Retry-After). The other files of the service: svc_internal.h says
 * which does what, and the lock order.
 */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "svc_internal.h"
#include "svc_admit.h"

/* ------------------------------------------------------------------- table */

/* Lock held: puts back a job whose removal from the store failed (the
 * caller's reference becomes the table's), unless its ID came back
 * meanwhile. */
static void table_restore(svc_t *s, svc_job *j)
{
    if (!j->in_table && !svc__find_locked(s, j->id))
        svc__table_insert(s, j);
    else
        svc__unref_locked(j);
}

/* 128 bits from /dev/urandom; if that ever fails, a splitmix64 of the
 * clock, pid and a counter (unique, merely not unguessable). Lock held. */
static void new_id(svc_t *s, char *out)
{
    unsigned char b[16];
    size_t got = 0;
    int i;

    while (s->urandom >= 0 && got < sizeof b) {
        ssize_t r = read(s->urandom, b + got, sizeof b - got);
        if (r < 0 && errno == EINTR)
            continue;
        if (r <= 0)
            break;
        got += (size_t)r;
    }
    if (got < sizeof b) {
        uint64_t x = (uint64_t)(srv_wall() * 1e9) ^ ((uint64_t)getpid() << 32);
        for (i = 0; i < 16; i += 8) {
            uint64_t z = x + (++s->counter) * 0x9e3779b97f4a7c15ull;
            z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
            z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
            z ^= z >> 31;
            memcpy(b + i, &z, 8);
        }
    }
    for (i = 0; i < 16; i++)
        snprintf(out + 2 * i, 3, "%02x", b[i]);
}

/* ------------------------------------------------------------------ submit */

void svc_request_init(svc_request *rq)
{
    memset(rq, 0, sizeof *rq);
    api_params_init(&rq->params);
}

void svc_request_free(svc_request *rq)
{
    api_params_free(&rq->params);
    free(rq->input);
    free(rq->target);
    svc_request_init(rq);
}

/* A fixed-step run over a time has a step count the parameters alone
 * decide (api_params_steps, the rule of api_params_finish): over
 * max_iterations it is the request's fault, refused at once rather than
 * a failed job. (Iterations are bounded when parsed: only time / dt can
 * exceed it.) */
static int steps_over_budget(const api_params *p, const api_limits *lim,
                             svc_error *err)
{
    double steps = api_params_steps(p, lim, NULL);

    if (steps <= lim->max_iterations)
        return 0;
    svc_error_set(err, SVC_P_PARAM_LIMIT, "parameters 'time' and 'dt': "
                  "%g / %g = %.3g steps exceed max_iterations (%d); raise "
                  "'dt', lower 'time', or use 'adaptive'", p->flow.time,
                  p->flow.dt, steps, lim->max_iterations);
    return 1;
}

/* Lock held: no worker or queue place free for one more job. */
static int queue_full_locked(const svc_t *s)
{
    return s->queued + s->reserved >= s->cfg.queue + (s->nthreads - s->busy);
}

/* Admission, lock held: whether one more job of bytes fits now. */
static int admit_locked(const svc_t *s, size_t bytes, svc_error *err)
{
    const svc_config *cfg = &s->cfg;

    if (s->draining) {
        svc_error_set(err, SVC_P_DRAINING, "the daemon is shutting down and "
                      "accepts no new jobs");
        return 0;
    }
    if (queue_full_locked(s)) {
        svc_error_set(err, SVC_P_BUSY, "the job queue is full (%d queued, %d "
                      "workers busy, --queue %d)", s->queued, s->nthreads,
                      cfg->queue);
        return 0;
    }
    /* The spool's quota: every job stays there until its TTL (a flood of
     * tiny jobs kept 687 MB). */
    if (cfg->spool_max_jobs > 0 &&
        s->njobs + s->reserved >= cfg->spool_max_jobs) {
        svc_error_set(err, SVC_P_SPOOL_FULL, "the spool holds %d jobs, "
                      "--spool-max-jobs %d; finished jobs leave after "
                      "--result-ttl %g s or a DELETE", s->njobs,
                      cfg->spool_max_jobs, cfg->result_ttl);
        return 0;
    }
    if (s->disk_bytes + bytes > cfg->spool_max_bytes) {
        svc_error_set(err, SVC_P_SPOOL_FULL, "the spool holds %zu bytes of "
                      "jobs; %zu more would pass --spool-max-bytes %zu; "
                      "finished jobs leave after --result-ttl %g s or a "
                      "DELETE", s->disk_bytes, bytes, cfg->spool_max_bytes,
                      cfg->result_ttl);
        return 0;
    }
    return 1;
}

/* The job from the request: its parameters (taken), their texts, what it
 * plans and the scheme it will run (without one named, the runner may
 * still choose the explicit fairing once the mesh's size is known). */
static svc_job *job_from_request(svc_t *s, svc_request *rq, double mem)
{
    svc_job *j = svc__job_new(s);
    const mcf_scheme_info *si;
    cJSON *shown, *given;
    const api_params *p;

    if (!j)
        return NULL;
    j->params = rq->params;
    api_params_init(&rq->params);
    p = &j->params;
    si = mcf_scheme_get(api_params_scheme(p, 0));
    snprintf(j->scheme, sizeof j->scheme, "%s", si ? si->name : "unknown");
    j->time_planned = p->flow.time > 0 ? p->flow.time : 0;
    j->steps_planned = (p->flow.time > 0 || p->flow.adaptive)
                           ? 0 : p->flow.iterations;
    shown = api_params_to_json(p);
    given = api_params_given_json(p);
    j->params_json = shown ? cJSON_PrintUnformatted(shown) : NULL;
    j->params_given = given ? cJSON_PrintUnformatted(given) : NULL;
    cJSON_Delete(shown);
    cJSON_Delete(given);
    snprintf(j->filename, sizeof j->filename, "%s",
             rq->filename[0] ? rq->filename : "mesh");
    j->has_target = rq->target != NULL;
    j->keep_fields = rq->fields;
    /* a target is there to be compared with, and the fields' viewer
     * shows the measures */
    j->measures = rq->measures || rq->target || rq->fields;
    j->keep_result = rq->keep_result;
    j->mem_estimate = mem;
    j->disk_bytes = rq->input_len + rq->target_len;
    j->created = srv_wall();
    if (!j->params_json || !j->params_given) {
        svc__job_free(j);
        return NULL;
    }
    return j;
}

/* Input, target, request and state, durably: the job exists. */
static int store_create(svc_t *s, svc_job *j, const svc_request *rq,
                        svc_error *err)
{
    svc_blob b[4];
    svc_state_rec r;
    char *req = svc__request_json(j), *state;
    int n = 0, rc, e;

    svc__state_of(j, &r); /* no other thread knows j yet */
    state = svc__state_json(&r);
    b[n++] = (svc_blob){"input", rq->input, rq->input_len};
    if (rq->target)
        b[n++] = (svc_blob){"target", rq->target, rq->target_len};
    b[n++] = (svc_blob){"request.json", req, req ? strlen(req) : 0};
    b[n++] = (svc_blob){"state.json", state, state ? strlen(state) : 0};
    errno = ENOMEM;
    rc = req && state ? s->store->ops->create(s->store, j->id, b, n) : -1;
    e = errno;
    free(req);
    free(state);
    if (rc == 0)
        return 0;
    if (e == ENOSPC || e == EDQUOT) {
        /* A full disk is a full spool: transient, the client's to retry,
         * like the quota's (and /readyz says so meanwhile). */
        char where[600];
        if (s->cfg.blob_dir[0])
            snprintf(where, sizeof where, "the blob directory %s (or Redis)",
                     s->cfg.blob_dir);
        else
            snprintf(where, sizeof where, "%s", s->cfg.store[0]
                                                    ? "the job store (Redis)"
                                                    : "the spool's filesystem");
        svc_error_set(err, SVC_P_SPOOL_FULL, "%s has no room for job %s "
                      "(%zu bytes): %s", where, j->id,
                      rq->input_len + rq->target_len, strerror(e));
        err->retry_after = 5;
    } else if (e == EAGAIN) {
        /* a store that cannot answer now (Redis down or loading) */
        svc_error_set(err, SVC_P_SPOOL_UNREADY, "cannot record job %s now: "
                      "%s", j->id, strerror(e));
        err->retry_after = 5;
    } else if (e == EFBIG) {
        svc_error_set(err, SVC_P_INPUT_LIMIT, "the input (%zu bytes) is "
                      "larger than the job store takes in one value "
                      "(Redis's proto-max-bulk-len, less a margin)",
                      rq->input_len > rq->target_len ? rq->input_len
                                                     : rq->target_len);
    } else {
        svc_error_set(err, SVC_P_STORAGE, "cannot write job %s to the spool "
                      "%s: %s", j->id, s->cfg.spool, strerror(e));
    }
    return -1;
}

/* A job recorded but refused by the queue (Redis: the queue key of
 * another type, out of memory, down): not acknowledged, so nothing of it
 * is kept; the client hears why and retries. Takes j (no one else knows
 * its ID yet). */
static void unqueued(svc_t *s, svc_job *j, svc_error *err)
{
    char why[400];
    int e = errno;

    if (s->store->ops->ready(s->store, why, sizeof why) == 0)
        snprintf(why, sizeof why, "%s", strerror(e));
    pthread_mutex_lock(&s->mu);
    svc__table_remove(s, j);
    s->queued--;
    pthread_mutex_unlock(&s->mu);
    if (s->store->ops->remove(s->store, j->id) != 0)
        srv_logf(SRV_LOG_ERROR, "job %s: cannot queue it, nor remove its "
                 "records (%s): it was never acknowledged", j->id,
                 strerror(errno));
    srv_logf(SRV_LOG_ERROR, "job %s: cannot queue it: %s; refused (503)",
             j->id, why);
    svc_error_set(err, SVC_P_SPOOL_UNREADY, "cannot queue the job now: %s; "
                  "nothing of it was kept", why);
    err->retry_after = 5;
    svc_job_unref(j);
}

int svc_submit(svc_t *s, svc_request *rq, svc_job **out, svc_error *err)
{
    const svc_config *cfg = &s->cfg;
    svc_job *j = NULL;
    int reserved = 0;
    double mem;

    /* Budgets first: refused even when busy. The estimate (svc_admit.c)
     * from what the input declares; over --max-job-memory it is refused
     * now. */
    if (steps_over_budget(&rq->params, &cfg->lim, err))
        goto fail;
    mem = svc_admit_estimate(rq->input, rq->input_len, rq->target_len,
                             &rq->params, &cfg->lim);
    if (svc_admit_refuse(cfg, mem, err))
        goto fail;
    if (!(j = job_from_request(s, rq, mem))) {
        svc_error_set(err, SVC_P_NOMEM, "out of memory accepting a job");
        goto fail;
    }
    /* Admission: the one place that decides whether a job fits now. */
    pthread_mutex_lock(&s->mu);
    if (!admit_locked(s, rq->input_len + rq->target_len, err)) {
        pthread_mutex_unlock(&s->mu);
        goto fail;
    }
    s->reserved++;
    reserved = 1;
    new_id(s, j->id);
    pthread_mutex_unlock(&s->mu);

    /* Durable before anyone hears of the ID. A queued job holds no copy
     * of its bytes in memory (80 queued uploads of 7 MB held 735 MB): the
     * worker reads them back. */
    if (store_create(s, j, rq, err) != 0)
        goto fail;
    svc_request_free(rq);

    pthread_mutex_lock(&s->mu);
    s->reserved--;
    reserved = 0;
    svc__table_insert(s, j);
    s->queued++;
    j->refs++; /* the caller's */
    pthread_mutex_unlock(&s->mu);
    if (s->store->ops->push(s->store, j->id, 0) != 0) {
        unqueued(s, j, err);
        return -1;
    }
    pthread_mutex_lock(&s->mu);
    svc__wake_locked(s);
    pthread_mutex_unlock(&s->mu);
    *out = j;
    return 0;

fail:
    if (reserved) {
        pthread_mutex_lock(&s->mu);
        s->reserved--;
        pthread_mutex_unlock(&s->mu);
    }
    svc_request_free(rq);
    if (j)
        svc__job_free(j);
    return -1;
}

int svc_can_accept(svc_t *s)
{
    int ok;
    pthread_mutex_lock(&s->mu);
    ok = !s->draining && !queue_full_locked(s);
    pthread_mutex_unlock(&s->mu);
    return ok;
}

int svc_upload_reserve(svc_t *s, size_t *held, size_t want, svc_error *e)
{
    double h = (double)*held;
    size_t more;
    want += SVC_UPLOAD_AROUND;
    if (want <= *held)
        return 0;
    more = want - *held;
    if (more < SVC_UPLOAD_STEP)
        more = SVC_UPLOAD_STEP;
    if (!svc_admit_more(s, &h, (double)more)) {
        svc_error_set(e, SVC_P_BUSY, "no memory for this upload now: the "
                      "running jobs and the uploads in flight hold --max-memory "
                      "(%zu MiB); retry after the delay", s->cfg.max_memory >> 20);
        return -1;
    }
    *held += more;
    return 0;
}

void svc_upload_release(svc_t *s, size_t *held)
{
    if (*held == 0)
        return;
    svc_admit_release(s, (double)*held);
    *held = 0;
    pthread_mutex_lock(&s->mu);  /* a queued job may fit now */
    svc__wake_locked(s);
    pthread_mutex_unlock(&s->mu);
}

int svc_draining(svc_t *s)
{
    int d;
    pthread_mutex_lock(&s->mu);
    d = s->draining;
    pthread_mutex_unlock(&s->mu);
    return d;
}

int svc_ready(svc_t *s, char *why, size_t size)
{
    return s->store->ops->ready(s->store, why, size);
}

const api_limits *svc_limits(const svc_t *s)
{
    return &s->cfg.lim;
}

/* ------------------------------------------------------------------ delete */

/* Forgets a finished job: out of the table first (a visible job always
 * has its blobs), then out of the store; a job that cannot be removed is
 * put back, rather than coming back after a restart. Takes the caller's
 * reference. 0 or -1 (errno). */
static int forget(svc_t *s, svc_job *j, const char *why)
{
    int e;

    pthread_mutex_lock(&s->mu);
    svc__table_remove(s, j);
    pthread_mutex_unlock(&s->mu);
    if (s->store->ops->remove(s->store, j->id) == 0) {
        svc_job_unref(j);
        return 0;
    }
    e = errno;
    srv_logf(SRV_LOG_ERROR, "spool: cannot remove %s job %s: %s", why, j->id,
             strerror(e));
    pthread_mutex_lock(&s->mu);
    table_restore(s, j);
    pthread_mutex_unlock(&s->mu);
    errno = e;
    return -1;
}

int svc_delete(svc_t *s, const char *id, svc_delete_result *res,
               svc_job_status *before, svc_error *err)
{
    svc_job *j = svc_job_find(s, id, err);
    svc_snap sn;
    int rc;

    if (!j)
        return -1;
    svc_job_snapshot(j, &sn);
    *before = sn.status;
    if (!svc_job_status_terminal(sn.status)) {
        *res = sn.status == SVC_JOB_QUEUED ? SVC_DELETE_CANCELED
                                           : SVC_DELETE_STOPPING;
        rc = svc_cancel(j, SVC_CANCEL_USER) < 0 ? -1 : 0;
        svc_job_unref(j);
    } else {
        *res = SVC_DELETE_FORGOTTEN;
        rc = forget(s, j, "deleted");
    }
    if (rc != 0) {
        svc_error_set(err, SVC_P_STORAGE, "job %s: the spool could not record "
                      "the deletion (%s); %s", id, strerror(errno),
                      *res != SVC_DELETE_FORGOTTEN
                      ? "it was not canceled; retry"
                      : "the job is kept; retry");
        return -1;
    }
    return 0;
}

/* ------------------------------------------------------------------- sweep */

/* Lock held: the jobs finished more than the TTL ago, out of the table
 * (held by a reference each, in *gone); parked jobs whose delay passed
 * back in the queue (their IDs in *again). */
/* One more ID at the end of a growing array. 0, or -1 (ENOMEM). */
typedef struct {
    char (*id)[SVC_ID_LEN + 1];
    int n, cap;
} id_list;

static int id_append(id_list *l, const char *id)
{
    if (l->n == l->cap) {
        int cap = l->cap ? 2 * l->cap : 16;
        void *p = realloc(l->id, (size_t)cap * sizeof *l->id);
        if (!p)
            return -1;
        l->id = p;
        l->cap = cap;
    }
    memcpy(l->id[l->n++], id, SVC_ID_LEN + 1);
    return 0;
}

/* Lock held: the jobs past their TTL (*gone, a reference each), the
 * parked jobs whose retry time came (again: counted as queued) and the
 * running ones (beat: their claim is alive). */
static int sweep_locked(svc_t *s, svc_job ***gone, int *ngone, id_list *again,
                        id_list *beat)
{
    int cap = 0, b;
    double now = srv_wall();
    svc_job *j, *next;

    for (b = 0; b < SVC_NBUCKETS; b++)
        for (j = s->buckets[b]; j; j = next) {
            next = j->hnext;
            if (j->run_here && id_append(beat, j->id) != 0)
                return -1;
            if (j->parked && !s->draining && srv_mono() >= j->retry_at) {
                if (id_append(again, j->id) != 0)
                    return -1;
                j->parked = 0;
                s->queued++;
            }
            if (!svc_job_status_terminal(j->status) ||
                now - j->finished < s->cfg.result_ttl)
                continue;
            if (*ngone == cap) {
                void *p = realloc(*gone, (size_t)(cap = cap ? 2 * cap : 64) * sizeof **gone);
                if (!p)
                    return -1;
                *gone = p;
            }
            j->refs++;
            (*gone)[(*ngone)++] = j;
        }
    return 0;
}

/* The run of job id here stops at its next step. */
static void stop_run(svc_t *s, const char *id)
{
    svc_job *j;

    pthread_mutex_lock(&s->mu);
    if ((j = svc__find_locked(s, id)) && j->run_here && !j->cancel) {
        j->cancel_reason = SVC_CANCEL_USER;
        j->cancel = 1;
    }
    pthread_mutex_unlock(&s->mu);
}

void svc_sweep(svc_t *s)
{
    svc_job **gone = NULL;
    id_list again = {NULL, 0, 0}, beat = {NULL, 0, 0};
    int ngone = 0, i;

    pthread_mutex_lock(&s->mu);
    sweep_locked(s, &gone, &ngone, &again, &beat);
    pthread_mutex_unlock(&s->mu);
    /* a shared store hands the job of a silent claimer to another; a run
     * whose records are gone from it (ENOENT) is stopped: its outcome
     * can no longer be recorded (svc__finish says so) */
    for (i = 0; i < beat.n; i++)
        if (s->store->ops->heartbeat(s->store, beat.id[i]) != 0 &&
            errno == ENOENT && s->store->ops->shared)
            stop_run(s, beat.id[i]);
    if (s->store->ops->shared)
        svc__shared_sweep(s);
    /* their outcome could not be recorded (svc__finish): again */
    for (i = 0; i < again.n; i++)
        s->store->ops->push(s->store, again.id[i], 0);
    if (again.n) {
        pthread_mutex_lock(&s->mu);
        svc__wake_locked(s);
        pthread_mutex_unlock(&s->mu);
    }
    /* A removal that fails puts the job back (tried again at the next
     * sweep) instead of leaving files that bring it back after a
     * restart. */
    for (i = 0; i < ngone; i++)
        if (forget(s, gone[i], "expired") == 0)
            srv_logf(SRV_LOG_DEBUG, "job %s expired after --result-ttl %g s",
                     gone[i]->id, s->cfg.result_ttl);
    free(gone);
    free(again.id);
    free(beat.id);
}

/* --------------------------------------------------------------- lifecycle */

int svc_start(const svc_config *cfg, svc_t **out, char *msg, size_t msgsize)
{
    svc_t *s = calloc(1, sizeof *s);
    pthread_condattr_t ca;

    *out = NULL;
    if (!s) {
        snprintf(msg, msgsize, "out of memory");
        return -1;
    }
    s->cfg = *cfg;
    if (s->cfg.cores < 1)      /* unset: a core per worker */
        s->cfg.cores = s->cfg.workers > 0 ? s->cfg.workers : 1;
    s->urandom = open("/dev/urandom", O_RDONLY | O_CLOEXEC);
    pthread_mutex_init(&s->mu, NULL);
    pthread_mutex_init(&s->state_mu, NULL);
    pthread_cond_init(&s->work, NULL);
    /* The drain's timed wait on the monotonic clock, like every deadline
     * of the daemon. */
    pthread_condattr_init(&ca);
    pthread_condattr_setclock(&ca, CLOCK_MONOTONIC);
    pthread_cond_init(&s->idle, &ca);
    pthread_condattr_destroy(&ca);
    svc_admit_init(s);
    s->store = cfg->store[0]
                   ? store_redis_open(cfg->store, cfg->store_password_file,
                                      cfg->blob_dir, cfg->workers,
                                      cfg->result_ttl + cfg->job_timeout +
                                          cfg->job_timeout_per_mib *
                                              (double)cfg->max_job_memory / 1048576.0 +
                                          3600,
                                      cfg->redis_allow_eviction, msg, msgsize)
                   : store_spool_open(cfg->spool, msg, msgsize);
    if (!s->store ||
        svc__recover(s, msg, msgsize) != 0 ||
        svc__workers_start(s, msg, msgsize) != 0 ||
        svc__follower_start(s, msg, msgsize) != 0) {
        svc_stop(s);
        return -1;
    }
    *out = s;
    return 0;
}

void svc_drain(svc_t *s)
{
    int b;
    svc_job *j;

    pthread_mutex_lock(&s->mu);
    s->draining = 1;
    /* Clients waiting on queued jobs hear now: those run after restart. */
    for (b = 0; b < SVC_NBUCKETS; b++)
        for (j = s->buckets[b]; j; j = j->hnext)
            if (j->status == SVC_JOB_QUEUED)
                svc__notify(j, SVC_NOTIFY_STATE);
    svc__wake_locked(s);
    pthread_mutex_unlock(&s->mu);
}

void svc_close_waiters(svc_t *s)
{
    int b;
    svc_job *j;

    pthread_mutex_lock(&s->mu);
    s->closing = 1;
    for (b = 0; b < SVC_NBUCKETS; b++)
        for (j = s->buckets[b]; j; j = j->hnext)
            svc__notify(j, SVC_NOTIFY_STATE);
    pthread_mutex_unlock(&s->mu);
}

void svc_checkpoint_running(svc_t *s)
{
    int b;
    svc_job *j;

    pthread_mutex_lock(&s->mu);
    for (b = 0; b < SVC_NBUCKETS; b++)
        for (j = s->buckets[b]; j; j = j->hnext)
            /* A job its user (or its hung-up client) canceled stays
             * canceled: it is not put back in the queue. */
            if (j->status == SVC_JOB_RUNNING &&
                !(j->cancel && (j->cancel_reason == SVC_CANCEL_USER ||
                                j->cancel_reason == SVC_CANCEL_CLIENT))) {
                j->cancel = 1;
                j->cancel_reason = SVC_CANCEL_SHUTDOWN;
            }
    pthread_mutex_unlock(&s->mu);
}

void svc_stop(svc_t *s)
{
    int b;
    svc_job *j, *next;

    if (!s)
        return;
    svc__follower_stop(s);
    svc__workers_stop(s);
    pthread_mutex_lock(&s->mu);
    for (b = 0; b < SVC_NBUCKETS; b++)
        for (j = s->buckets[b]; j; j = next) {
            next = j->hnext;
            svc__table_remove(s, j);
        }
    pthread_mutex_unlock(&s->mu);
    if (s->store)
        s->store->ops->close(s->store);
    if (s->urandom >= 0)
        close(s->urandom);
    svc_admit_destroy(s);
    pthread_cond_destroy(&s->work);
    pthread_cond_destroy(&s->idle);
    pthread_mutex_destroy(&s->state_mu);
    pthread_mutex_destroy(&s->mu);
    free(s);
}

svc_gauges svc_get_gauges(svc_t *s)
{
    svc_gauges g;
    pthread_mutex_lock(&s->mu);
    g.queue_depth = s->queued;
    g.queue_capacity = s->cfg.queue;
    g.workers = s->nthreads;
    g.workers_busy = s->busy;
    g.jobs_in_memory = s->njobs;
    g.draining = s->draining;
    g.spool_bytes = (double)s->disk_bytes;
    pthread_mutex_unlock(&s->mu);
    return g;
}
