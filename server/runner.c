/*
 * runner.c - one job, start to end, on a worker thread: reads the input
 * back from the spool, rebuilds the parameters from the record, decodes,
 * checks, smooths with progress events, encodes, computes the metrics
 * document, writes result and metrics to the spool, and publishes the
 * outcome (state.json first, then memory, then the subscribers).
 *
 * No lock is held across mesh work or disk I/O: the job's fields are
 * read and written in short sections under the service lock. The
 * progress callback appends one ndjson event per step, notifies the
 * progress subscribers and turns a passed job timeout into a cancel.
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
    const mcf_flow_stats *st; /* the run's statistics: its step log */
    double deadline;          /* srv_mono() seconds, 0: none */
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

static int on_progress(void *ctx, int step, double t, double dt, double energy)
{
    run_ctx *c = ctx;
    svc_job *j = c->job;
    /* The step's volume is the step log's (the core fills entry step - 1
     * before this call): the quantity of flow.volume0/volume1 and
     * mcf_mesh_volume, in input units (api_metrics.c). */
    double vol = c->st->log && step >= 1 && step <= c->st->nlog
                     ? c->st->log[step - 1].volume : NAN;
    char line[320], a[32], b[32], e[32], v[32];
    int stop, n;

    fmt_num(a, sizeof a, t);
    fmt_num(b, sizeof b, dt);
    fmt_num(e, sizeof e, energy);
    fmt_num(v, sizeof v, vol);
    n = snprintf(line, sizeof line,
                 "{\"step\":%d,\"t\":%s,\"dt\":%s,\"energy\":%s,\"volume\":%s}\n",
                 step, a, b, e, v);
    svc__lock();
    j->step = step;
    j->t = t;
    j->dt = dt;
    j->energy = energy;
    j->volume = vol;
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

/* When the run is over, before its outcome is published: its progress
 * events go to the spool (events.ndjson and events.idx, not fsynced:
 * nothing depends on them after a crash) and out of memory, where
 * admission no longer counts them; svc_job_events reads them back. A
 * spool that takes no write loses them (followers then see the outcome
 * alone). Only this worker appends to or frees them, so they are read
 * outside the lock. */
static void events_to_spool(svc_job *j)
{
    const char *spool = svc__S.cfg.spool;
    const char *data;
    const size_t *ends;
    size_t len;
    int n, ok;

    svc__lock();
    data = j->events.data;
    len = j->events.len;
    ends = j->event_end;
    n = j->nevents;
    svc__unlock();
    if (n == 0)
        return;
    ok = srv_spool_write(spool, j->id, "events.ndjson", data, len, 0) == 0 &&
         srv_spool_write(spool, j->id, "events.idx", ends,
                         (size_t)n * sizeof *ends, 0) == 0;
    if (!ok)
        srv_logf(SRV_LOG_WARN, "job %s: its %d progress events could not be "
                 "written to the spool (%s); late followers get its outcome "
                 "alone", j->id, n, strerror(errno));
    svc__lock();
    api_buf_free(&j->events);
    api_buf_init(&j->events, SVC_EVENTS_MAX);
    free(j->event_end);
    j->event_end = NULL;
    j->event_cap = 0;
    if (ok) {
        size_t add = len + (size_t)n * sizeof *ends;
        j->events_disk = len;
        j->disk_bytes += add;
        if (j->in_table)
            svc__S.disk_bytes += add;
    } else {
        j->nevents = 0;
    }
    svc__unlock();
}

/* The metrics document of a finished job: api's, the CLI's too
 * (api_metrics_json), with the daemon's own facts. */
static char *metrics_doc(const svc_job *j, const api_metrics *mt,
                         const api_params *prm, const mcf_flow_stats *st,
                         api_format in_fmt, api_format out_fmt, double qerr,
                         size_t in_bytes, size_t out_bytes, double t_queue,
                         double t_decode, double t_flow, double t_encode,
                         double t_metrics)
{
    api_metrics_run run;
    cJSON *o;
    char *s;

    api_metrics_run_init(&run);
    run.job = j->id;
    run.input_name = j->rec.filename[0] ? j->rec.filename : NULL;
    run.output_name = j->result_name;
    run.target_name = j->rec.has_target ? "target" : NULL;
    run.input_format = in_fmt;
    run.output_format = out_fmt;
    run.input_bytes = in_bytes;
    run.output_bytes = out_bytes;
    run.quantization_max_error = qerr;
    run.queue_s = t_queue;
    run.decode_s = t_decode;
    run.flow_s = t_flow;
    run.encode_s = t_encode;
    run.metrics_s = t_metrics;
    run.total_s = t_decode + t_flow + t_encode + t_metrics;
    o = api_metrics_json(mt, prm, st, &run);
    s = o ? cJSON_PrintUnformatted(o) : NULL;
    cJSON_Delete(o);
    return s;
}

/* The error of a job stopped by its cancel flag after `steps` steps
 * (-1: while its input was decoded); 1 when it must run again after a
 * restart. */
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
        svc_error_set(prob, SVC_EDRAINING, NULL, "the daemon shut down "
                      "while job %s ran; it runs again after the restart",
                      j->id);
    else if (reason == SVC_CANCEL_TIMEOUT)
        svc_error_set(prob, SVC_ETIMEOUT, "ELIMIT", "the job ran longer than "
                      "--job-timeout %g s and was stopped %s",
                      cfg->job_timeout, when);
    else if (reason == SVC_CANCEL_CLIENT)
        svc_error_set(prob, SVC_ECANCELED, NULL, "canceled %s: the client "
                      "closed its connection before the answer", when);
    else
        svc_error_set(prob, SVC_ECANCELED, NULL, "canceled by request %s",
                      when);
    prob->cancel = (svc_cancel_reason)reason;
    return reason == SVC_CANCEL_SHUTDOWN;
}

/* After decoding: the estimate from the real counts (svc_admit.c); over
 * --max-job-memory an ELIMIT, else the reservation grows (waiting for
 * memory). 0 when the job may go on, else prob is set and -1 (it failed)
 * or 1 (canceled by the shutdown: it runs again after the restart). */
static int memory_regrow(svc_job *j, int nv, int nf, size_t input_len,
                         size_t target_len, const api_params *p,
                         int keep_fields, svc_error *prob)
{
    /* fields=true: the mesh kept from before the flow (48 bytes a vertex
     * with its faces), five double fields (40) and the document (68, up
     * to twice that while its buffer grows). */
    double est = svc_admit_estimate_counts(nv, nf, input_len, target_len, p,
                                           &svc__S.cfg.lim) +
                 (keep_fields ? 256.0 * nv : 0);
    if (svc_admit_refuse(&svc__S.cfg, est, prob))
        return -1;
    if (svc_admit_grow(&svc__S.cfg, &j->mem_held, est, &j->cancel) != 0)
        return canceled_error(j, -1, prob) ? 1 : -1;
    return 0;
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
    /* its progress runs again from step 1; the events it wrote to the
     * spool are written again at its end (uncounted till then) */
    if (j->events_disk) {
        size_t sub = j->events_disk + (size_t)j->nevents * sizeof(size_t);
        j->disk_bytes -= sub;
        if (j->in_table)
            svc__S.disk_bytes -= sub;
        j->events_disk = 0;
    }
    api_buf_free(&j->events);
    api_buf_init(&j->events, SVC_EVENTS_MAX);
    j->nevents = 0;
    svc_error_set(&j->err, SVC_ESTORAGE, "EIO", "job %s %s, but the spool "
                  "could not record it (%s); it runs again in %g s", j->id,
                  svc_job_status_name(final), strerror(e), delay);
    srv_logf(SRV_LOG_ERROR, "spool: %s", j->err.detail);
}

void svc__run_job(svc_job *j)
{
    const svc_config *cfg = &svc__S.cfg;
    api_params prm;
    int have_prm = 0;
    mcf_mesh *m = NULL, *tgt = NULL, *before = NULL;
    api_attrs *attrs = NULL;   /* the input's texcoords, colours, normals */
    api_format fmt = API_FMT_UNKNOWN, tfmt;
    mcf_error err = {MCF_OK, ""};
    mcf_status rc;
    mcf_flow_stats st;
    api_metrics mt;
    api_buf out, fields;
    api_encode_opts eo;
    svc_error prob;
    int failed = 1, requeue = 0, nv = 0, nf = 0, tries = 0, written = 0,
        e = 0, keep_fields = 0;
    char *input = NULL, *target = NULL, *metrics = NULL;
    size_t input_len = 0, target_len = 0;
    svc_job_status final;
    char *state = NULL;
    double t0 = mcf_now(), t_decode = 0, t_flow = 0, t_encode = 0, t_queue,
           t_metrics = 0, t_after, qerr = NAN;
    run_ctx ctx;

    memset(&st, 0, sizeof st);
    api_metrics_init(&mt);
    memset(&prob, 0, sizeof prob);
    api_buf_init(&out, SVC_RESULT_MAX);
    api_buf_init(&fields, 0);
    svc__lock();
    input = j->input;
    input_len = j->input_len;
    target = j->target;
    target_len = j->target_len;
    j->input = j->target = NULL;
    t_queue = j->started - j->created;
    svc__unlock();
    svc__write_state(j, 0);

    if (!input && read_retry(j, "input", &input, &input_len, &tries) != 0) {
        svc_error_set(&prob, SVC_ESTORAGE, "EIO", "cannot read the input of "
                      "job %s from the spool (%d tries): %s", j->id, tries + 1,
                      strerror(errno));
        goto stopped_or_done;
    }
    if (j->rec.has_target && !target &&
        read_retry(j, "target", &target, &target_len, &tries) != 0) {
        svc_error_set(&prob, SVC_ESTORAGE, "EIO", "cannot read the target of "
                      "job %s from the spool (%d tries): %s", j->id, tries + 1,
                      strerror(errno));
        goto stopped_or_done;
    }
    if ((rc = svc_record_params(&j->rec, &cfg->lim, &prm, &err)) != MCF_OK) {
        svc_error_from_mcf(&prob, rc, SVC_STAGE_PARAMS, NULL, &err);
        goto done;
    }
    if (svc_record_fields(&j->rec, &keep_fields, &prob) != 0)
        goto done;
    have_prm = 1;
    /* sandbox.c: Draco decodes in a child process under limits. */
    while ((rc = svc_decode_upload(input, input_len, cfg, &j->cancel, "mesh",
                                   &m, &attrs, &fmt, &prob)) == MCF_ENOMEM &&
           retry(j, &tries, ENOMEM, "decoding", 0))
        ;
    if (rc != MCF_OK)
        goto decode_failed;
    free(input);
    input = NULL;
    nv = mcf_mesh_nvertices(m);
    nf = mcf_mesh_nfaces(m);
    /* svc_admit.c: estimated again from the decoded counts (polygons
     * split, STL welded); a larger estimate is refused or waits. */
    if ((requeue = memory_regrow(j, nv, nf, input_len, target_len, &prm,
                                 keep_fields, &prob)) != 0) {
        requeue = requeue > 0;
        goto done;
    }
    if ((rc = api_params_finish(&prm, nv, &cfg->lim, &err)) != MCF_OK) {
        /* A budget exceeded here (steps x vertices) depends on the mesh:
         * 422. What the parameters alone exceed was refused at submit. */
        svc_error_from_mcf(&prob, rc, rc == MCF_ELIMIT ? SVC_STAGE_RUN
                                                     : SVC_STAGE_PARAMS,
                         NULL, &err);
        goto done;
    }
    /* a request without a scheme runs the default the mesh's size
     * chose (api_default_scheme): the job says which */
    svc__lock();
    snprintf(j->scheme, sizeof j->scheme, "%s", mcf_scheme_get(prm.flow.scheme)->name);
    svc__unlock();
    if (target) {
        if ((rc = svc_decode_upload(target, target_len, cfg, &j->cancel,
                                    "target", &tgt, NULL, &tfmt, &prob)) != MCF_OK)
            goto decode_failed;
        if (mcf_mesh_nvertices(tgt) != nv || mcf_mesh_nfaces(tgt) != nf) {
            mcf_error_set(&err, MCF_EINVAL, "target: %d vertices and %d "
                          "faces, the mesh has %d and %d; the target must "
                          "share the mesh's connectivity",
                          mcf_mesh_nvertices(tgt), mcf_mesh_nfaces(tgt), nv, nf);
            svc_error_from_mcf(&prob, MCF_EINVAL, SVC_STAGE_RUN, NULL, &err);
            goto done;
        }
    }
    t_decode = mcf_now() - t0;
    t_metrics = mcf_now();
    if ((rc = api_metrics_before(&mt, m, tgt, &err)) != MCF_OK) {
        svc_error_from_mcf(&prob, rc, SVC_STAGE_RUN, "metrics", &err);
        goto done;
    }
    t_metrics = mcf_now() - t_metrics;
    /* fields=true: the mesh as the flow receives it, for the per-vertex
     * fields (api_fields_encode) written beside the result. */
    if (keep_fields && !(before = mcf_mesh_dup(m, &err))) {
        svc_error_from_mcf(&prob, err.status, SVC_STAGE_RUN, "fields", &err);
        goto done;
    }

    memset(&ctx, 0, sizeof ctx);
    ctx.job = j;
    ctx.st = &st;
    ctx.deadline = cfg->job_timeout > 0 ? srv_mono() + cfg->job_timeout : 0;
    prm.flow.progress = on_progress;
    prm.flow.progress_ctx = &ctx;
    prm.flow.cancel = &j->cancel;
    /* The step log: the metrics' flow.log (as the CLI's) and the volume of
     * each streamed step. */
    prm.flow.log_steps = 1;

    svc__lock();
    j->ready = 1;
    snprintf(j->in_format, sizeof j->in_format, "%s", api_format_name(fmt));
    svc__notify(j, SVC_NOTIFY_STATE);
    svc__unlock();

    t_flow = mcf_now();
    rc = mcf_flow_run(m, &prm.flow, &st, &err);
    t_flow = mcf_now() - t_flow;
    if (rc == MCF_ECANCELED) {
        requeue = canceled_error(j, st.steps, &prob);
        goto done;
    }
    if (rc != MCF_OK) {
        svc_error_from_mcf(&prob, rc, SVC_STAGE_RUN, "flow", &err);
        goto done;
    }

    t_encode = mcf_now();
    if (prm.encode.format == API_FMT_UNKNOWN)
        prm.encode.format = fmt; /* the metrics' params say what was written */
    eo = prm.encode;
    eo.attrs = attrs;
    rc = eo.format == API_FMT_DRACO ? api_draco_encode(m, &eo, &out, &qerr, &err)
                                    : api_mesh_encode(m, &eo, &out, &err);
    if (rc != MCF_OK) {
        svc_error_from_mcf(&prob, rc, SVC_STAGE_RUN, "encode", &err);
        goto done;
    }
    t_encode = mcf_now() - t_encode;
    t_after = mcf_now();
    if ((rc = api_metrics_after(&mt, m, tgt, &err)) != MCF_OK) {
        svc_error_from_mcf(&prob, rc, SVC_STAGE_RUN, "metrics", &err);
        goto done;
    }
    t_metrics += mcf_now() - t_after;
    if (before && (rc = api_fields_encode(before, m, &fields, &err)) != MCF_OK) {
        svc_error_from_mcf(&prob, rc, SVC_STAGE_RUN, NULL, &err);
        goto done;
    }
    svc__lock();
    snprintf(j->out_format, sizeof j->out_format, "%s",
             api_format_name(eo.format));
    snprintf(j->result_name, sizeof j->result_name, "result%s",
             api_format_ext(eo.format));
    svc__unlock();
    metrics = metrics_doc(j, &mt, &prm, &st, fmt, eo.format, qerr, input_len,
                          out.len, t_queue, t_decode, t_flow, t_encode,
                          t_metrics);
    if (!metrics) {
        svc_error_set(&prob, SVC_ENOMEM, NULL, "out of memory writing metrics");
        goto done;
    }
    while (srv_spool_write(cfg->spool, j->id, j->result_name, out.data,
                           out.len, 1) != 0 ||
           srv_spool_write(cfg->spool, j->id, "metrics.json", metrics,
                           strlen(metrics), 1) != 0 ||
           (before && srv_spool_write(cfg->spool, j->id, SVC_FIELDS_FILE,
                                      fields.data, fields.len, 1) != 0))
        if (!retry(j, &tries, errno, "writing its result", 0)) {
            svc_error_set(&prob, SVC_ESTORAGE, "EIO", "cannot write the "
                          "result of job %s to the spool (%d tries): %s",
                          j->id, tries + 1, strerror(errno));
            goto stopped_or_done;
        }
    failed = 0;
    goto done;

stopped_or_done:
    /* A retry given up because the job was stopped: canceled, or put
     * back for the restart, as a stop during the flow. */
    if (j->cancel)
        requeue = canceled_error(j, -1, &prob);
    goto done;

decode_failed:
    /* svc_decode_upload filled prob, except for a cancel. */
    if (rc == MCF_ECANCELED)
        requeue = canceled_error(j, -1, &prob);
done:
    if (!requeue)
        events_to_spool(j);
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
        j->result_len = failed ? 0 : out.len;
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
            /* its metrics stay on disk only (svc_read.c reads them) */
            size_t add = j->result_len + strlen(metrics) + fields.len;
            if (j->keep_result) {
                size_t len;
                j->result = api_buf_detach(&out, &len);
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
        svc__log_job(j, nv, nf, mcf_now() - t0);
    }
    svc__lock();
    svc__notify(j, SVC_NOTIFY_STATE);
    svc__unlock();
    if (have_prm)
        api_params_free(&prm);
    mcf_flow_stats_free(&st);
    mcf_mesh_free(m);
    mcf_mesh_free(tgt);
    mcf_mesh_free(before);
    api_attrs_free(attrs);
    api_buf_free(&out);
    api_buf_free(&fields);
    free(input);
    free(target);
    free(metrics);
}

