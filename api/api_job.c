/* SPDX-License-Identifier: MIT */
/*
 * api_job.c - one smoothing job, bytes to bytes and a metrics document
 * (api.h, "jobs"): the pipeline `mcf smooth` and the daemon's workers
 * share. Each step is timed into the document's timings; a failure names
 * its stage (parameters, decoding, or the run) and its part, and leaves
 * the message unprefixed for the door.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

#include "api_internal.h"

void api_job_request_init(api_job_request *rq)
{
    memset(rq, 0, sizeof *rq);
    rq->queue_s = rq->read_s = NAN;
}

void api_job_result_init(api_job_result *r)
{
    memset(r, 0, sizeof *r);
    api_buf_init(&r->output, 0);
    api_buf_init(&r->fields, 0);
    r->quantization_max_error = NAN;
}

void api_job_result_free(api_job_result *r)
{
    api_buf_free(&r->output);
    api_buf_free(&r->fields);
    cJSON_Delete(r->metrics);
    mcf_flow_stats_free(&r->stats);
    api_job_result_init(r);
}

/* What one run holds besides its result. */
typedef struct {
    api_job_request *rq;
    const api_job_hooks *h;
    api_job_result *res;
    mcf_mesh *m, *target, *before;
    api_attrs *attrs;
    api_metrics mt;
    api_metrics_run run;       /* the document's door facts and timings */
} job;

/* A failure: its stage, part and status (err already holds the message). */
static mcf_status failed(job *jb, api_job_stage stage, const char *part,
                         mcf_status s)
{
    jb->res->stage = stage;
    jb->res->part = part;
    jb->res->err.status = s;
    return s;
}

/* The hooks' cancel flag set (a signal, the daemon's stop): the job stops
 * between its stages too, not only in the flow's. */
static int canceled(const job *jb)
{
    return jb->h && jb->h->cancel && atomic_load_explicit(jb->h->cancel, memory_order_acquire);
}

static mcf_status stop(job *jb, const char *part, const char *before)
{
    mcf_error_set(&jb->res->err, MCF_ECANCELED, "canceled before %s", before);
    return failed(jb, API_JOB_RUN, part, MCF_ECANCELED);
}

static double elapsed(double t0)
{
    return mcf_now() - t0;
}

static mcf_status decode_part(job *jb, const char *part, const void *buf,
                              size_t len, const api_limits *lim,
                              mcf_mesh **out, api_attrs **attrs,
                              api_format *fmt)
{
    const api_job_hooks *h = jb->h;
    api_job_stage stage = API_JOB_DECODE;
    mcf_status rc;

    if (h && h->decode)
        rc = h->decode(h->ctx, part, buf, len, lim, out, attrs, fmt, &stage,
                       &jb->res->err);
    else
        rc = api_mesh_decode_attrs(buf, len, lim, out, attrs, fmt,
                                   &jb->res->err);
    return rc == MCF_OK ? MCF_OK : failed(jb, stage, part, rc);
}

/* The target shares the mesh's connectivity (the metrics compare them
 * vertex by vertex). */
static mcf_status check_target(job *jb)
{
    const mcf_mesh *m = jb->m, *t = jb->target;
    int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m);

    if (mcf_mesh_nvertices(t) == nv && mcf_mesh_nfaces(t) == nf &&
        memcmp(mcf_mesh_faces(t), mcf_mesh_faces(m),
               3 * sizeof(int32_t) * (size_t)nf) == 0)
        return MCF_OK;
    mcf_error_set(&jb->res->err, MCF_EINVAL, "not the same connectivity as "
                  "the mesh (%d/%d vertices, %d/%d faces): the target must "
                  "share the mesh's", mcf_mesh_nvertices(t), nv,
                  mcf_mesh_nfaces(t), nf);
    return failed(jb, API_JOB_RUN, "target", MCF_EINVAL);
}

/* Decodes the input and the target, finishes the parameters for the
 * mesh. */
static mcf_status prepare(job *jb, api_params *p, const api_limits *lim)
{
    api_job_request *rq = jb->rq;
    const api_job_hooks *h = jb->h;
    api_job_result *res = jb->res;
    api_format tfmt;
    mcf_status rc;
    double t0 = mcf_now();

    if ((rc = decode_part(jb, "mesh", rq->input, rq->input_len, lim, &jb->m,
                          &jb->attrs, &res->input_format)) != MCF_OK)
        return rc;
    if (rq->free_bytes) {
        free(rq->input);
        rq->input = NULL;
    }
    res->nv = mcf_mesh_nvertices(jb->m);
    res->nf = mcf_mesh_nfaces(jb->m);
    jb->run.decode_s = elapsed(t0);
    if (h && h->decoded &&
        (rc = h->decoded(h->ctx, res->nv, res->nf, p, &res->err)) != MCF_OK)
        return failed(jb, API_JOB_RUN, "mesh", rc);
    /* A budget the parameters exceed only with this mesh (steps x
     * vertices) is the run's; any other refusal the parameters'. */
    if ((rc = api_params_finish(p, res->nv, lim, &res->err)) != MCF_OK)
        return failed(jb, rc == MCF_ELIMIT ? API_JOB_RUN : API_JOB_PARAMS,
                      "params", rc);
    if (p->encode.format == API_FMT_UNKNOWN)
        p->encode.format = res->input_format;
    p->encode.attrs = jb->attrs;
    if (rq->target) {
        t0 = mcf_now();
        if ((rc = decode_part(jb, "target", rq->target, rq->target_len, lim,
                              &jb->target, NULL, &tfmt)) != MCF_OK)
            return rc;
        jb->run.decode_s += elapsed(t0);
        if (rq->free_bytes) {
            free(rq->target);
            rq->target = NULL;
        }
        if ((rc = check_target(jb)) != MCF_OK)
            return rc;
    }
    return MCF_OK;
}

/* core's progress -> the door's, with the step's volume from the log. */
typedef struct {
    job *jb;
    const mcf_flow_stats *st;
} progress_ctx;

static int on_progress(void *ctx, int step, double t, double dt, double energy)
{
    progress_ctx *pc = ctx;
    const mcf_flow_stats *st = pc->st;
    const api_job_hooks *h = pc->jb->h;
    api_job_step s;

    s.step = step;
    s.t = t;
    s.dt = dt;
    s.energy = energy;
    /* the core fills log entry step - 1 before this call */
    s.volume = st->log && step >= 1 && step <= st->nlog
                   ? st->log[step - 1].volume : NAN;
    s.t_target = st->t_target;
    s.threads_cpu_s = st->threads_cpu_s;
    return h->progress(h->ctx, &s);
}

static void on_work(void *ctx, const char *phase, double done)
{
    const api_job_hooks *h = ((progress_ctx *)ctx)->jb->h;
    h->work(h->ctx, phase, done);
}

static mcf_status flow(job *jb, api_params *p)
{
    const api_job_hooks *h = jb->h;
    api_job_result *res = jb->res;
    progress_ctx pc = {jb, &res->stats};
    mcf_status rc;
    double t0;

    if (h && h->progress) {
        p->flow.progress = on_progress;
        p->flow.progress_ctx = &pc;
    }
    if (h && h->work) {
        p->flow.work = on_work;
        p->flow.progress_ctx = &pc;
    }
    if (h)
        p->flow.cancel = h->cancel;
    /* the step log: the document's flow.log, each step's volume */
    p->flow.log_steps = jb->rq->metrics && !jb->rq->light;
    p->flow.threads = jb->rq->threads;
    if (h && h->threads) {
        int n = h->threads(h->ctx, res->nv);
        if (n >= 1)
            p->flow.threads = n;
    }
    t0 = mcf_now();
    rc = mcf_flow_run(jb->m, &p->flow, &res->stats, &res->err);
    res->flow_s = jb->run.flow_s = elapsed(t0);
    p->flow.progress = NULL;
    p->flow.work = NULL;
    p->flow.progress_ctx = NULL;
    return rc == MCF_OK ? MCF_OK : failed(jb, API_JOB_RUN, "flow", rc);
}

/* Encodes (Draco measures its quantization error) and stores the output. */
static mcf_status output(job *jb, const api_params *p)
{
    const api_job_request *rq = jb->rq;
    const api_job_hooks *h = jb->h;
    api_job_result *res = jb->res;
    api_format f = p->encode.format;
    mcf_status rc;
    double t0 = mcf_now();

    res->output_format = f;
    res->output_name = rq->output_name;
    if (!rq->output_name && rq->output_stem) {
        snprintf(res->name_buf, sizeof res->name_buf, "%s%s",
                 rq->output_stem, api_format_ext(f));
        res->output_name = res->name_buf;
    }
    api_buf_free(&res->output);
    api_buf_init(&res->output, rq->max_output);
    rc = f == API_FMT_DRACO
             ? api_draco_encode(jb->m, &p->encode, &res->output,
                                &res->quantization_max_error, &res->err)
             : api_mesh_encode(jb->m, &p->encode, &res->output, &res->err);
    if (rc != MCF_OK)
        return failed(jb, API_JOB_RUN, "encode", rc);
    jb->run.encode_s = elapsed(t0);
    jb->run.output_bytes = res->output.len;
    jb->run.quantization_max_error = res->quantization_max_error;
    res->not_kept_n = api_attrs_not_kept(jb->attrs, f, res->not_kept, sizeof res->not_kept);
    jb->run.not_kept = res->not_kept_n ? res->not_kept : NULL;
    if (h && h->store) {
        if (canceled(jb))
            return stop(jb, "output", "the output was stored");
        t0 = mcf_now();
        if ((rc = h->store(h->ctx, &res->output, res->output_name,
                           &res->err)) != MCF_OK)
            return failed(jb, API_JOB_RUN, "output", rc);
        jb->run.write_s = elapsed(t0);
    }
    return MCF_OK;
}

static double peak_rss_bytes(void)
{
    struct rusage ru;
    if (getrusage(RUSAGE_SELF, &ru) != 0)
        return NAN;
    return (double)ru.ru_maxrss * 1024.0; /* Linux: KiB */
}

/* The metrics document of the run (api_metrics_json) with the door's
 * facts and the timings. */
static mcf_status document(job *jb, const api_params *p, double t_start)
{
    const api_job_request *rq = jb->rq;
    api_job_result *res = jb->res;
    api_metrics_run *run = &jb->run;

    run->job = rq->job;
    run->input_name = rq->input_name;
    run->output_name = res->withheld ? NULL : res->output_name;
    run->target_name = jb->target ? rq->target_name : NULL;
    run->input_format = res->input_format;
    run->output_format = p->encode.format;
    run->input_bytes = rq->input_len;
    run->queue_s = rq->queue_s;
    run->read_s = rq->read_s;
    run->total_s = (isfinite(rq->read_s) ? rq->read_s : 0) + elapsed(t_start);
    if (rq->process_rss)
        run->peak_rss_bytes = peak_rss_bytes();
    run->nv = res->nv;
    run->nf = res->nf;
    res->metrics = api_metrics_json(&jb->mt, p, &res->stats, run);
    if (res->metrics)
        return MCF_OK;
    mcf_error_set(&res->err, MCF_ENOMEM, "out of memory");
    return failed(jb, API_JOB_RUN, "metrics", MCF_ENOMEM);
}

/* The measures before and after the flow (timed as metrics_s). */
static mcf_status measure(job *jb, int after)
{
    double t0 = mcf_now();
    mcf_status rc;

    if (!jb->rq->metrics || jb->rq->light)
        return MCF_OK;
    rc = (after ? api_metrics_after : api_metrics_before)(
        &jb->mt, jb->m, jb->target, &jb->res->err);
    /* NaN (not measured) until the first measure */
    jb->run.metrics_s = (after && !isnan(jb->run.metrics_s) ? jb->run.metrics_s : 0.0)
                        + elapsed(t0);
    return rc == MCF_OK ? MCF_OK : failed(jb, API_JOB_RUN, "metrics", rc);
}

static mcf_status run_steps(job *jb, api_params *p, const api_limits *lim,
                            double t_start)
{
    const api_job_hooks *h = jb->h;
    api_job_result *res = jb->res;
    mcf_status rc;

    if ((rc = prepare(jb, p, lim)) != MCF_OK)
        return rc;
    if (canceled(jb))
        return stop(jb, "mesh", "the flow");
    if ((rc = measure(jb, 0)) != MCF_OK)
        return rc;
    /* fields: the mesh as the flow receives it */
    if (jb->rq->fields && !(jb->before = mcf_mesh_dup(jb->m, &res->err)))
        return failed(jb, API_JOB_RUN, "fields", res->err.status);
    if (h && h->ready)
        h->ready(h->ctx, p, res->input_format);
    if ((rc = flow(jb, p)) != MCF_OK)
        return rc;
    res->withheld = h && h->flowed && h->flowed(h->ctx, &res->stats);
    if (!res->withheld && (rc = output(jb, p)) != MCF_OK)
        return rc;
    if ((rc = measure(jb, 1)) != MCF_OK)
        return rc;
    if (jb->before &&
        (rc = api_fields_encode(jb->before, jb->m, &res->fields, &res->err)) != MCF_OK)
        return failed(jb, API_JOB_RUN, "fields", rc);
    return jb->rq->metrics ? document(jb, p, t_start) : MCF_OK;
}

mcf_status api_job_run(api_job_request *rq, api_params *p,
                       const api_job_hooks *h, api_job_result *res)
{
    api_limits def;
    job jb;
    mcf_status rc;
    double t_start = mcf_now();

    api_job_result_free(res);
    if (!rq || !p) {
        mcf_error_set(&res->err, MCF_EINVAL, "job: no request or parameters");
        res->stage = API_JOB_DECODE;
        res->part = "mesh";
        return MCF_EINVAL;
    }
    if (!rq->input || rq->input_len == 0) {
        mcf_error_set(&res->err, MCF_EDECODE, "the input is empty (0 bytes): no mesh to read");
        res->stage = API_JOB_DECODE;
        res->part = "mesh";
        return MCF_EDECODE;
    }
    if (!rq->lim)
        api_limits_default(&def);
    memset(&jb, 0, sizeof jb);
    jb.rq = rq;
    jb.h = h;
    jb.res = res;
    api_metrics_init(&jb.mt);
    api_metrics_run_init(&jb.run);
    rc = run_steps(&jb, p, rq->lim ? rq->lim : &def, t_start);
    p->encode.attrs = NULL; /* freed below */
    mcf_mesh_free(jb.m);
    mcf_mesh_free(jb.target);
    mcf_mesh_free(jb.before);
    api_attrs_free(jb.attrs);
    if (rc == MCF_OK)
        res->stage = API_JOB_OK;
    return rc;
}
