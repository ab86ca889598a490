/*
 * svc_error.c - the job service's errors (service.h): code names, and
 * svc_error values from a message or from a failure of the core or the
 * codecs, whose code follows from the mcf status and the stage it came
 * from. Each door maps the code to its transport (service.h's table).
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

const char *svc_code_name(svc_code c)
{
    return (unsigned)c < sizeof code_names / sizeof *code_names
               ? code_names[c] : "";
}

static void error_vset(svc_error *e, svc_code code, const char *name,
                       const char *fmt, va_list ap)
{
    memset(e, 0, sizeof *e);
    e->code = code;
    snprintf(e->name, sizeof e->name, "%s", name ? name : svc_code_name(code));
    vsnprintf(e->detail, sizeof e->detail, fmt, ap);
    if (code == SVC_EBUSY || code == SVC_EQUOTA || code == SVC_ENOMEM)
        e->retry_after = 1;
    else if (code == SVC_EDRAINING)
        e->retry_after = 5;
}

void svc_error_set(svc_error *e, svc_code code, const char *name,
                   const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    error_vset(e, code, name, fmt, ap);
    va_end(ap);
}

/* The service code of a failure of the core or the codecs. */
static svc_code code_of_mcf(mcf_status s, svc_stage stage)
{
    switch (s) {
    case MCF_OK:
        return SVC_OK;
    case MCF_ENOMEM:
        return SVC_ENOMEM;
    case MCF_ECANCELED:
        return SVC_ECANCELED;
    case MCF_EIO:
        return SVC_EINTERNAL;
    default:
        break;
    }
    return stage == SVC_STAGE_PARAMS ? SVC_EPARAMS
           : stage == SVC_STAGE_DECODE ? SVC_EINPUT : SVC_EMESH;
}

void svc_error_from_mcf(svc_error *e, mcf_status s, svc_stage stage,
                        const char *prefix, const mcf_error *err)
{
    const char *msg = (err && err->msg[0]) ? err->msg : mcf_strerror(s);

    svc_error_set(e, code_of_mcf(s, stage), mcf_status_name(s), "%s%s%s",
                  prefix ? prefix : "", prefix ? ": " : "", msg);
    e->mcf = s;
    e->stage = stage;
}

