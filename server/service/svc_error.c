/* SPDX-License-Identifier: MIT */
/*
 * svc_error.c - the job service's errors (service.h): the columns of the
 * one table of client-visible errors (SVC_PROBLEMS), code names, and
 * svc_error values from a message or from a failure of the core or the
 * codecs, whose row follows from the mcf status and the stage it came
 * from. Each door maps a row's columns to its transport.
 */
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "svc_internal.h"

static const char *const code_names[] = {
#define X(name, text) #name,
    SVC_CODES(X)
#undef X
};

static const struct {
    const char *name;
    svc_code code;
    mcf_status mcf;
    unsigned http;
    svc_grpc_status grpc;
    const char *text;
} rows[] = {
#define X(id, name, code, mcf, http, grpc, text)                               \
    {name, SVC_##code, MCF_##mcf, http, SVC_GRPC_##grpc, text},
    SVC_PROBLEMS(X)
#undef X
};

#define NROWS (sizeof rows / sizeof rows[0])

const char *svc_code_name(svc_code c)
{
    return (unsigned)c < sizeof code_names / sizeof *code_names
               ? code_names[c] : "";
}

static unsigned row(svc_problem p)
{
    return (unsigned)p < NROWS ? (unsigned)p : (unsigned)SVC_P_INTERNAL;
}

const char *svc_problem_name(svc_problem p) { return rows[row(p)].name; }
svc_code svc_problem_code(svc_problem p) { return rows[row(p)].code; }
mcf_status svc_problem_mcf(svc_problem p) { return rows[row(p)].mcf; }
unsigned svc_problem_http(svc_problem p) { return rows[row(p)].http; }
svc_grpc_status svc_problem_grpc(svc_problem p) { return rows[row(p)].grpc; }
const char *svc_problem_text(svc_problem p) { return rows[row(p)].text; }

svc_code svc_error_code(const svc_error *e)
{
    return svc_problem_code(e->problem);
}

static void error_vset(svc_error *e, svc_problem p, const char *fmt,
                       va_list ap)
{
    svc_code code = svc_problem_code(p);

    memset(e, 0, sizeof *e);
    e->problem = p;
    vsnprintf(e->detail, sizeof e->detail, fmt, ap);
    if (code == SVC_EBUSY || code == SVC_EQUOTA || code == SVC_ENOMEM)
        e->retry_after = 1;
    else if (code == SVC_EDRAINING)
        e->retry_after = 5;
}

void svc_error_set(svc_error *e, svc_problem p, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    error_vset(e, p, fmt, ap);
    va_end(ap);
}

/* The service code of a failure of the core or the codecs: out of
 * memory, canceled, an I/O error, or the stage's. */
static svc_code code_of_mcf(mcf_status s, api_job_stage stage)
{
    if (s == MCF_OK)
        return SVC_OK;
    if (s == MCF_ENOMEM)
        return SVC_ENOMEM;
    if (s == MCF_ECANCELED)
        return SVC_ECANCELED;
    if (s == MCF_EIO)
        return SVC_EINTERNAL;
    return stage == API_JOB_PARAMS ? SVC_EPARAMS
           : stage == API_JOB_DECODE ? SVC_EINPUT : SVC_EMESH;
}

/* The row of (code, s); a pair without one (no path produces it) is
 * INTERNAL, its detail naming the status. */
static svc_problem find_row(svc_code code, mcf_status s)
{
    unsigned i;
    for (i = 0; i < NROWS; i++)
        if (rows[i].code == code && rows[i].mcf == s)
            return (svc_problem)i;
    if (code == SVC_ECANCELED)
        return SVC_P_CANCELED;
    return SVC_P_INTERNAL;
}

void svc_error_from_mcf(svc_error *e, mcf_status s, api_job_stage stage,
                        const char *prefix, const mcf_error *err)
{
    const char *msg = (err && err->msg[0]) ? err->msg : mcf_strerror(s);
    svc_problem p = find_row(code_of_mcf(s, stage), s);

    svc_error_set(e, p, "%s%s%s%s%s", p == SVC_P_INTERNAL ? mcf_status_name(s) : "",
                  p == SVC_P_INTERNAL ? ": " : "", prefix ? prefix : "",
                  prefix ? ": " : "", msg);
}

/* The row of a service code and a name (a persisted error): 0 and *p, or
 * -1 when no row has both. */
int svc__problem_find(svc_code code, const char *name, svc_problem *p)
{
    unsigned i;
    for (i = 0; i < NROWS; i++)
        if (rows[i].code == code && strcmp(rows[i].name, name) == 0) {
            *p = (svc_problem)i;
            return 0;
        }
    return -1;
}
