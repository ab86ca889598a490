/*
 * service.c - the job service's table and lifecycle (service.h): jobs and
 * their references, the ID table and the bounded queue, admission and
 * submit, cancel and delete, subscriptions, drain, close, sweep, stop and
 * the gauges.
 *
 * A job is accepted only after its input, request and state are on disk
 * (spool.c), so an accepted job survives kill -9: recovery.c queues it
 * again at the next start. Capacity: a submission is accepted while the
 * jobs waiting for a worker stay within --queue plus the idle workers;
 * beyond that it is refused with EBUSY (REST: 503 and Retry-After).
 *
 * One mutex (svc__S.mu) guards the table, the queue and every mutable job
 * field; see svc_internal.h. The other service files: svc_read.c (the
 * readers), svc_state.c (the record and the persisted forms), svc_error.c
 * (errors), runner.c (one job), workers.c (the pool), recovery.c (the
 * spool at start).
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

struct svc_state svc__S = {.mu = PTHREAD_MUTEX_INITIALIZER,
                           .work = PTHREAD_COND_INITIALIZER,
                           .idle = PTHREAD_COND_INITIALIZER,
                           .urandom = -1};

void svc__lock(void)
{
    pthread_mutex_lock(&svc__S.mu);
}

void svc__unlock(void)
{
    pthread_mutex_unlock(&svc__S.mu);
}

/* -------------------------------------------------------------------- jobs */

static const char *const status_names[] = {"queued", "running", "succeeded",
                                           "failed", "canceled"};

const char *svc_job_status_name(svc_job_status s)
{
    return (unsigned)s < 5 ? status_names[s] : "unknown";
}

int svc_job_status_terminal(svc_job_status s)
{
    return s == SVC_JOB_SUCCEEDED || s == SVC_JOB_FAILED ||
           s == SVC_JOB_CANCELED;
}

svc_job *svc__job_new(void)
{
    svc_job *j = calloc(1, sizeof *j);
    if (!j)
        return NULL;
    j->refs = 1;
    api_buf_init(&j->events, SVC_EVENTS_MAX);
    snprintf(j->scheme, sizeof j->scheme, "unknown");
    return j;
}

void svc__job_free(svc_job *j)
{
    svc_record_free(&j->rec);
    free(j->input);
    free(j->target);
    free(j->params_json);
    free(j->result);
    api_buf_free(&j->events);
    free(j->event_end);
    free(j);
}

/* Lock held. Frees the job when the last reference goes. */
void svc__unref_locked(svc_job *j)
{
    if (--j->refs == 0)
        svc__job_free(j);
}

void svc_job_unref(svc_job *j)
{
    if (!j)
        return;
    svc__lock();
    svc__unref_locked(j);
    svc__unlock();
}

svc_job *svc_job_ref(svc_job *j)
{
    svc__lock();
    j->refs++;
    svc__unlock();
    return j;
}

const char *svc_job_id(const svc_job *j)
{
    return j->id;
}

static unsigned bucket_of(const char *id)
{
    uint32_t h = 2166136261u;
    for (; *id; id++)
        h = (h ^ (unsigned char)*id) * 16777619u;
    return h % SVC_NBUCKETS;
}

svc_job *svc__find_locked(const char *id)
{
    svc_job *j;
    for (j = svc__S.buckets[bucket_of(id)]; j; j = j->hnext)
        if (strcmp(j->id, id) == 0)
            return j;
    return NULL;
}

void svc__table_insert(svc_job *j)
{
    unsigned b = bucket_of(j->id);
    j->hnext = svc__S.buckets[b];
    svc__S.buckets[b] = j;
    j->in_table = 1;
    svc__S.njobs++;
    svc__S.disk_bytes += j->disk_bytes;
}

/* Removes j from the table and drops the table's reference. */
static void table_remove(svc_job *j)
{
    svc_job **pp = &svc__S.buckets[bucket_of(j->id)];
    while (*pp && *pp != j)
        pp = &(*pp)->hnext;
    if (*pp) {
        *pp = j->hnext;
        j->in_table = 0;
        svc__S.njobs--;
        svc__S.disk_bytes -= j->disk_bytes;
        svc__unref_locked(j);
    }
}

/* Lock held: puts back a job whose spool removal failed (the caller's
 * reference becomes the table's), unless its ID came back meanwhile. */
static void table_restore(svc_job *j)
{
    if (!j->in_table && !svc__find_locked(j->id))
        svc__table_insert(j);
    else
        svc__unref_locked(j);
}

void svc__queue_push(svc_job *j)
{
    j->qnext = NULL;
    if (svc__S.qtail)
        svc__S.qtail->qnext = j;
    else
        svc__S.qhead = j;
    svc__S.qtail = j;
    svc__S.qlen++;
}

svc_job *svc__queue_pop(void)
{
    svc_job *j = svc__S.qhead;
    if (j) {
        svc__S.qhead = j->qnext;
        if (!svc__S.qhead)
            svc__S.qtail = NULL;
        j->qnext = NULL;
        svc__S.qlen--;
    }
    return j;
}

/* Back at the head of the queue (a cancel the spool refused). */
static void queue_push_front(svc_job *j)
{
    j->qnext = svc__S.qhead;
    svc__S.qhead = j;
    if (!svc__S.qtail)
        svc__S.qtail = j;
    svc__S.qlen++;
}

static int queue_remove(svc_job *j)
{
    svc_job *prev = NULL, *q;
    for (q = svc__S.qhead; q; prev = q, q = q->qnext)
        if (q == j) {
            if (prev)
                prev->qnext = j->qnext;
            else
                svc__S.qhead = j->qnext;
            if (svc__S.qtail == j)
                svc__S.qtail = prev;
            j->qnext = NULL;
            svc__S.qlen--;
            return 1;
        }
    return 0;
}

svc_job *svc_job_get(const char *id)
{
    svc_job *j;
    svc__lock();
    j = svc__find_locked(id);
    if (j)
        j->refs++;
    svc__unlock();
    return j;
}

/* 128 bits from /dev/urandom; if that ever fails, a splitmix64 of the
 * clock, pid and a counter (unique, merely not unguessable). */
static void new_id(char *out)
{
    unsigned char b[16];
    size_t got = 0;
    int i;

    while (svc__S.urandom >= 0 && got < sizeof b) {
        ssize_t r = read(svc__S.urandom, b + got, sizeof b - got);
        if (r < 0 && errno == EINTR)
            continue;
        if (r <= 0)
            break;
        got += (size_t)r;
    }
    if (got < sizeof b) {
        uint64_t x = (uint64_t)(srv_wall() * 1e9) ^ ((uint64_t)getpid() << 32);
        for (i = 0; i < 16; i += 8) {
            uint64_t z = x + (++svc__S.counter) * 0x9e3779b97f4a7c15ull;
            z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
            z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
            z ^= z >> 31;
            memcpy(b + i, &z, 8);
        }
    }
    for (i = 0; i < 16; i++)
        snprintf(out + 2 * i, 3, "%02x", b[i]);
}

/* ----------------------------------------------------------- subscriptions */

void svc__notify(svc_job *j, unsigned what)
{
    svc_sub *s;
    for (s = j->subs; s; s = s->next)
        if (s->flags & what)
            s->fn(s->ctx, what);
}

int svc_subscribe(svc_job *j, unsigned flags, svc_notify_fn fn, void *ctx,
                  svc_sub **sub)
{
    svc_sub *s = calloc(1, sizeof *s);

    *sub = NULL;
    if (!s)
        return -1;
    s->job = j;
    s->flags = flags | SVC_NOTIFY_STATE;
    s->fn = fn;
    s->ctx = ctx;
    svc__lock();
    s->next = j->subs;
    if (j->subs)
        j->subs->prev = s;
    j->subs = s;
    svc__unlock();
    *sub = s;
    return 0;
}

void svc_unsubscribe(svc_sub *s)
{
    if (!s)
        return;
    svc__lock();
    if (s->prev)
        s->prev->next = s->next;
    else
        s->job->subs = s->next;
    if (s->next)
        s->next->prev = s->prev;
    svc__unlock();
    free(s);
}

int svc_followers(const svc_job *j)
{
    const svc_sub *s;
    int n = 0;

    svc__lock();
    for (s = j->subs; s; s = s->next)
        n += (s->flags & SVC_NOTIFY_PROGRESS) != 0;
    svc__unlock();
    return n;
}

/* ------------------------------------------------------------------ submit */

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
    svc_error_set(err, SVC_EPARAMS, "ELIMIT", "parameters 'time' and 'dt': "
                  "%g / %g = %.3g steps exceed max_iterations (%d); raise "
                  "'dt', lower 'time', or use 'adaptive'", p->flow.time,
                  p->flow.dt, steps, lim->max_iterations);
    err->mcf = MCF_ELIMIT;
    err->stage = SVC_STAGE_PARAMS;
    return 1;
}

/* Lock held: no worker or queue place free for one more job. */
static int queue_full_locked(void)
{
    return svc__S.qlen + svc__S.reserved >=
           svc__S.cfg.queue + (svc__S.nthreads - svc__S.busy);
}

/* Admission, lock held: whether one more job of bytes fits now. */
static int admit_locked(size_t bytes, svc_error *err)
{
    const svc_config *cfg = &svc__S.cfg;

    if (svc__S.draining) {
        svc_error_set(err, SVC_EDRAINING, NULL, "the daemon is shutting "
                      "down and accepts no new jobs");
        return 0;
    }
    if (queue_full_locked()) {
        svc_error_set(err, SVC_EBUSY, NULL, "the job queue is full (%d "
                      "queued, %d workers busy, --queue %d)", svc__S.qlen,
                      svc__S.nthreads, cfg->queue);
        return 0;
    }
    /* The spool's quota: every job stays there until its TTL (a flood of
     * tiny jobs kept 687 MB). */
    if (cfg->spool_max_jobs > 0 &&
        svc__S.njobs + svc__S.reserved >= cfg->spool_max_jobs) {
        svc_error_set(err, SVC_EQUOTA, "ESPOOLFULL", "the spool holds %d "
                      "jobs, --spool-max-jobs %d; finished jobs leave after "
                      "--result-ttl %g s or a DELETE", svc__S.njobs,
                      cfg->spool_max_jobs, cfg->result_ttl);
        return 0;
    }
    if (svc__S.disk_bytes + bytes > cfg->spool_max_bytes) {
        svc_error_set(err, SVC_EQUOTA, "ESPOOLFULL", "the spool holds %zu "
                      "bytes of jobs; %zu more would pass --spool-max-bytes "
                      "%zu; finished jobs leave after --result-ttl %g s or a "
                      "DELETE", svc__S.disk_bytes, bytes, cfg->spool_max_bytes,
                      cfg->result_ttl);
        return 0;
    }
    return 1;
}

int svc_submit(svc_record *rec, char *input, size_t input_len, char *target,
               size_t target_len, unsigned flags, svc_job **out,
               svc_error *err)
{
    const svc_config *cfg = &svc__S.cfg;
    svc_job *j = NULL;
    api_params prm;
    mcf_error merr = {MCF_OK, ""};
    mcf_status rc;
    cJSON *pj;
    char *rs = NULL;
    int reserved = 0;
    const mcf_scheme_info *si;
    double mem;
    int fields;

    /* Parameters first: a misspelled key is refused even when busy. */
    if ((rc = svc_record_params(rec, &cfg->lim, &prm, &merr)) != MCF_OK) {
        svc_error_from_mcf(err, rc, SVC_STAGE_PARAMS, NULL, &merr);
        goto fail;
    }
    if (svc_record_fields(rec, &fields, err) != 0 ||
        steps_over_budget(&prm, &cfg->lim, err)) {
        api_params_free(&prm);
        goto fail;
    }
    /* Memory admission (svc_admit.c): the estimate from what the input
     * declares; over --max-job-memory it is refused now. */
    mem = svc_admit_estimate(input, input_len, target_len, &prm, &cfg->lim);
    if (svc_admit_refuse(cfg, mem, err)) {
        api_params_free(&prm);
        goto fail;
    }
    j = svc__job_new();
    if (!j) {
        api_params_free(&prm);
        svc_error_set(err, SVC_ENOMEM, NULL, "out of memory accepting a job");
        goto fail;
    }
    /* the scheme it will run (without one named, the runner may still
     * choose the explicit fairing once the mesh's size is known) */
    si = mcf_scheme_get(api_params_scheme(&prm, 0));
    snprintf(j->scheme, sizeof j->scheme, "%s", si ? si->name : "unknown");
    j->time_planned = prm.flow.time > 0 ? prm.flow.time : 0;
    j->steps_planned = (prm.flow.time > 0 || prm.flow.adaptive)
                           ? 0 : prm.flow.iterations;
    pj = api_params_to_json(&prm);
    j->params_json = pj ? cJSON_PrintUnformatted(pj) : NULL;
    cJSON_Delete(pj);
    api_params_free(&prm);

    /* Admission: the one place that decides whether a job fits now. */
    svc__lock();
    if (!admit_locked(input_len + target_len, err)) {
        svc__unlock();
        goto fail;
    }
    svc__S.reserved++;
    reserved = 1;
    new_id(j->id);
    svc__unlock();

    j->rec = *rec;
    memset(rec, 0, sizeof *rec);
    j->rec.has_target = target != NULL;
    j->input = input;
    j->input_len = input_len;
    j->target = target;
    j->target_len = target_len;
    input = target = NULL;
    j->keep_result = (flags & SVC_KEEP_RESULT) != 0;
    j->mem_estimate = mem;
    j->disk_bytes = input_len + target_len;
    j->created = srv_wall();
    j->status = SVC_JOB_QUEUED;

    /* Durable before anyone hears of the ID: input, request, state. */
    rs = svc__request_json(j);
    if (!rs || srv_spool_mkjob(cfg->spool, j->id) != 0 ||
        srv_spool_write(cfg->spool, j->id, "input", j->input, j->input_len,
                        1) != 0 ||
        (j->target && srv_spool_write(cfg->spool, j->id, "target", j->target,
                                      j->target_len, 1) != 0) ||
        srv_spool_write(cfg->spool, j->id, "request.json", rs, strlen(rs),
                        1) != 0 ||
        svc__write_state(j, 1) != 0) {
        int e = errno;
        if (e == ENOSPC || e == EDQUOT) {
            /* A full disk is a full spool: transient, the client's to
             * retry, like the quota's (and /readyz says so meanwhile). */
            svc_error_set(err, SVC_EQUOTA, "ESPOOLFULL", "the spool's "
                          "filesystem has no room for job %s (%zu bytes): "
                          "%s", j->id, input_len + target_len, strerror(e));
            err->retry_after = 5;
        } else {
            svc_error_set(err, SVC_ESTORAGE, "EIO", "cannot write job %s to "
                          "the spool %s: %s", j->id, cfg->spool, strerror(e));
        }
        srv_spool_remove(cfg->spool, j->id);
        goto fail;
    }
    free(rs);
    rs = NULL;
    /* On disk now: a queued job holds no copy in memory (80 queued
     * uploads of 7 MB held 735 MB); the worker reads it back. */
    free(j->input);
    j->input = NULL;
    free(j->target);
    j->target = NULL;

    svc__lock();
    svc__S.reserved--;
    reserved = 0;
    svc__table_insert(j);
    svc__queue_push(j);
    j->refs++; /* the caller's */
    pthread_cond_signal(&svc__S.work);
    svc__unlock();
    *out = j;
    return 0;

fail:
    if (reserved) {
        svc__lock();
        svc__S.reserved--;
        svc__unlock();
    }
    free(rs);
    free(input);
    free(target);
    svc_record_free(rec);
    if (j)
        svc__job_free(j);
    return -1;
}

int svc_can_accept(void)
{
    int ok;
    svc__lock();
    ok = !svc__S.draining && !queue_full_locked();
    svc__unlock();
    return ok;
}

int svc_upload_reserve(size_t *held, size_t want, svc_error *e)
{
    const svc_config *cfg = &svc__S.cfg;
    double h = (double)*held;
    size_t more;
    want += SVC_UPLOAD_AROUND;
    if (want <= *held)
        return 0;
    more = want - *held;
    if (more < SVC_UPLOAD_STEP)
        more = SVC_UPLOAD_STEP;
    if (!svc_admit_more(cfg, &h, (double)more)) {
        svc_error_set(e, SVC_EBUSY, NULL, "no memory for this upload now: the "
                      "running jobs and the uploads in flight hold --max-memory "
                      "(%zu MiB); retry after the delay", cfg->max_memory >> 20);
        return -1;
    }
    *held += more;
    return 0;
}

void svc_upload_release(size_t *held)
{
    if (*held == 0)
        return;
    svc_admit_release((double)*held);
    *held = 0;
    svc__lock();               /* a queued job may fit now */
    pthread_cond_broadcast(&svc__S.work);
    svc__unlock();
}

int svc_draining(void)
{
    int d;
    svc__lock();
    d = svc__S.draining;
    svc__unlock();
    return d;
}

/* ------------------------------------------------------------------ cancel */

/* A cancel is on disk before anyone sees it, and a refused one changes
 * nothing: a client told 500 finds the job as it was, and no state a
 * client saw changes after a restart. Both helpers are called with
 * svc_state_mu and the service lock held (in that order; the state.json
 * snapshot and its write go together, see svc__write_state) and return
 * with both let go: 0, or -1 with errno when the spool refused. */

/* Writes j's state as it would be after apply(j) (snapshot taken with
 * the change made, then undone by undo(j)); a job's fields change only
 * when the write succeeded. Lock held on entry and on return; svc_state_mu
 * held throughout. */
static int write_state_as(svc_job *j, void (*apply)(svc_job *, void *),
                          void (*undo)(svc_job *, void *), void *ctx)
{
    char *s;
    int rc, e;

    apply(j, ctx);
    s = svc__state_json(j);
    undo(j, ctx);
    j->refs++;
    svc__unlock();
    rc = s ? srv_spool_write(svc__S.cfg.spool, j->id, "state.json", s,
                             strlen(s), 1) : -1;
    e = s ? errno : ENOMEM;
    free(s);
    svc__lock();
    svc__unref_locked(j);
    errno = e;
    return rc;
}

typedef struct {
    svc_cancel_reason reason;
    svc_job_status status;
    double finished;
    svc_error err;
} cancel_change;

/* The change of a cancel: a queued job becomes canceled; a running one
 * is asked (cancel_asked: cancel_requested in its state.json; its cancel
 * flag, which the flow reads without the lock, is set only for real). */
static void cancel_apply(svc_job *j, void *arg)
{
    cancel_change *c = arg;
    c->status = j->status;
    c->finished = j->finished;
    c->err = j->err;
    if (j->status != SVC_JOB_QUEUED) {
        j->cancel_asked = c->reason;
        return;
    }
    j->status = SVC_JOB_CANCELED;
    j->cancel = 1;
    j->cancel_reason = c->reason;
    j->finished = srv_wall();
    if (c->reason == SVC_CANCEL_CLIENT)
        svc_error_set(&j->err, SVC_ECANCELED, NULL, "canceled while queued: "
                      "the client closed its connection before the answer");
    else
        svc_error_set(&j->err, SVC_ECANCELED, NULL, "canceled by request "
                      "while queued");
    j->err.cancel = c->reason;
}

static void cancel_undo(svc_job *j, void *arg)
{
    cancel_change *c = arg;
    if (c->status == SVC_JOB_QUEUED) {
        j->cancel = 0;
        j->cancel_reason = SVC_CANCEL_NONE;
    }
    j->cancel_asked = SVC_CANCEL_NONE;
    j->status = c->status;
    j->finished = c->finished;
    j->err = c->err;
}

/* Cancels a queued or running job (see above). A queued one leaves the
 * queue while its state is written (no worker takes it, nor svc_sweep
 * when it was parked) and comes back to the head of the queue when the
 * write fails; a running one gets its cancel flag only once
 * cancel_requested is on disk. */
static int cancel_locked(svc_job *j, svc_cancel_reason reason)
{
    cancel_change c = {.reason = reason};
    int was = j->status, parked = j->parked;
    int inq = was == SVC_JOB_QUEUED && queue_remove(j), rc, e;

    j->parked = 0;
    rc = write_state_as(j, cancel_apply, cancel_undo, &c);
    e = errno;
    if (rc == 0 && j->status == SVC_JOB_QUEUED) {
        cancel_apply(j, &c);
        svc__notify(j, SVC_NOTIFY_STATE);
    } else if (rc == 0 && j->status == SVC_JOB_RUNNING) {
        j->cancel_reason = reason;
        j->cancel = 1;
    } else if (rc != 0) {
        j->parked = parked;
        if (inq) {
            queue_push_front(j);
            pthread_cond_signal(&svc__S.work);
        }
    }
    was = was == SVC_JOB_QUEUED && j->status == SVC_JOB_CANCELED;
    j->refs++;
    svc__unlock();
    pthread_mutex_unlock(&svc_state_mu);
    if (was) {
        srv_metrics_job(j->scheme, "canceled", 0);
        svc__log_job(j, 0, 0, 0);
    }
    svc_job_unref(j);
    errno = e;
    return rc;
}

int svc_cancel(svc_job *j, svc_cancel_reason reason)
{
    pthread_mutex_lock(&svc_state_mu);
    svc__lock();
    if ((j->cancel && j->status == SVC_JOB_RUNNING) ||
        (j->status != SVC_JOB_QUEUED && j->status != SVC_JOB_RUNNING)) {
        svc__unlock();
        pthread_mutex_unlock(&svc_state_mu);
        return 0;
    }
    return cancel_locked(j, reason) == 0 ? 1 : -1;
}

int svc_delete(const char *id, svc_delete_result *res, svc_job_status *before,
               svc_error *err)
{
    svc_job *j;
    int rc;

    pthread_mutex_lock(&svc_state_mu);
    svc__lock();
    j = svc__find_locked(id);
    if (!j) {
        svc__unlock();
        pthread_mutex_unlock(&svc_state_mu);
        svc_error_set(err, SVC_ENOTFOUND, NULL, "no job with ID %s (never "
                      "existed, deleted, or expired)", id);
        return -1;
    }
    *before = j->status;
    if (j->status == SVC_JOB_QUEUED || j->status == SVC_JOB_RUNNING) {
        *res = j->status == SVC_JOB_QUEUED ? SVC_DELETE_CANCELED
                                           : SVC_DELETE_STOPPING;
        if (j->cancel && j->status == SVC_JOB_RUNNING) { /* asked already */
            svc__unlock();
            pthread_mutex_unlock(&svc_state_mu);
            return 0;
        }
        rc = cancel_locked(j, SVC_CANCEL_USER);
    } else {
        pthread_mutex_unlock(&svc_state_mu);
        /* Finished: forget it, out of the table first (a visible job
         * always has its files), then off the disk; a job that cannot be
         * removed is put back, rather than coming back after a restart. */
        j->refs++;
        table_remove(j);
        svc__unlock();
        *res = SVC_DELETE_FORGOTTEN;
        rc = srv_spool_remove(svc__S.cfg.spool, id);
        if (rc != 0) {
            int e = errno;
            srv_logf(SRV_LOG_ERROR, "spool: cannot remove job %s: %s", id,
                     strerror(e));
            svc__lock();
            table_restore(j);
            svc__unlock();
            errno = e;
        } else {
            svc_job_unref(j);
        }
    }
    if (rc != 0) {
        svc_error_set(err, SVC_ESTORAGE, "EIO", "job %s: the spool could not "
                      "record the deletion (%s); %s", id, strerror(errno),
                      *res != SVC_DELETE_FORGOTTEN
                      ? "it was not canceled; retry"
                      : "the job is kept; retry");
        return -1;
    }
    return 0;
}

/* ------------------------------------------------------------------- sweep */

void svc_sweep(void)
{
    svc_job **gone = NULL;
    int n = 0, cap = 0, b, i;
    double now = srv_wall();
    svc_job *j, *next;

    svc__lock();
    for (b = 0; b < SVC_NBUCKETS; b++)
        for (j = svc__S.buckets[b]; j; j = next) {
            next = j->hnext;
            if (j->parked && !svc__S.draining &&
                srv_mono() >= j->retry_at) {
                /* runner.c: its outcome could not be recorded; again */
                j->parked = 0;
                svc__queue_push(j);
                pthread_cond_signal(&svc__S.work);
            }
            if (!svc_job_status_terminal(j->status) ||
                now - j->finished < svc__S.cfg.result_ttl)
                continue;
            if (n == cap) {
                int ncap = cap ? 2 * cap : 64;
                void *p = realloc(gone, (size_t)ncap * sizeof *gone);
                if (!p)
                    break;
                gone = p;
                cap = ncap;
            }
            /* Out of the table before its files go (a visible job always
             * has its files), held by a reference of ours. */
            j->refs++;
            table_remove(j);
            gone[n++] = j;
        }
    svc__unlock();
    /* A removal that fails puts the job back (tried again at the next
     * sweep) instead of leaving files that bring it back after a
     * restart. */
    for (i = 0; i < n; i++) {
        j = gone[i];
        if (srv_spool_remove(svc__S.cfg.spool, j->id) != 0) {
            srv_logf(SRV_LOG_WARN, "spool: cannot remove expired job %s: %s",
                     j->id, strerror(errno));
            svc__lock();
            table_restore(j);
            svc__unlock();
            continue;
        }
        srv_logf(SRV_LOG_DEBUG, "job %s expired after --result-ttl %g s",
                 j->id, svc__S.cfg.result_ttl);
        svc_job_unref(j);
    }
    free(gone);
}

/* --------------------------------------------------------------- lifecycle */

int svc_start(const svc_config *cfg, char *msg, size_t msgsize)
{
    svc__S.cfg = *cfg;
    svc__S.urandom = open("/dev/urandom", O_RDONLY);
    {
        /* The drain's timed wait on the monotonic clock, like every
         * deadline of the daemon. */
        pthread_condattr_t ca;
        if (pthread_condattr_init(&ca) == 0) {
            if (pthread_condattr_setclock(&ca, CLOCK_MONOTONIC) == 0) {
                pthread_cond_destroy(&svc__S.idle);
                pthread_cond_init(&svc__S.idle, &ca);
            }
            pthread_condattr_destroy(&ca);
        }
    }
    if (svc__recover(msg, msgsize) != 0)
        return -1;
    return svc__workers_start(msg, msgsize);
}

void svc_drain(void)
{
    svc_job *j;

    svc__lock();
    svc__S.draining = 1;
    /* Clients waiting on queued jobs hear now: those run after restart. */
    for (j = svc__S.qhead; j; j = j->qnext)
        svc__notify(j, SVC_NOTIFY_STATE);
    pthread_cond_broadcast(&svc__S.work);
    svc__unlock();
}

void svc_close_waiters(void)
{
    int b;
    svc_job *j;

    svc__lock();
    svc__S.closing = 1;
    for (b = 0; b < SVC_NBUCKETS; b++)
        for (j = svc__S.buckets[b]; j; j = j->hnext)
            svc__notify(j, SVC_NOTIFY_STATE);
    svc__unlock();
}

void svc_stop(void)
{
    int b;
    svc_job *j, *next;

    svc__workers_stop();
    svc__lock();
    while (svc__queue_pop())
        ;
    for (b = 0; b < SVC_NBUCKETS; b++)
        for (j = svc__S.buckets[b]; j; j = next) {
            next = j->hnext;
            table_remove(j);
        }
    svc__unlock();
    if (svc__S.urandom >= 0)
        close(svc__S.urandom);
    svc__S.urandom = -1;
}

svc_gauges svc_get_gauges(void)
{
    svc_gauges g;
    svc__lock();
    g.queue_depth = svc__S.qlen;
    g.queue_capacity = svc__S.cfg.queue;
    g.workers = svc__S.nthreads;
    g.workers_busy = svc__S.busy;
    g.jobs_in_memory = svc__S.njobs;
    g.draining = svc__S.draining;
    g.spool_bytes = (double)svc__S.disk_bytes;
    svc__unlock();
    return g;
}
