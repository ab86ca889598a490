/* SPDX-License-Identifier: MIT */
/*
 * mcfpy.c - the in-process door for Python (build/libmcfpy.so, loaded by
 * clients/python/mcf with ctypes): one job from the input's bytes to the
 * result's, through api_job_run as `mcf smooth` runs it, so the same
 * bytes and parameters give the same mesh, to rounding (this library
 * links Debian's shared CHOLMOD, mcf its serial copy: Makefile, pylib).
 *
 * Like cli/, a client of api and core: the parameters are set one by one
 * through api_params_set (the table that validates mcf's options and the
 * daemon's query), the output format comes from `format` or the output
 * name's extension, and a failure is reported with the core's status
 * name (mcf_status_name: the code the daemon answers with) and the door's
 * one-line message. Unlike mcf, the decode is not bounded by rlimits (they
 * would bound the caller's whole process): untrusted Draco files belong
 * in the daemon's sandbox.
 *
 * The caller's hooks: step (every accepted step), work (the run's share
 * of work, mcf_work_fn) and a cancel flag loaded before every step. They
 * run on the calling thread; ctypes releases the GIL around mcfpy_run and
 * takes it back for each hook.
 *
 * Everything a run returns lives in one opaque mcfpy_result (freed with
 * mcfpy_free); ctypes reads it through the accessors below.
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "api.h"

/* The exported entry points (the rest of the library is hidden by
 * pyext/mcfpy.map). */
typedef void (*mcfpy_step_fn)(void *ctx, int step, double t, double dt, double energy,
                              double volume);
typedef void (*mcfpy_work_fn)(void *ctx, const char *phase, double done);

typedef struct {
    mcf_status status;
    char code[16];              /* mcf_status_name of status */
    char message[MCF_ERRMSG_SIZE + 64];
    char *output;               /* the encoded mesh (malloc'ed) */
    size_t output_len;
    char *metrics;              /* the metrics document, JSON (malloc'ed) */
    unsigned warnings;          /* MCF_WARN_* bits */
    int nv, nf;
} mcfpy_result;

typedef struct {
    mcfpy_step_fn step;
    mcfpy_work_fn work;
    void *ctx;
} hooks_ctx;

const char *mcfpy_version(void);
mcfpy_result *mcfpy_run(const void *in, size_t in_len, const char *out_name,
                        const char *const *keys, const char *const *values, int n,
                        int want_metrics, mcfpy_step_fn step, mcfpy_work_fn work, void *ctx,
                        const mcf_cancel_flag *cancel);
int mcfpy_status(const mcfpy_result *r);
const char *mcfpy_code(const mcfpy_result *r);
const char *mcfpy_message(const mcfpy_result *r);
const char *mcfpy_output(const mcfpy_result *r, size_t *len);
const char *mcfpy_metrics(const mcfpy_result *r);
unsigned mcfpy_warnings(const mcfpy_result *r);
const char *mcfpy_warning_name(unsigned bit);
int mcfpy_counts(const mcfpy_result *r, int *nf);
void mcfpy_free(mcfpy_result *r);

const char *mcfpy_version(void)
{
    return API_VERSION;
}

static int on_step(void *ctx, const api_job_step *s)
{
    const hooks_ctx *h = ctx;
    if (h->step)
        h->step(h->ctx, s->step, s->t, s->dt, s->energy, s->volume);
    return 0;
}

static void on_work(void *ctx, const char *phase, double done)
{
    const hooks_ctx *h = ctx;
    if (h->work)
        h->work(h->ctx, phase, done);
}

static void failed(mcfpy_result *r, mcf_status st, const char *part, const char *msg)
{
    r->status = st;
    snprintf(r->code, sizeof r->code, "%s", mcf_status_name(st));
    snprintf(r->message, sizeof r->message, "%s%s%s", part ? part : "", part ? ": " : "", msg);
}

mcfpy_result *mcfpy_run(const void *in, size_t in_len, const char *out_name,
                        const char *const *keys, const char *const *values, int n,
                        int want_metrics, mcfpy_step_fn step, mcfpy_work_fn work, void *ctx,
                        const mcf_cancel_flag *cancel)
{
    mcfpy_result *r = calloc(1, sizeof *r);
    api_limits lim;
    api_params p;
    api_job_request rq;
    api_job_hooks h;
    api_job_result res;
    hooks_ctx hc = {step, work, ctx};
    mcf_error err = {MCF_OK, ""};

    if (!r)
        return NULL;
    snprintf(r->code, sizeof r->code, "OK");
    api_limits_default(&lim);
    api_params_init(&p);
    for (int i = 0; i < n; i++)
        if (api_params_set(&p, keys[i], values[i], &lim, &err) != MCF_OK) {
            failed(r, err.status, NULL, err.msg);
            api_params_free(&p);
            return r;
        }
    /* the output format: `format`, else the output name's (as mcf's OUT) */
    if (p.encode.format == API_FMT_UNKNOWN &&
        (p.encode.format = api_format_from_name(out_name ? out_name : "")) == API_FMT_UNKNOWN) {
        snprintf(err.msg, sizeof err.msg,
                 "cannot tell the output format from '%s' (use format=obj|draco|ply|stl|off|glb|gltf)",
                 out_name ? out_name : "");
        failed(r, MCF_EINVAL, NULL, err.msg);
        api_params_free(&p);
        return r;
    }
    api_job_request_init(&rq);
    rq.input = (char *)(uintptr_t)in;
    rq.input_len = in_len;
    rq.lim = &lim;
    rq.metrics = want_metrics;
    rq.output_name = out_name;
    rq.process_rss = 0;
    memset(&h, 0, sizeof h);
    h.ctx = &hc;
    h.progress = on_step;
    h.work = on_work;
    h.cancel = cancel;
    api_job_result_init(&res);
    if (api_job_run(&rq, &p, &h, &res) != MCF_OK) {
        failed(r, res.err.status, res.part, res.err.msg);
    } else {
        r->output = malloc(res.output.len ? res.output.len : 1);
        r->metrics = res.metrics ? api_json_print(res.metrics, 1) : NULL;
        if (!r->output || (res.metrics && !r->metrics)) {
            failed(r, MCF_ENOMEM, "output", "out of memory");
        } else {
            if (res.output.len)
                memcpy(r->output, res.output.data, res.output.len);
            r->output_len = res.output.len;
        }
    }
    r->warnings = res.stats.warnings;
    r->nv = res.nv;
    r->nf = res.nf;
    api_job_result_free(&res);
    api_params_free(&p);
    return r;
}

int mcfpy_status(const mcfpy_result *r)
{
    return (int)r->status;
}

const char *mcfpy_code(const mcfpy_result *r)
{
    return r->code;
}

const char *mcfpy_message(const mcfpy_result *r)
{
    return r->message;
}

const char *mcfpy_output(const mcfpy_result *r, size_t *len)
{
    *len = r->output_len;
    return r->output;
}

const char *mcfpy_metrics(const mcfpy_result *r)
{
    return r->metrics;
}

unsigned mcfpy_warnings(const mcfpy_result *r)
{
    return r->warnings;
}

const char *mcfpy_warning_name(unsigned bit)
{
    return mcf_warning_name(bit);
}

int mcfpy_counts(const mcfpy_result *r, int *nf)
{
    *nf = r->nf;
    return r->nv;
}

void mcfpy_free(mcfpy_result *r)
{
    if (!r)
        return;
    free(r->output);
    free(r->metrics);
    free(r);
}
