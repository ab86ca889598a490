/* SPDX-License-Identifier: MIT */
/*
 * svc_job.c - a job's life in the job service: its progress, and every
 * change of its status, each one recorded in the store before anyone can
 * see it:
 *
 *   queued   -> running     a worker starts it (svc__start)
 *   running  -> succeeded, failed, canceled; or queued again: stopped by
 *               the shutdown, or its outcome could not be recorded
 *               (parked, svc__finish)
 *   queued   -> canceled    a user or its client (svc_cancel)
 *   loaded   -> queued, canceled   recovery (svc__recovered)
 *
 * A change is computed on a copy of what state.json records
 * (svc_state_rec, taken under the service lock), written from the copy
 * outside it, and applied to the job (and its subscribers told) only once
 * written: a client never sees a state a restart could change. state_mu
 * keeps a snapshot and its write together, so the last taken is the last
 * written. No other file writes a job's status. (A job's references and
 * subscriptions: svc_ref.c; its progress events: svc_events.c.)
 */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "svc_internal.h"
#include "svc_admit.h"

/* ------------------------------------------------------------------ state */

/* The fields a job and its recorded state (svc_state_rec) share, copied
 * one way by svc__state_of and the other by apply_rec: one list. */
#define SVC_RECORDED(X)                                                      \
    X(status) X(created) X(started) X(finished) X(scheme) X(steps_planned)  \
    X(time_planned) X(step) X(t) X(in_format) X(out_format) X(result_name)  \
    X(result_len)
#define SVC_COPY(to, from, f)                                                \
    do {                                                                     \
        _Static_assert(sizeof (to)->f == sizeof (from)->f, #f);              \
        memcpy(&(to)->f, &(from)->f, sizeof (to)->f);                        \
    } while (0);

void svc__state_of(const svc_job *j, svc_state_rec *r)
{
    memset(r, 0, sizeof *r);
    memcpy(r->id, j->id, sizeof r->id);
#define X(f) SVC_COPY(r, j, f)
    SVC_RECORDED(X)
#undef X
    /* a cancel asked of a running job holds across a restart */
    if (j->canceling)
        r->cancel_requested = j->canceling;
    else if (j->cancel && (j->cancel_reason == SVC_CANCEL_USER ||
                           j->cancel_reason == SVC_CANCEL_CLIENT))
        r->cancel_requested = j->cancel_reason;
    r->params_json = j->params_json;
    r->err = j->err;
}

/* Writes r (state_mu held by the caller). 0 or -1 (errno). */
static int write_rec(svc_t *s, const svc_state_rec *r, int durable)
{
    char *text = svc__state_json(r);
    int rc, e;

    if (!text) {
        errno = ENOMEM;
        return -1;
    }
    rc = s->store->ops->put(s->store, r->id, "state.json", text, strlen(text),
                            durable);
    e = errno;
    free(text);
    errno = e;
    return rc;
}

int svc__write_state(svc_job *j, int durable)
{
    svc_t *s = j->svc;
    svc_state_rec r;
    int rc;

    pthread_mutex_lock(&s->state_mu);
    pthread_mutex_lock(&s->mu);
    svc__state_of(j, &r);
    pthread_mutex_unlock(&s->mu);
    rc = write_rec(s, &r, durable);
    pthread_mutex_unlock(&s->state_mu);
    return rc;
}

/* ----------------------------------------------------------------- retries */

/* Errors of a resource a client can exhaust (descriptors, disk space,
 * memory) are worth trying again; any other is final at once. */
static int transient(int e)
{
    return e == EMFILE || e == ENFILE || e == ENOSPC || e == EDQUOT ||
           e == ENOMEM || e == EAGAIN || e == ENOBUFS;
}

int svc__canceled(const svc_job *j)
{
    return atomic_load_explicit(&j->cancel, memory_order_acquire) != 0;
}

svc_cancel_reason svc__cancel_reason(const svc_job *j)
{
    svc_cancel_reason r;
    pthread_mutex_lock(&j->svc->mu);
    r = j->cancel ? j->cancel_reason : SVC_CANCEL_NONE;
    pthread_mutex_unlock(&j->svc->mu);
    return r;
}

/* The CPU seconds the calling thread has taken. */
static double thread_cpu(void)
{
    struct timespec ts;

    if (clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts) != 0)
        return 0;
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

int svc__sync(const svc_job *j)
{
    return j->keep_result && !j->svc->store->ops->shared;
}

int svc__retry(svc_job *j, int *tries, int e, const char *what,
               int only_shutdown)
{
    svc_t *s = j->svc;
    double delay, end;

    if (!transient(e) ||
        *tries >= (svc__sync(j) ? SVC_RETRY_SYNC_TRIES : SVC_RETRY_TRIES))
        goto give_up;
    delay = 0.1 * (double)(1 << *tries);
    if (delay > 8)
        delay = 8;
    (*tries)++;
    srv_logf(SRV_LOG_WARN, "job %s: %s: %s; try %d of %d in %.1f s", j->id,
             what, strerror(e), *tries + 1, SVC_RETRY_TRIES + 1, delay);
    for (end = srv_mono() + delay; srv_mono() < end;) {
        struct timespec ts = {0, 20 * 1000 * 1000};
        int stop;
        pthread_mutex_lock(&s->mu);
        stop = j->cancel && (!only_shutdown ||
                             j->cancel_reason == SVC_CANCEL_SHUTDOWN);
        pthread_mutex_unlock(&s->mu);
        if (stop)
            goto give_up;
        nanosleep(&ts, NULL);
    }
    errno = e;
    return 1;
give_up:
    errno = e;
    return 0;
}

/* -------------------------------------------------------- start and finish */

int svc__start(svc_job *j)
{
    svc_t *s = j->svc;
    int rc;

    pthread_mutex_lock(&s->mu);
    if (j->status != SVC_JOB_QUEUED)
        rc = -1;
    else if (j->canceling || s->draining)
        rc = 1;
    else {
        rc = 0;
        j->refs++;             /* the worker's */
        j->status = SVC_JOB_RUNNING;
        j->run_here = 1;
        j->started = srv_wall();
        j->timeout = s->cfg.job_timeout > 0
                         ? s->cfg.job_timeout + s->cfg.job_timeout_per_mib *
                                                    j->mem_estimate / 1048576.0
                         : 0;
        j->deadline = j->timeout > 0 ? srv_mono() + j->timeout : 0;
        /* on the worker's thread, which runs it (workers.c) */
        j->cpu_budget = s->cfg.job_cpu > 0
                            ? s->cfg.job_cpu + s->cfg.job_cpu_per_mib *
                                                   j->mem_estimate / 1048576.0
                            : 0;
        j->cpu0 = thread_cpu();
        j->cpu_used = j->cpu_threads = 0;
        j->phase[0] = '\0';
        j->work = j->work_told = 0;
        j->nphases = 0;
        s->queued--;
        s->busy++;
        svc__notify(j, SVC_NOTIFY_STATE);
    }
    pthread_mutex_unlock(&s->mu);
    if (rc == 0)
        svc__write_state(j, 0);
    return rc;
}

/* Lock held: a job whose outcome (final) the store would not take goes
 * back to queued, where its state.json still has it, and runs again
 * after a delay (svc_sweep puts it back in the queue): 2, 4, ... 60 s. */
static void park_locked(svc_job *j, svc_job_status final, int e)
{
    int k = j->parks < 5 ? j->parks : 5;
    double delay = (double)(2 << k);

    if (delay > 60)
        delay = 60;
    j->parks++;
    j->parked = 1;
    j->retry_at = srv_mono() + delay;
    j->status = SVC_JOB_QUEUED;
    j->ready = 0;
    j->started = j->finished = 0;
    j->step = 0;
    j->t = 0;
    j->result_len = 0;
    svc__events_reset_locked(j);
    svc_error_set(&j->err, SVC_P_STORAGE, "job %s %s, but the spool "
                  "could not record it (%s); it runs again in %g s", j->id,
                  svc_job_status_name(final), strerror(e), delay);
    srv_logf(SRV_LOG_ERROR, "spool: %s", j->err.detail);
}

/* The outcome as state.json will record it. */
static void outcome_rec(const svc_job *j, const svc_outcome *o, double now,
                        svc_state_rec *r)
{
    svc__state_of(j, r);
    r->status = o->status;
    r->err = o->err;
    if (o->status == SVC_JOB_QUEUED)
        return;
    r->finished = now;
    r->result_len = o->result_len;
    if (o->status == SVC_JOB_SUCCEEDED) {
        memcpy(r->out_format, o->out_format, sizeof r->out_format);
        memcpy(r->result_name, o->result_name, sizeof r->result_name);
    }
}

/* The outcome recorded in *r applied to the job (lock held). */
static void apply_outcome_locked(svc_job *j, svc_outcome *o,
                                 const svc_state_rec *r)
{
    svc_t *s = j->svc;

    j->status = o->status;
    j->err = o->err;
    if (o->status == SVC_JOB_QUEUED) {
        j->ready = 0;
        return;
    }
    j->finished = r->finished;
    j->result_len = r->result_len;
    memcpy(j->out_format, r->out_format, sizeof j->out_format);
    memcpy(j->result_name, r->result_name, sizeof j->result_name);
    if (o->status == SVC_JOB_SUCCEEDED) {
        if (j->keep_result) {
            j->result = o->result;
            o->result = NULL;
        }
        j->disk_bytes += o->disk_add;
        if (j->in_table)
            s->disk_bytes += o->disk_add;
    }
}

/* A store with finish (store.h): what the run leaves, written with its
 * state and its ack in one step. */
typedef struct {
    svc_blob b[6];             /* result, metrics, fields, events x2, state */
    int n;
    size_t ev_len;             /* its events: bytes and lines */
    int ev_n;
} end_blobs;

static void end_add(end_blobs *eb, const char *name, const void *data,
                    size_t len)
{
    eb->b[eb->n++] = (svc_blob){name, data ? data : "", len};
}

static void end_blobs_of(svc_job *j, const svc_outcome *o, end_blobs *eb)
{
    const char *data;
    const size_t *ends;

    memset(eb, 0, sizeof *eb);
    if (o->status == SVC_JOB_SUCCEEDED) {
        end_add(eb, o->result_name, o->result, o->result_len);
        end_add(eb, "metrics.json", o->metrics,
                o->metrics ? strlen(o->metrics) : 0);
        if (o->fields)
            end_add(eb, SVC_FIELDS_FILE, o->fields, o->fields_len);
    }
    if ((eb->ev_n = svc__events_now(j, &data, &eb->ev_len, &ends)) > 0) {
        end_add(eb, "events.ndjson", data, eb->ev_len);
        end_add(eb, "events.idx", ends, (size_t)eb->ev_n * sizeof *ends);
    }
}

/* The store refused a blob of the end as too large for one value (EFBIG:
 * Redis's proto-max-bulk-len bounds each argument of the finish) or had
 * no room for it after every retry (ENOSPC, EDQUOT: the shared blob
 * directory's disk full, Redis out of memory): a succeeded run becomes
 * failed, saying why, without its result, metrics and fields; an end
 * still refused drops its events. Never parked, so never run again to
 * the same end. 0, or -1 when nothing is left to drop. */
static int end_refused(svc_job *j, svc_outcome *o, end_blobs *eb, int e)
{
    const svc_blob *big = &eb->b[0];
    int i;

    if (eb->n == 0)
        return -1;
    for (i = 1; i < eb->n; i++)
        if (eb->b[i].len > big->len)
            big = &eb->b[i];
    srv_logf(SRV_LOG_ERROR, "job %s: the store refused its %s (%zu bytes): "
             "%s", j->id, big->name, big->len,
             e == EFBIG ? "too large" : strerror(e));
    if (o->status != SVC_JOB_SUCCEEDED) {
        eb->n = eb->ev_n = 0;      /* its events alone were too large */
        eb->ev_len = 0;
        return 0;
    }
    o->status = SVC_JOB_FAILED;
    if (e == EFBIG)
        svc_error_set(&o->err, SVC_P_MESH_LIMIT, "the run ended, but its %s "
                      "(%zu bytes) is larger than the job store takes in "
                      "one value (Redis's proto-max-bulk-len, less a "
                      "margin), so it was not kept; ask for a smaller "
                      "result (another format, no fields)", big->name,
                      big->len);
    else
        svc_error_set(&o->err, SVC_P_STORAGE, "the run ended, but the job "
                      "store had no room for its %s (%zu bytes: %s; the "
                      "blob directory's disk or Redis's memory is full), so "
                      "it was not kept; submit it again once there is room",
                      big->name, big->len, strerror(e));
    o->result_len = 0;
    end_blobs_of(j, o, eb);
    return 0;
}

/* The blobs, state r and the ack in one step (state_mu held). */
static int finish_rec(svc_t *s, const svc_state_rec *r, end_blobs *eb)
{
    char *text = svc__state_json(r);
    int rc, e;

    if (!text) {
        errno = ENOMEM;
        return -1;
    }
    eb->b[eb->n] = (svc_blob){"state.json", text, strlen(text)};
    rc = s->store->ops->finish(s->store, r->id, eb->b, eb->n + 1);
    e = errno;
    free(text);
    errno = e;
    return rc;
}

/* A job that failed or was canceled never runs again: its input and
 * target leave the store now, not at its result TTL (issue 28: 15
 * uploads of 265 MB refused at decode held the default 4G spool quota
 * for an hour). Emptied, the store having no removal of one blob; best
 * effort (a failure leaves them to the TTL). */
void svc__drop_input(svc_job *j)
{
    static const char *const names[2] = {"input", "target"};
    svc_t *s = j->svc;
    svc_store *st = s->store;
    int k;

    for (k = 0; k < 1 + (j->has_target != 0); k++) {
        size_t size = 0;
        if (st->ops->stat(st, j->id, names[k], &size) != 0 || size == 0 ||
            st->ops->put(st, j->id, names[k], "", 0, 1) != 0)
            continue;
        pthread_mutex_lock(&s->mu);
        if (size > j->disk_bytes)
            size = j->disk_bytes;
        j->disk_bytes -= size;
        if (j->in_table)
            s->disk_bytes -= size;
        pthread_mutex_unlock(&s->mu);
    }
}

/* Lock held: the outcome o could not be recorded and will not be (its
 * error says why): j fails here, leaves the table (404 from now), and a
 * client waiting on it hears o's error. */
static void dropped_locked(svc_job *j, svc_outcome *o, svc_state_rec *r)
{
    srv_logf(SRV_LOG_ERROR, "%s", o->err.detail);
    o->status = r->status = SVC_JOB_FAILED;
    r->result_len = 0;
    apply_outcome_locked(j, o, r);
    if (j->in_table)
        svc__table_remove(j->svc, j);
    svc__notify(j, SVC_NOTIFY_STATE);
}

void svc__finish(svc_job *j, svc_outcome *o)
{
    svc_t *s = j->svc;
    svc_state_rec r;
    end_blobs eb;
    int tries = 0, written = 0, e = 0,
        fin = s->store->ops->finish && o->status != SVC_JOB_QUEUED,
        sync = svc__sync(j) && o->status != SVC_JOB_QUEUED;
    double now = srv_wall(), t0 = srv_mono();

    if (fin)
        end_blobs_of(j, o, &eb);
    else if (o->status != SVC_JOB_QUEUED)
        svc__events_to_store(j);
    /* The outcome is in the store before anyone can see it (GET polls,
     * waiters, a restart): a client told "succeeded" can always find the
     * result again, and no terminal state a client saw changes after a
     * restart. From each snapshot to its publication no other state.json
     * write (a DELETE's would be stale): state_mu, let go between tries. */
    for (;;) {
        pthread_mutex_lock(&s->state_mu);
        pthread_mutex_lock(&s->mu);
        outcome_rec(j, o, now, &r);
        pthread_mutex_unlock(&s->mu);
        if ((fin ? finish_rec(s, &r, &eb) : write_rec(s, &r, 1)) == 0) {
            written = 1;
            break;             /* state_mu held until published */
        }
        e = errno;
        pthread_mutex_unlock(&s->state_mu);
        if (fin && e == EFBIG && o->status != SVC_JOB_QUEUED &&
            end_refused(j, o, &eb, e) == 0)
            continue;
        /* A shutdown alone stops these tries: a cancel asked now changes
         * nothing of an outcome already reached; nor does one of a run
         * another replica took over (ESTALE: its outcome is that one's),
         * nor one whose records a shared store lost (ENOENT). */
        if (o->status == SVC_JOB_QUEUED || e == ESTALE ||
            (e == ENOENT && s->store->ops->shared))
            break;
        if (svc__retry(j, &tries, e, "recording its outcome", 1))
            continue;
        /* a shared store still full after every try: the job fails
         * clearly rather than being parked and run again to the same end */
        if (!(fin && s->store->ops->shared && tries >= SVC_RETRY_TRIES &&
              (e == ENOSPC || e == EDQUOT) &&
              end_refused(j, o, &eb, e) == 0))
            break;
    }
    if (fin)
        svc__events_done(j, written, eb.ev_len, eb.ev_n);
    pthread_mutex_lock(&s->mu);
    j->run_here = 0;
    if (!written && e == ESTALE) {
        /* still running, elsewhere: the sweep refreshes it */
        srv_logf(SRV_LOG_WARN, "job %s: its run here was taken over by "
                 "another replica; its outcome here is dropped", j->id);
        pthread_mutex_unlock(&s->mu);
        return;
    }
    if (!written && e == ENOENT && s->store->ops->shared) {
        /* nobody took it over: its records are gone, so is the job (404
         * from now); a client waiting here hears why */
        svc_error_set(&o->err, SVC_P_STORAGE, "job %s: its records are "
                      "gone from the store (a restart of a Redis without "
                      "persistence, an eviction, or a deletion); its "
                      "outcome here is dropped", j->id);
        dropped_locked(j, o, &r);
        pthread_mutex_unlock(&s->mu);
        return;
    }
    if (!written && sync && transient(e)) {
        svc_error_set(&o->err, e == ENOSPC || e == EDQUOT
                      ? SVC_P_SPOOL_FULL : SVC_P_SPOOL_UNREADY, "job %s %s, "
                      "but the spool has no room to record it (%s, %d tries "
                      "in %.1f s): it is dropped; submit it again after the "
                      "delay, or as an async job (POST /v1/jobs: its outcome "
                      "is tried for longer)", j->id,
                      svc_job_status_name(o->status), strerror(e), tries + 1,
                      srv_mono() - t0);
        o->err.retry_after = 5;
        dropped_locked(j, o, &r);
        pthread_mutex_unlock(&s->mu);
        srv_metrics_job(j->scheme, "failed", o->run_s);
        s->store->ops->ack(s->store, j->id);
        if (s->store->ops->remove(s->store, j->id) != 0)
            srv_logf(SRV_LOG_WARN, "job %s: cannot remove its files (%s): "
                     "it runs again after a restart, for no one", j->id,
                     strerror(errno));
        return;
    }
    if (!written && o->status != SVC_JOB_QUEUED)
        park_locked(j, o->status, e);
    else
        apply_outcome_locked(j, o, &r);
    pthread_mutex_unlock(&s->mu);
    if (written)
        pthread_mutex_unlock(&s->state_mu);
    /* a shared queue: a job stopped by the shutdown goes back to its head
     * for another replica (else its entry stays pending and the reaper
     * hands it over) */
    if (!(fin && written) &&
        !(s->store->ops->shared && o->status == SVC_JOB_QUEUED &&
          (!written || s->store->ops->push(s->store, j->id, 1) != 0)))
        s->store->ops->ack(s->store, j->id);
    /* Counted before anyone hears, so /metrics agrees with what clients
     * have seen. */
    if (written && o->status != SVC_JOB_QUEUED) {
        srv_metrics_job(j->scheme, svc_job_status_name(o->status), o->run_s);
        svc__log_job(j, o->nv, o->nf, o->run_s);
    }
    if (written && (o->status == SVC_JOB_FAILED ||
                    o->status == SVC_JOB_CANCELED))
        svc__drop_input(j);
    pthread_mutex_lock(&s->mu);
    svc__notify(j, SVC_NOTIFY_STATE);
    pthread_mutex_unlock(&s->mu);
}

/* ---------------------------------------------------------------- progress */

int svc__canceled_error(svc_job *j, int steps, svc_error *e)
{
    svc_t *s = j->svc;
    char when[96];
    svc_cancel_reason reason;
    char phase[sizeof j->phase];
    double work;

    pthread_mutex_lock(&s->mu);
    reason = j->cancel_reason;
    memcpy(phase, j->phase, sizeof phase);
    work = j->work;
    pthread_mutex_unlock(&s->mu);
    if (steps >= 0 && phase[0])
        snprintf(when, sizeof when, "after step %d, in its %s phase with "
                 "%.0f%% of its work done", steps, phase, 100.0 * work);
    else if (steps >= 0)
        snprintf(when, sizeof when, "after step %d", steps);
    else
        snprintf(when, sizeof when, "while its input was decoded");
    if (reason == SVC_CANCEL_SHUTDOWN)
        svc_error_set(e, SVC_P_DRAINING, "the daemon shut down while job %s "
                      "ran; it runs again after the restart", j->id);
    else if (reason == SVC_CANCEL_TIMEOUT)
        svc_error_set(e, SVC_P_TIMEOUT, "the job ran longer than its "
                      "timeout, %.2f s (--job-timeout %g s + %g s per MiB of "
                      "its memory estimate, %.1f MiB), and was stopped %s",
                      j->timeout, s->cfg.job_timeout,
                      s->cfg.job_timeout_per_mib, j->mem_estimate / 1048576.0,
                      when);
    else if (reason == SVC_CANCEL_CPU)
        svc_error_set(e, SVC_P_TIMEOUT, "the job used more than its CPU "
                      "budget, %.2f s (--job-cpu %g s + %g s per MiB of its "
                      "memory estimate, %.1f MiB), and was stopped %s",
                      j->cpu_budget, s->cfg.job_cpu, s->cfg.job_cpu_per_mib,
                      j->mem_estimate / 1048576.0, when);
    else if (reason == SVC_CANCEL_CLIENT)
        svc_error_set(e, SVC_P_CANCELED, "canceled %s: the client closed "
                      "its connection before the answer", when);
    else
        svc_error_set(e, SVC_P_CANCELED, "canceled by request %s", when);
    e->cancel = reason;
    return reason == SVC_CANCEL_SHUTDOWN;
}

void svc__ready(svc_job *j, const char *scheme, const char *in_format)
{
    svc_t *s = j->svc;

    pthread_mutex_lock(&s->mu);
    snprintf(j->scheme, sizeof j->scheme, "%s", scheme);
    snprintf(j->in_format, sizeof j->in_format, "%s", in_format);
    j->ready = 1;
    svc__notify(j, SVC_NOTIFY_STATE);
    pthread_mutex_unlock(&s->mu);
}

/* Lock held: the job timeout and the CPU budget (threads_cpu_s: the CPU
 * of the threads its flow started); sets the cancel flag past either,
 * which the flow loads before its next step or pass. */
static void limits_locked(svc_job *j, double threads_cpu_s)
{
    if (!j->cancel && j->deadline > 0 && srv_mono() > j->deadline) {
        j->cancel = 1;
        j->cancel_reason = SVC_CANCEL_TIMEOUT;
    }
    /* the worker's thread runs the flow and calls the hooks; the threads
     * the flow starts (mcf_flow_params.threads) count too */
    if (j->cpu_budget > 0) {
        j->cpu_threads = threads_cpu_s;
        j->cpu_used = thread_cpu() - j->cpu0 + j->cpu_threads;
    }
    if (!j->cancel && j->cpu_budget > 0 && j->cpu_used > j->cpu_budget) {
        j->cancel = 1;
        j->cancel_reason = SVC_CANCEL_CPU;
        srv_metrics_cpu_budget();
    }
}

int svc__progress(svc_job *j, const api_job_step *st)
{
    svc_t *s = j->svc;
    char line[SVC_EVENT_LINE];
    int stop, n = svc__event_line(st, line);

    pthread_mutex_lock(&s->mu);
    j->step = st->step;
    j->t = st->t;
    j->dt = st->dt;
    j->energy = st->energy;
    j->volume = st->volume;
    if (n > 0)
        svc__event_add_locked(j, line, (size_t)n);
    svc__notify(j, SVC_NOTIFY_PROGRESS);
    limits_locked(j, st->threads_cpu_s);
    stop = j->cancel;
    pthread_mutex_unlock(&s->mu);
    if (n > 0)
        s->store->ops->progress(s->store, j->id, line, (size_t)n);
    return stop;
}

/* The followers hear of a milestone when its phase changes or its share
 * moves by SVC_WORK_STEP: a pass of the default filter may take a
 * millisecond, and a stream needs no more than a hundred updates. */
void svc__work(svc_job *j, const char *phase, double done,
               double threads_cpu_s)
{
    svc_t *s = j->svc;
    int changed;

    pthread_mutex_lock(&s->mu);
    j->work = done;
    changed = strncmp(j->phase, phase, sizeof j->phase - 1) != 0;
    if (changed && j->nphases < SVC_PHASES_MAX) {
        svc_phase *e = &j->phases[j->nphases++];
        snprintf(e->phase, sizeof e->phase, "%s", phase);
        e->step = j->step;
        e->fraction = done;
    }
    if (changed || done >= j->work_told + SVC_WORK_STEP || done >= 1.0) {
        snprintf(j->phase, sizeof j->phase, "%s", phase);
        j->work_told = done;
        svc__notify(j, SVC_NOTIFY_PROGRESS);
    }
    limits_locked(j, threads_cpu_s);
    pthread_mutex_unlock(&s->mu);
}

/* ------------------------------------------------------------------ cancel */

/* A queued job canceled: its state (lock held). */
static void cancel_queued_locked(svc_job *j, svc_cancel_reason reason,
                                 double now)
{
    j->status = SVC_JOB_CANCELED;
    j->cancel = 1;
    j->cancel_reason = reason;
    j->finished = now;
    if (reason == SVC_CANCEL_CLIENT)
        svc_error_set(&j->err, SVC_P_CANCELED, "canceled while queued: the "
                      "client closed its connection before the answer");
    else
        svc_error_set(&j->err, SVC_P_CANCELED, "canceled by request while "
                      "queued");
    j->err.cancel = reason;
}

/* The state a cancel records: a queued job canceled; a running one with
 * cancel_requested (its cancel flag, which the flow reads without the
 * lock, is set only once that is written). */
static void cancel_rec(const svc_job *j, svc_cancel_reason reason, double now,
                       svc_state_rec *r)
{
    svc__state_of(j, r);
    if (j->status != SVC_JOB_QUEUED) {
        r->cancel_requested = reason;
        return;
    }
    r->status = SVC_JOB_CANCELED;
    r->finished = now;
    r->cancel_requested = SVC_CANCEL_NONE;
    svc_error_set(&r->err, SVC_P_CANCELED, "%s", reason == SVC_CANCEL_CLIENT
                  ? "canceled while queued: the client closed its connection "
                    "before the answer"
                  : "canceled by request while queued");
    r->err.cancel = reason;
}

int svc_cancel(svc_job *j, svc_cancel_reason reason)
{
    svc_t *s = j->svc;
    svc_state_rec r;
    int rc, e, was_queued, run_here, changed = 0, unclaimed, taken;
    double now = srv_wall();

    pthread_mutex_lock(&s->state_mu);
    pthread_mutex_lock(&s->mu);
    if ((j->cancel && j->status == SVC_JOB_RUNNING) || j->canceling ||
        (j->status != SVC_JOB_QUEUED && j->status != SVC_JOB_RUNNING)) {
        pthread_mutex_unlock(&s->mu);
        pthread_mutex_unlock(&s->state_mu);
        return 0;
    }
    /* No worker starts it while its cancel is written (svc__start). */
    j->canceling = reason;
    j->refs++;
    cancel_rec(j, reason, now, &r);
    pthread_mutex_unlock(&s->mu);
    /* a shared store decides: canceled while queued, or started by
     * another replica first (ESTALE: that one's run stops, and it ends
     * and counts the job) */
    unclaimed = s->store->ops->shared && r.status == SVC_JOB_CANCELED;
    rc = write_rec(s, &r, unclaimed ? SVC_PUT_UNCLAIMED : 1);
    e = errno;
    taken = rc != 0 && unclaimed && e == ESTALE;
    pthread_mutex_lock(&s->mu);
    j->canceling = SVC_CANCEL_NONE;
    was_queued = j->status == SVC_JOB_QUEUED;
    run_here = j->run_here;
    if (rc == 0 && was_queued) {
        if (!j->parked)
            s->queued--;
        j->parked = 0;
        cancel_queued_locked(j, reason, now);
        svc__notify(j, SVC_NOTIFY_STATE);
        changed = 1;
    } else if (rc == 0 && j->status == SVC_JOB_RUNNING) {
        j->cancel_reason = reason;
        j->cancel = 1;
    }
    if (was_queued)
        svc__wake_locked(s); /* a worker may have put it back meanwhile */
    pthread_mutex_unlock(&s->mu);
    pthread_mutex_unlock(&s->state_mu);
    /* a shared store: the replica that runs it (or starts it before
     * it reads the state written here) stops it at its next sweep */
    if ((rc == 0 || taken) && s->store->ops->shared && !run_here)
        svc__cancel_elsewhere(j, reason);
    if (changed) {
        s->store->ops->drop(s->store, j->id);
        srv_metrics_job(j->scheme, "canceled", 0);
        svc__log_job(j, 0, 0, 0);
    }
    svc_job_unref(j);
    errno = e;
    return rc == 0 || taken ? 1 : -1;
}

/* ------------------------------------------- a store shared by replicas */

/* Lock held: whether j counts in s->queued (queued, not parked). */
static int counted(const svc_job *j)
{
    return j->in_table && j->status == SVC_JOB_QUEUED && !j->parked;
}

int svc__remote_state(svc_job *j, const svc_state_rec *r, int nevents,
                      size_t events_bytes)
{
    svc_t *s = j->svc;
    int was = counted(j), step = j->step, changed;
    double t = j->t;

    if (j->run_here || j->canceling || svc_job_status_terminal(j->status))
        return 0;
    changed = j->status != r->status || j->started != r->started ||
              (r->cancel_requested && !j->cancel);
#define X(f) SVC_COPY(j, r, f)
    SVC_RECORDED(X)
#undef X
    j->err = r->err;
    if (r->cancel_requested && j->status == SVC_JOB_RUNNING) {
        j->cancel = 1;
        j->cancel_reason = r->cancel_requested;
    }
    j->ready = j->status == SVC_JOB_RUNNING;
    if (j->status == SVC_JOB_RUNNING && step > j->step) {
        j->step = step;        /* its progress stream is ahead of state.json */
        j->t = t;
    }
    s->queued += counted(j) - was;
    if (changed && svc_job_status_terminal(j->status)) {
        svc__events_reset_locked(j);   /* the store has them all now */
        j->nevents = nevents;
        j->events_disk = events_bytes;
    }
    if (changed)
        svc__notify(j, SVC_NOTIFY_STATE);
    return changed;
}

static double num_of(const cJSON *o, const char *key, double dflt)
{
    const cJSON *e = cJSON_GetObjectItemCaseSensitive(o, key);
    return cJSON_IsNumber(e) ? e->valuedouble : dflt;
}

void svc__remote_progress(svc_job *j, const char *line, size_t len)
{
    cJSON *o;

    if (j->run_here || j->status != SVC_JOB_RUNNING ||
        !(o = cJSON_ParseWithLength(line, len)))
        return;
    /* The events held are a prefix of the run's (its end replaces them
     * with the stored ones and a follower goes on from its count): a
     * line after a gap (lines the runner could not publish while Redis
     * was down, or trimmed from a long run's stream) is not kept, and
     * the followers wait for the end. */
    if (num_of(o, "step", 0) != j->nevents + 1) {
        cJSON_Delete(o);
        return;
    }
    j->step = (int)num_of(o, "step", j->step);
    j->t = num_of(o, "t", j->t);
    j->dt = num_of(o, "dt", j->dt);
    j->energy = num_of(o, "energy", NAN);
    j->volume = num_of(o, "volume", NAN);
    cJSON_Delete(o);
    j->ready = 1;
    svc__event_add_locked(j, line, len);
    svc__notify(j, SVC_NOTIFY_PROGRESS);
}

void svc__retaken_locked(svc_job *j)
{
    svc_t *s = j->svc;

    if (j->run_here || j->status != SVC_JOB_RUNNING)
        return;
    j->status = SVC_JOB_QUEUED;
    j->started = 0;
    j->step = 0;
    j->t = 0;
    j->ready = 0;
    svc__events_reset_locked(j);
    if (counted(j))
        s->queued++;
    svc__notify(j, SVC_NOTIFY_STATE);
}

void svc__dead(svc_job *j)
{
    svc_t *s = j->svc;
    svc_state_rec r;
    double now = srv_wall();
    int was;

    pthread_mutex_lock(&s->state_mu);
    pthread_mutex_lock(&s->mu);
    if (j->run_here || svc_job_status_terminal(j->status)) {
        pthread_mutex_unlock(&s->mu);
        pthread_mutex_unlock(&s->state_mu);
        return;
    }
    svc__state_of(j, &r);
    r.status = SVC_JOB_FAILED;
    r.finished = now;
    r.cancel_requested = SVC_CANCEL_NONE;
    svc_error_set(&r.err, SVC_P_INTERNAL, "job %s was not run again: the "
                  "replica running it stopped (killed, out of memory, or "
                  "lost) during each of its runs", j->id);
    pthread_mutex_unlock(&s->mu);
    if (write_rec(s, &r, 1) != 0) {
        /* the store keeps it dead-lettered; another read retries */
        srv_logf(SRV_LOG_ERROR, "job %s: cannot record it failed (dead "
                 "letter): %s", j->id, strerror(errno));
        pthread_mutex_unlock(&s->state_mu);
        return;
    }
    pthread_mutex_lock(&s->mu);
    was = counted(j);
    j->status = SVC_JOB_FAILED;
    j->finished = now;
    j->err = r.err;
    s->queued -= was;
    svc__events_reset_locked(j);
    svc__notify(j, SVC_NOTIFY_STATE);
    pthread_mutex_unlock(&s->mu);
    pthread_mutex_unlock(&s->state_mu);
    srv_metrics_job(j->scheme, "failed", 0);
    svc__log_job(j, 0, 0, 0);
}

void svc__cancel_elsewhere(svc_job *j, svc_cancel_reason reason)
{
    svc_store *st = j->svc->store;
    char text[32];
    int n = snprintf(text, sizeof text, "{\"reason\":%d}", (int)reason);

    if (st->ops->put(st, j->id, "cancel.json", text, (size_t)n, 1) != 0)
        srv_logf(SRV_LOG_WARN, "job %s: its cancel could not be passed to "
                 "the replica running it: %s", j->id, strerror(errno));
}

/* ---------------------------------------------------------------- recovery */

/* The recorded state applied to a job being loaded. */
static void apply_rec(svc_job *j, const svc_state_rec *r)
{
#define X(f) SVC_COPY(j, r, f)
    SVC_RECORDED(X)
#undef X
    if (r->cancel_requested) {
        j->cancel = 1;
        j->cancel_reason = r->cancel_requested;
    }
    j->err = r->err;
}

int svc__recovered(svc_job *j, const svc_state_rec *loaded)
{
    svc_state_rec r;

    apply_rec(j, loaded);
    j->recovered = 1;
    if (svc_job_status_terminal(j->status))
        return 0;
    if (j->cancel) {
        /* Canceled while it ran, and the process ended before the step
         * did: it stays canceled. */
        svc_cancel_reason why = j->cancel_reason;
        j->status = SVC_JOB_CANCELED;
        j->finished = srv_wall();
        svc_error_set(&j->err, SVC_P_CANCELED, "canceled %s while it ran, "
                      "before the daemon restarted; it did not run again",
                      why == SVC_CANCEL_USER ? "by request"
                                             : "when its client hung up");
        j->err.cancel = why;
        svc__state_of(j, &r);
        if (write_rec(j->svc, &r, 1) != 0)
            srv_logf(SRV_LOG_WARN, "spool: cannot record job %s as "
                     "canceled: %s", j->id, strerror(errno));
        return 0;
    }
    /* queued, or running when the process died: run it again */
    j->status = SVC_JOB_QUEUED;
    j->started = 0;
    j->step = 0;
    j->t = 0;
    return 1;
}
