/*
 * runner.c - one job, start to end, on a worker thread: reads the input
 * back from the spool, runs the job (api_job_run: decode, check, smooth
 * with progress events, encode, the metrics document), writes result and
 * metrics to the spool, and publishes the outcome (state.json first, then
 * memory, then the subscribers).
 *
 * What is the daemon's comes in through api_job_run's hooks: the Draco
 * sandbox (sandbox.c), memory admission once the counts are known
 * (svc_admit.c), the progress events and the job timeout, the result
 * written to the spool. No lock is held across mesh work or disk I/O: the
 * job's fields are read and written in short sections under the service
 * lock.
 */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "svc_internal.h"
#include "svc_admit.h"
#include "sandbox.h"

typedef struct {
    svc_job *job;
    double deadline;          /* srv_mono() seconds, 0: none */
    int tries;                /* retries spent (runner's retry) */
    int keep_fields;          /* fields=true */
    size_t input_len, target_len;
    svc_error prob;           /* a hook's own error (memory, the spool) */
    int has_prob;
} run_ctx;

static void fmt_num(char *buf, size_t size, double v)
{
    if (isfinite(v))
        snprintf(buf, size, "%.17g", v);
    else
        snprintf(buf, size, "null");
}

/* Errors of a resource a client can exhaust (descriptors, disk space,
 * memory) are worth trying again; any other is final at once. */
static int transient(int e)
{
    return e == EMFILE || e == ENFILE || e == ENOSPC || e == EDQUOT ||
           e == ENOMEM || e == EAGAIN || e == ENOBUFS;
}

/* Before attempt *tries + 2 of a step that failed with errno e: waits
 * 0.1 s doubling to at most 8 s (SVC_RETRY_TRIES retries: 37 s in all),
 * watching the cancel flag (any cancel, or with only_shutdown the
 * shutdown's alone). 1 to try again; 0 to give up: e is not transient,
 * the tries are spent, or the job is being stopped. errno is kept. */
static int retry(svc_job *j, int *tries, int e, const char *what,
                 int only_shutdown)
{
    double delay, end;

    if (!transient(e) || *tries >= SVC_RETRY_TRIES)
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
        svc__lock();
        stop = j->cancel && (!only_shutdown ||
                             j->cancel_reason == SVC_CANCEL_SHUTDOWN);
        svc__unlock();
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

/* srv_spool_read, tried again on a transient error (retry). */
static int read_retry(svc_job *j, const char *name, char **data, size_t *len,
                      int *tries)
{
    char what[64];
    snprintf(what, sizeof what, "reading its %s", name);
    while (srv_spool_read(svc__S.cfg.spool, j->id, name, data, len) != 0)
        if (!retry(j, tries, errno, what, 0))
            return -1;
    return 0;
}

/* srv_spool_write (durable), tried again on a transient error. */
static int write_retry(svc_job *j, const char *name, const void *data,
                       size_t len, int *tries)
{
    while (srv_spool_write(svc__S.cfg.spool, j->id, name, data, len, 1) != 0)
        if (!retry(j, tries, errno, "writing its result", 0))
            return -1;
    return 0;
}

/* Lock held: one more ndjson line in the job's event log (dropped when
 * the log is full or memory is short: the stream then skips it). */
static void add_event(svc_job *j, const char *line, size_t n)
{
    if (j->nevents == j->event_cap) {
        int cap = j->event_cap ? 2 * j->event_cap : 256;
        size_t *p = realloc(j->event_end, (size_t)cap * sizeof *p);
        if (!p)
            return;
        j->event_end = p;
        j->event_cap = cap;
    }
    if (api_buf_append(&j->events, line, n) == MCF_OK)
        j->event_end[j->nevents++] = j->events.len;
}

/* The error of a job stopped by its cancel flag after `steps` steps
 * (-1: before its flow); 1 when it must run again after a restart. */
static int canceled_error(svc_job *j, int steps, svc_error *prob)
{
    const svc_config *cfg = &svc__S.cfg;
    char when[48];
    int reason;

    svc__lock();
    reason = j->cancel_reason;
    svc__unlock();
    if (steps >= 0)
        snprintf(when, sizeof when, "after step %d", steps);
    else
        snprintf(when, sizeof when, "while its input was decoded");
    if (reason == SVC_CANCEL_SHUTDOWN)
        svc_error_set(prob, SVC_P_DRAINING, "the daemon shut down "
                      "while job %s ran; it runs again after the restart",
                      j->id);
    else if (reason == SVC_CANCEL_TIMEOUT)
        svc_error_set(prob, SVC_P_TIMEOUT, "the job ran longer than "
                      "--job-timeout %g s and was stopped %s",
                      cfg->job_timeout, when);
    else if (reason == SVC_CANCEL_CLIENT)
        svc_error_set(prob, SVC_P_CANCELED, "canceled %s: the client "
                      "closed its connection before the answer", when);
    else
        svc_error_set(prob, SVC_P_CANCELED, "canceled by request %s",
                      when);
    prob->cancel = (svc_cancel_reason)reason;
    return reason == SVC_CANCEL_SHUTDOWN;
}

/* ------------------------------------------------------------------ hooks */

/* sandbox.c: Draco decodes in a child process under limits; a decode out
 * of memory is tried again (retry). */
static mcf_status hook_decode(void *ctx, const char *part, const void *buf,
                              size_t len, const api_limits *lim,
                              mcf_mesh **out, api_attrs **attrs,
                              api_format *fmt, api_job_stage *stage,
                              mcf_error *err)
{
    run_ctx *c = ctx;
    mcf_status rc;

    (void)lim;
    while ((rc = svc_decode_upload(buf, len, &svc__S.cfg, &c->job->cancel,
                                   out, attrs, fmt, stage, err)) == MCF_ENOMEM &&
           strcmp(part, "mesh") == 0 &&
           retry(c->job, &c->tries, ENOMEM, "decoding", 0))
        ;
    return rc;
}

/* After decoding: the estimate from the real counts (svc_admit.c); over
 * --max-job-memory an ELIMIT, else the reservation grows (waiting for
 * memory; ECANCELED when the job is stopped meanwhile). */
static mcf_status hook_decoded(void *ctx, int nv, int nf, const api_params *p,
                               mcf_error *err)
{
    run_ctx *c = ctx;
    /* fields=true: the mesh kept from before the flow (48 bytes a vertex
     * with its faces), five double fields (40) and the document (68, up
     * to twice that while its buffer grows). */
    double est = svc_admit_estimate_counts(nv, nf, c->input_len, c->target_len,
                                           p, &svc__S.cfg.lim) +
                 (c->keep_fields ? 256.0 * nv : 0);

    if (svc_admit_refuse(&svc__S.cfg, est, &c->prob)) {
        c->has_prob = 1;
        return mcf_error_set(err, MCF_ELIMIT, "%s", c->prob.detail);
    }
    if (svc_admit_grow(&svc__S.cfg, &c->job->mem_held, est, &c->job->cancel) != 0)
        return mcf_error_set(err, MCF_ECANCELED, "canceled");
    return MCF_OK;
}

/* Decoded and checked: the scheme it runs (a request without one runs
 * the default the mesh's size chose), its input format; streams may
 * start. */
static void hook_ready(void *ctx, const api_params *p, api_format in_fmt)
{
    svc_job *j = ((run_ctx *)ctx)->job;

    svc__lock();
    snprintf(j->scheme, sizeof j->scheme, "%s", mcf_scheme_get(p->flow.scheme)->name);
    j->ready = 1;
    snprintf(j->in_format, sizeof j->in_format, "%s", api_format_name(in_fmt));
    svc__notify(j, SVC_NOTIFY_STATE);
    svc__unlock();
}

/* One ndjson event per step for the followers; a passed job timeout
 * becomes a cancel. */
static int hook_progress(void *ctx, const api_job_step *s)
{
    run_ctx *c = ctx;
    svc_job *j = c->job;
    char line[320], a[32], b[32], e[32], v[32];
    int stop, n;

    fmt_num(a, sizeof a, s->t);
    fmt_num(b, sizeof b, s->dt);
    fmt_num(e, sizeof e, s->energy);
    fmt_num(v, sizeof v, s->volume);
    n = snprintf(line, sizeof line,
                 "{\"step\":%d,\"t\":%s,\"dt\":%s,\"energy\":%s,\"volume\":%s}\n",
                 s->step, a, b, e, v);
    svc__lock();
    j->step = s->step;
    j->t = s->t;
    j->dt = s->dt;
    j->energy = s->energy;
    j->volume = s->volume;
    if (n > 0)
        add_event(j, line, (size_t)n);
    svc__notify(j, SVC_NOTIFY_PROGRESS);
    if (!j->cancel && c->deadline > 0 && srv_mono() > c->deadline) {
        j->cancel = 1;
        j->cancel_reason = SVC_CANCEL_TIMEOUT;
    }
    stop = j->cancel;
    svc__unlock();
    return stop;
}

/* The result on the spool (durable, retried). */
static mcf_status hook_store(void *ctx, const api_buf *out, const char *name,
                             mcf_error *err)
{
    run_ctx *c = ctx;
    svc_job *j = c->job;

    if (write_retry(j, name, out->data ? out->data : "", out->len, &c->tries) == 0)
        return MCF_OK;
    svc_error_set(&c->prob, SVC_P_STORAGE, "cannot write the result of "
                  "job %s to the spool (%d tries): %s", j->id, c->tries + 1,
                  strerror(errno));
    c->has_prob = 1;
    return mcf_error_set(err, MCF_EIO, "%s", c->prob.detail);
}

/* ---------------------------------------------------------------- the run */

/* The service error of a failed api_job_run: a hook's own, a cancel, or
 * the core's or a codec's with its stage and part. 1 when the job must
 * run again after a restart. */
static int job_error(run_ctx *c, const api_job_result *res, svc_error *prob)
{
    const char *part = res->part ? res->part : "";
    int prefixed = strcmp(part, "params") != 0 && strcmp(part, "fields") != 0;

    if (res->err.status == MCF_ECANCELED && c->job->cancel)
        return canceled_error(c->job, strcmp(part, "flow") == 0
                                           ? res->stats.steps : -1, prob);
    if (c->has_prob) {
        *prob = c->prob;
        return c->job->cancel ? canceled_error(c->job, -1, prob) : 0;
    }
    svc_error_from_mcf(prob, res->err.status, res->stage,
                       prefixed ? part : NULL, &res->err);
    return 0;
}

/* Reads the input (and target) back, runs the job, writes the result,
 * the metrics and the fields. 0 and *disk_add the bytes written, or -1
 * with *prob (and *requeue when the job must run again after a restart). */
static int run(svc_job *j, api_job_result *res, svc_error *prob, int *requeue,
               size_t *disk_add)
{
    const svc_config *cfg = &svc__S.cfg;
    api_job_request rq;
    api_job_hooks h;
    api_params prm;
    run_ctx c;
    char *input = NULL, *target = NULL, *metrics = NULL;
    mcf_error err = {MCF_OK, ""};
    mcf_status rc;
    int ok = -1;
    double t0 = mcf_now();

    memset(&c, 0, sizeof c);
    c.job = j;
    api_job_request_init(&rq);
    svc__lock();
    rq.queue_s = j->started - j->created;
    svc__unlock();
    if (read_retry(j, "input", &input, &c.input_len, &c.tries) != 0 ||
        (j->rec.has_target &&
         read_retry(j, "target", &target, &c.target_len, &c.tries) != 0)) {
        svc_error_set(prob, SVC_P_STORAGE, "cannot read the input of "
                      "job %s from the spool (%d tries): %s", j->id,
                      c.tries + 1, strerror(errno));
        *requeue = j->cancel && canceled_error(j, -1, prob);
        goto out;
    }
    rq.read_s = mcf_now() - t0;
    if ((rc = svc_record_params(&j->rec, &cfg->lim, &prm, &err)) != MCF_OK) {
        svc_error_from_mcf(prob, rc, API_JOB_PARAMS, NULL, &err);
        goto out;
    }
    if (svc_record_fields(&j->rec, &c.keep_fields, prob) != 0) {
        api_params_free(&prm);
        goto out;
    }
    rq.input = input;
    rq.input_len = c.input_len;
    rq.target = target;
    rq.target_len = c.target_len;
    rq.free_bytes = 1;
    input = target = NULL;
    rq.lim = &cfg->lim;
    rq.metrics = 1;
    rq.fields = c.keep_fields;
    rq.max_output = SVC_RESULT_MAX;
    rq.job = j->id;
    rq.input_name = j->rec.filename[0] ? j->rec.filename : NULL;
    rq.target_name = "target";
    rq.output_stem = "result";
    c.deadline = cfg->job_timeout > 0 ? srv_mono() + cfg->job_timeout : 0;
    memset(&h, 0, sizeof h);
    h.ctx = &c;
    h.decode = hook_decode;
    h.decoded = hook_decoded;
    h.ready = hook_ready;
    h.progress = hook_progress;
    h.store = hook_store;
    h.cancel = &j->cancel;
    rc = api_job_run(&rq, &prm, &h, res);
    api_params_free(&prm);
    free(rq.input);
    free(rq.target);
    if (rc != MCF_OK) {
        *requeue = job_error(&c, res, prob);
        goto out;
    }
    metrics = cJSON_PrintUnformatted(res->metrics);
    if (!metrics) {
        svc_error_set(prob, SVC_P_NOMEM, "out of memory writing metrics");
        goto out;
    }
    if (write_retry(j, "metrics.json", metrics, strlen(metrics), &c.tries) != 0 ||
        (c.keep_fields && write_retry(j, SVC_FIELDS_FILE, res->fields.data,
                                      res->fields.len, &c.tries) != 0)) {
        svc_error_set(prob, SVC_P_STORAGE, "cannot write the result of "
                      "job %s to the spool (%d tries): %s", j->id, c.tries + 1,
                      strerror(errno));
        *requeue = j->cancel && canceled_error(j, -1, prob);
        goto out;
    }
    svc__lock();
    snprintf(j->out_format, sizeof j->out_format, "%s",
             api_format_name(res->output_format));
    snprintf(j->result_name, sizeof j->result_name, "%s", res->output_name);
    svc__unlock();
    /* its metrics stay on disk only (svc_read.c reads them) */
    *disk_add = res->output.len + strlen(metrics) + res->fields.len;
    ok = 0;
out:
    free(input);
    free(target);
    free(metrics);
    return ok;
}

/* Lock held: a job whose outcome (final) the spool would not take goes
 * back to queued, where its state.json still has it, and runs again
 * after a delay (svc_sweep puts it back in the queue): 2, 4, ... 60 s.
 * A client never sees an outcome a restart could change. */
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
    /* its progress runs again from step 1 */
    api_buf_free(&j->events);
    api_buf_init(&j->events, SVC_EVENTS_MAX);
    j->nevents = 0;
    svc_error_set(&j->err, SVC_P_STORAGE, "job %s %s, but the spool "
                  "could not record it (%s); it runs again in %g s", j->id,
                  svc_job_status_name(final), strerror(e), delay);
    srv_logf(SRV_LOG_ERROR, "spool: %s", j->err.detail);
}

void svc__run_job(svc_job *j)
{
    const svc_config *cfg = &svc__S.cfg;
    api_job_result res;
    svc_error prob;
    int failed, requeue = 0, tries, written = 0, e = 0;
    size_t disk_add = 0;
    svc_job_status final;
    char *state = NULL;
    double t0 = mcf_now();

    memset(&prob, 0, sizeof prob);
    api_job_result_init(&res);
    svc__write_state(j, 0);
    failed = run(j, &res, &prob, &requeue, &disk_add) != 0;
    /* The outcome is on disk before anyone can see it (GET polls,
     * waiters, a restart): a client told "succeeded" can always find the
     * result again, and no terminal state a client saw changes after a
     * restart. From each snapshot to its publication no other state.json
     * write (a DELETE's would be stale): svc_state_mu, let go between
     * tries. */
    svc__lock();
    if (requeue) {
        /* Back to queued on disk; the process is exiting. */
        final = SVC_JOB_QUEUED;
        j->ready = 0;
        j->err = prob;
    } else {
        final = !failed ? SVC_JOB_SUCCEEDED
                : j->cancel && (j->cancel_reason == SVC_CANCEL_USER ||
                                j->cancel_reason == SVC_CANCEL_CLIENT)
                    ? SVC_JOB_CANCELED : SVC_JOB_FAILED;
        j->err = prob;
        j->finished = srv_wall();
        j->result_len = failed ? 0 : res.output.len;
    }
    svc__unlock();
    for (tries = 0;;) {
        pthread_mutex_lock(&svc_state_mu);
        svc__lock();
        j->status = final;
        state = svc__state_json(j);
        j->status = SVC_JOB_RUNNING;
        svc__unlock();
        if (state && srv_spool_write(cfg->spool, j->id, "state.json", state,
                                     strlen(state), 1) == 0) {
            written = 1;
            break; /* svc_state_mu held until published */
        }
        e = state ? errno : ENOMEM;
        free(state);
        state = NULL;
        pthread_mutex_unlock(&svc_state_mu);
        /* A shutdown alone stops these tries: a cancel asked now changes
         * nothing of an outcome already reached. */
        if (requeue || !retry(j, &tries, e, "recording its outcome", 1))
            break;
    }
    free(state);
    svc__lock();
    if (!written && !requeue) {
        park_locked(j, final, e);
    } else {
        j->status = final;
        if (final == SVC_JOB_SUCCEEDED) {
            size_t add = disk_add;
            if (j->keep_result) {
                size_t len;
                j->result = api_buf_detach(&res.output, &len);
            }
            j->disk_bytes += add;
            if (j->in_table)
                svc__S.disk_bytes += add;
        }
    }
    svc__unlock();
    if (written)
        pthread_mutex_unlock(&svc_state_mu);
    /* Counted before anyone hears, so /metrics agrees with what clients
     * have seen. */
    if (written && !requeue) {
        srv_metrics_job(j->scheme, svc_job_status_name(j->status),
                        mcf_now() - t0);
        svc__log_job(j, res.nv, res.nf, mcf_now() - t0);
    }
    svc__lock();
    svc__notify(j, SVC_NOTIFY_STATE);
    svc__unlock();
    api_job_result_free(&res);
}
