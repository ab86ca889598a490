/* SPDX-License-Identifier: MIT */
/*
 * runner.c - one job, start to end, on a worker thread: reads the input
 * back from the store, runs the job (api_job_run: decode, check, smooth
 * with progress events, encode, the metrics document), writes result,
 * metrics and fields to the store, and returns the outcome; the worker
 * records and publishes it (svc__finish). A store that ends a run in one
 * step (its finish op: Redis) gets them in the outcome instead, written
 * with the state by svc__finish.
 *
 * What is the daemon's comes in through api_job_run's hooks: the Draco
 * sandbox (sandbox.c), memory admission once the counts are known
 * (svc_admit.c), progress events and the job timeout (svc__progress), the
 * result written to the store. This file takes no lock: what it changes
 * of the job goes through svc_job.c.
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "svc_internal.h"
#include "svc_admit.h"
#include "sandbox.h"

typedef struct {
    svc_job *job;
    svc_t *svc;
    int tries;                /* retries spent (svc__retry) */
    size_t input_len, target_len;
    svc_error prob;           /* a hook's own error (memory, the store) */
    int has_prob;
    int defer;                /* result, metrics, fields: svc__finish's */
    const mcf_flow_stats *stats;  /* the run's (api_job_result.stats): the
                                  CPU of the threads its flow started */
} run_ctx;

/* A blob read back, tried again on a transient error. */
static int read_retry(run_ctx *c, const char *name, char **data, size_t *len)
{
    svc_store *st = c->svc->store;
    char what[64];

    snprintf(what, sizeof what, "reading its %s", name);
    while (st->ops->get(st, c->job->id, name, data, len) != 0)
        if (!svc__retry(c->job, &c->tries, errno, what, 0))
            return -1;
    return 0;
}

/* A blob written durably, tried again on a transient error. */
static int write_retry(run_ctx *c, const char *name, const void *data,
                       size_t len)
{
    svc_store *st = c->svc->store;

    while (st->ops->put(st, c->job->id, name, data, len, 1) != 0)
        if (!svc__retry(c->job, &c->tries, errno, "writing its result", 0))
            return -1;
    return 0;
}

/* ------------------------------------------------------------------ hooks */

/* sandbox.c: Draco decodes in a child process under limits; a decode out
 * of memory is tried again. */
static mcf_status hook_decode(void *ctx, const char *part, const void *buf,
                              size_t len, const api_limits *lim,
                              mcf_mesh **out, api_attrs **attrs,
                              api_format *fmt, api_job_stage *stage,
                              mcf_error *err)
{
    run_ctx *c = ctx;
    mcf_status rc;

    (void)lim;
    while ((rc = sandbox_decode_upload(buf, len, &c->svc->cfg, &c->job->cancel,
                                       out, attrs, fmt, stage, err)) == MCF_ENOMEM &&
           strcmp(part, "mesh") == 0 &&
           svc__retry(c->job, &c->tries, ENOMEM, "decoding", 0))
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
    svc_t *s = c->svc;
    /* fields: the mesh kept from before the flow (48 bytes a vertex with
     * its faces), five double fields (40) and the document (68, up to
     * twice that while its buffer grows). */
    double est = svc_admit_estimate_counts(nv, nf, c->input_len, c->target_len,
                                           p, &s->cfg.lim) +
                 (c->job->keep_fields ? 256.0 * nv : 0);

    if (svc_admit_refuse(&s->cfg, est, &c->prob)) {
        c->has_prob = 1;
        return mcf_error_set(err, MCF_ELIMIT, "%s", c->prob.detail);
    }
    if (svc_admit_grow(s, &c->job->mem_held, est, &c->job->cancel) != 0)
        return mcf_error_set(err, MCF_ECANCELED, "canceled");
    return MCF_OK;
}

/* The flow's threads: the job's cores (workers.c's rule). */
static int hook_threads(void *ctx, int nv)
{
    return svc_admit_cores(((run_ctx *)ctx)->job, nv);
}

static void hook_ready(void *ctx, const api_params *p, api_format in_fmt)
{
    run_ctx *c = ctx;
    svc__ready(c->job, mcf_scheme_get(p->flow.scheme)->name,
               api_format_name(in_fmt));
}

static int hook_progress(void *ctx, const api_job_step *st)
{
    return svc__progress(((run_ctx *)ctx)->job, st);
}

/* The core's milestones: the job's phase and share of work for its
 * followers, and its limits checked between the steps of a filter that
 * reports no step until its end; the flow stops at its next step or pass
 * (the flag it loads). */
static void hook_work(void *ctx, const char *phase, double done)
{
    run_ctx *c = ctx;

    svc__work(c->job, phase, done, c->stats ? c->stats->threads_cpu_s : 0);
}

/* The result in the store (durable, retried). */
static mcf_status hook_store(void *ctx, const api_buf *out, const char *name,
                             mcf_error *err)
{
    run_ctx *c = ctx;

    if (c->defer ||
        write_retry(c, name, out->data ? out->data : "", out->len) == 0)
        return MCF_OK;
    if (errno == ENOSPC || errno == EDQUOT) {
        /* the client's to retry once there is room (a synchronous one
         * hears it after SVC_RETRY_SYNC_TRIES: 503 with Retry-After) */
        svc_error_set(&c->prob, SVC_P_SPOOL_FULL, "the spool has no room "
                      "for the result of job %s (%d tries): %s", c->job->id,
                      c->tries + 1, strerror(errno));
        c->prob.retry_after = 5;
    } else {
        svc_error_set(&c->prob, SVC_P_STORAGE, "cannot write the result of "
                      "job %s to the spool (%d tries): %s", c->job->id,
                      c->tries + 1, strerror(errno));
    }
    c->has_prob = 1;
    return mcf_error_set(err, MCF_EIO, "%s", c->prob.detail);
}

/* ---------------------------------------------------------------- the run */

/* The service error of a failed api_job_run: a cancel, a hook's own, or
 * the core's or a codec's with its stage and part. 1 when the job must
 * run again after a restart. */
static int job_error(run_ctx *c, const api_job_result *res, svc_error *e)
{
    const char *part = res->part ? res->part : "";
    int prefixed = strcmp(part, "params") != 0 && strcmp(part, "fields") != 0;

    if (res->err.status == MCF_ECANCELED && svc__canceled(c->job))
        return svc__canceled_error(c->job, strcmp(part, "mesh") != 0
                                               ? res->stats.steps : -1, e);
    if (c->has_prob) {
        *e = c->prob;
        return svc__canceled(c->job) ? svc__canceled_error(c->job, -1, e) : 0;
    }
    svc_error_from_mcf(e, res->err.status, res->stage, prefixed ? part : NULL,
                       &res->err);
    return 0;
}

/* A retry given up because the job was stopped is its cancel's error. */
static int store_failed(run_ctx *c, const char *what, svc_error *e)
{
    svc_error_set(e, SVC_P_STORAGE, "cannot %s of job %s %s the spool (%d "
                  "tries): %s", what, c->job->id,
                  strncmp(what, "read", 4) == 0 ? "from" : "to", c->tries + 1,
                  strerror(errno));
    return svc__canceled(c->job) && svc__canceled_error(c->job, -1, e);
}

/* The job's request for api_job_run, its hooks bound to c. */
static void request_of(run_ctx *c, api_job_request *rq, api_job_hooks *h)
{
    svc_job *j = c->job;

    rq->lim = &c->svc->cfg.lim;
    rq->metrics = 1;
    rq->light = !j->measures;  /* nobody asked for the measures */
    rq->threads = 1;           /* hook_threads: the job's cores */
    rq->fields = j->keep_fields;
    rq->max_output = SVC_RESULT_MAX;
    rq->job = j->id;
    rq->input_name = j->filename[0] ? j->filename : NULL;
    rq->target_name = "target";
    rq->output_stem = "result";
    rq->free_bytes = 1;
    rq->queue_s = j->started - j->created; /* this worker's (svc__start) */
    memset(h, 0, sizeof *h);
    h->ctx = c;
    h->decode = hook_decode;
    h->decoded = hook_decoded;
    h->threads = hook_threads;
    h->ready = hook_ready;
    h->progress = hook_progress;
    h->work = hook_work;
    h->store = hook_store;
    h->cancel = &j->cancel;
}

/* Reads the input back, runs the job, writes metrics and fields. 0, or -1
 * with o->err (and o->status QUEUED when the job must run again after a
 * restart). */
static int run(run_ctx *c, api_job_result *res, svc_outcome *o)
{
    svc_job *j = c->job;
    api_job_request rq;
    api_job_hooks h;
    api_params prm;
    char *metrics = NULL;
    double t0 = mcf_now();
    int rc = -1;

    api_job_request_init(&rq);
    if (read_retry(c, "input", &rq.input, &c->input_len) != 0 ||
        (j->has_target && read_retry(c, "target", &rq.target, &c->target_len) != 0)) {
        if (store_failed(c, rq.input ? "read the target" : "read the input", &o->err))
            o->status = SVC_JOB_QUEUED;
        goto out;
    }
    rq.read_s = mcf_now() - t0;
    rq.input_len = c->input_len;
    rq.target_len = c->target_len;
    request_of(c, &rq, &h);
    c->stats = &res->stats;
    /* a copy: a job that runs again starts from the parameters asked */
    if (api_params_copy(&prm, &j->params) != MCF_OK) {
        svc_error_set(&o->err, SVC_P_NOMEM, "out of memory for the parameters");
        goto out;
    }
    rc = api_job_run(&rq, &prm, &h, res) == MCF_OK ? 0 : -1;
    api_params_free(&prm);
    if (rc != 0) {
        if (job_error(c, res, &o->err))
            o->status = SVC_JOB_QUEUED;
        goto out;
    }
    rc = -1;
    if (!(metrics = cJSON_PrintUnformatted(res->metrics))) {
        svc_error_set(&o->err, SVC_P_NOMEM, "out of memory writing metrics");
        goto out;
    }
    o->disk_add = res->output.len + strlen(metrics) + res->fields.len;
    if (c->defer) {            /* written by svc__finish */
        o->metrics = metrics;
        metrics = NULL;
        rc = 0;
        goto out;
    }
    if (write_retry(c, "metrics.json", metrics, strlen(metrics)) != 0 ||
        (j->keep_fields &&
         write_retry(c, SVC_FIELDS_FILE, res->fields.data, res->fields.len) != 0)) {
        if (store_failed(c, "write the result", &o->err))
            o->status = SVC_JOB_QUEUED;
        goto out;
    }
    /* its metrics stay in the store only (svc_read.c reads them) */
    rc = 0;
out:
    free(rq.input);
    free(rq.target);
    free(metrics);
    return rc;
}

void svc__run(svc_job *j, svc_outcome *o)
{
    run_ctx c;
    api_job_result res;
    double t0 = mcf_now();
    size_t len;

    memset(&c, 0, sizeof c);
    memset(o, 0, sizeof *o);
    c.job = j;
    c.svc = j->svc;
    c.defer = j->svc->store->ops->finish != NULL;
    api_job_result_init(&res);
    o->status = SVC_JOB_FAILED;
    if (run(&c, &res, o) == 0) {
        o->status = SVC_JOB_SUCCEEDED;
        o->result_len = res.output.len;
        snprintf(o->out_format, sizeof o->out_format, "%s",
                 api_format_name(res.output_format));
        snprintf(o->result_name, sizeof o->result_name, "%s", res.output_name);
        o->result = api_buf_detach(&res.output, &len);
        if (c.defer && j->keep_fields)
            o->fields = api_buf_detach(&res.fields, &o->fields_len);
    } else if (o->status == SVC_JOB_FAILED) {
        svc_cancel_reason why = svc__cancel_reason(j);
        if (why == SVC_CANCEL_USER || why == SVC_CANCEL_CLIENT)
            o->status = SVC_JOB_CANCELED;
    }
    o->nv = res.nv;
    o->nf = res.nf;
    o->run_s = mcf_now() - t0;
    api_job_result_free(&res);
}
