/*
 * reply.c - errors as the client sees them: the mcf_status -> HTTP status
 * map and RFC 9457 problem+json documents.
 *
 * The map is a switch over every code of the MCF_ERRORS table with no
 * default branch, so -Wswitch flags a code appended to core/mcf.h that
 * this file has not mapped yet. Where a code came from (parameters,
 * decoding, the flow) decides between 400 and 422: a parameter the client
 * spelled wrong or a body that does not parse is the request's fault
 * (400); a well-formed mesh the flow cannot smooth is 422.
 */
#include <ctype.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "srv.h"

unsigned srv_http_status(mcf_status s, srv_stage stage)
{
    switch (s) {
    case MCF_OK:
        return 200;
    case MCF_ENOMEM:
        return 503;            /* transient: retry when memory frees up */
    case MCF_EINVAL:
        /* A parameter (named in the detail) is wrong; from the flow itself
         * it means a combination only the mesh reveals. */
        return stage == SRV_STAGE_RUN ? 422 : 400;
    case MCF_EDECODE:
        /* Bytes that do not parse as the detected format (or a params
         * document that is not JSON): malformed request content. */
        return 400;
    case MCF_EFORMAT:
        return 415;
    case MCF_ELIMIT:
        /* Only input over a size limit is "Content Too Large". A step or
         * work budget is the parameters' fault when they alone exceed it
         * (400), else a property of this mesh with these parameters (422);
         * the detail names the parameter or limit. */
        return stage == SRV_STAGE_DECODE ? 413
               : stage == SRV_STAGE_PARAMS ? 400 : 422;
    case MCF_EMESH:
    case MCF_ENOTPOSDEF:
    case MCF_ENUMERIC:
    case MCF_ENOCONV:
        return 422;
    case MCF_ECANCELED:
        return 409;            /* canceled through DELETE /v1/jobs/ID */
    case MCF_EIO:
        return 500;
    }
    return 500;
}

const char *srv_http_reason(unsigned status)
{
    switch (status) {
    case 200: return "OK";
    case 202: return "Accepted";
    case 204: return "No Content";
    case 400: return "Bad Request";
    case 401: return "Unauthorized";
    case 404: return "Not Found";
    case 405: return "Method Not Allowed";
    case 409: return "Conflict";
    case 413: return "Content Too Large";
    case 414: return "URI Too Long";
    case 415: return "Unsupported Media Type";
    case 422: return "Unprocessable Content";
    case 500: return "Internal Server Error";
    case 503: return "Service Unavailable";
    default: return "Error";
    }
}

void srv_problem_set(srv_problem *p, unsigned http, const char *code,
                     const char *fmt, ...)
{
    va_list ap;

    p->http = http;
    snprintf(p->code, sizeof p->code, "%s", code);
    va_start(ap, fmt);
    vsnprintf(p->detail, sizeof p->detail, fmt, ap);
    va_end(ap);
}

void srv_problem_from(srv_problem *p, mcf_status s, srv_stage stage,
                      const char *prefix, const mcf_error *err)
{
    const char *msg = (err && err->msg[0]) ? err->msg : mcf_strerror(s);

    srv_problem_set(p, srv_http_status(s, stage), mcf_status_name(s), "%s%s%s",
                    prefix ? prefix : "", prefix ? ": " : "", msg);
}

cJSON *srv_problem_json(const srv_problem *p, const char *instance,
                        const char *job_id)
{
    char type[64];
    size_t i, n;
    cJSON *o = cJSON_CreateObject();

    if (!o)
        return NULL;
    /* A stable, non-dereferenceable identifier per error code; the codes
     * are listed in /openapi.yaml (components.schemas.Problem). */
    n = (size_t)snprintf(type, sizeof type, "urn:mcfd:problem:%s", p->code);
    for (i = sizeof "urn:mcfd:problem:" - 1; i < n && i < sizeof type; i++)
        type[i] = (char)tolower((unsigned char)type[i]);
    if (!cJSON_AddStringToObject(o, "type", type) ||
        !cJSON_AddStringToObject(o, "title", srv_http_reason(p->http)) ||
        !cJSON_AddNumberToObject(o, "status", p->http) ||
        !cJSON_AddStringToObject(o, "detail", p->detail) ||
        !cJSON_AddStringToObject(o, "code", p->code) ||
        (instance && !cJSON_AddStringToObject(o, "instance", instance)) ||
        (job_id && !cJSON_AddStringToObject(o, "job", job_id))) {
        cJSON_Delete(o);
        return NULL;
    }
    return o;
}
