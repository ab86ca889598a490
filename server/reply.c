/*
 * reply.c - what the REST client reads: responses (queued and counted),
 * errors as RFC 9457 problem+json documents with the service error ->
 * HTTP status map (service.h's table), and the job document with its
 * links.
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

#include "http.h"

unsigned srv_http_status(mcf_status s, svc_stage stage)
{
    switch (s) {
    case MCF_OK:
        return 200;
    case MCF_ENOMEM:
        return 503;            /* transient: retry when memory frees up */
    case MCF_EINVAL:
        /* A parameter (named in the detail) is wrong; from the flow itself
         * it means a combination only the mesh reveals. */
        return stage == SVC_STAGE_RUN ? 422 : 400;
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
        return stage == SVC_STAGE_DECODE ? 413
               : stage == SVC_STAGE_PARAMS ? 400 : 422;
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
    case 501: return "Not Implemented";
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

void srv_problem_from_svc(srv_problem *p, const svc_error *e)
{
    unsigned http = 500;

    switch (e->code) {
    case SVC_OK:
        http = 200;
        break;
    case SVC_EPARAMS:
    case SVC_EINPUT:
    case SVC_EMESH:
        http = srv_http_status(e->mcf, e->stage);
        break;
    case SVC_ENOMEM:
    case SVC_EBUSY:
    case SVC_EQUOTA:
    case SVC_EDRAINING:
        http = 503;
        break;
    case SVC_ENOTFOUND:
        http = 404;
        break;
    case SVC_ENOTREADY:
    case SVC_ENORESULT:
    case SVC_ECANCELED:
        http = 409;
        break;
    case SVC_ETIMEOUT:
        http = 422;
        break;
    case SVC_ESTORAGE:
    case SVC_EINTERNAL:
        http = 500;
        break;
    }
    srv_problem_set(p, http, e->name, "%s", e->detail);
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

/* ---------------------------------------------------------------- responses */

enum MHD_Result srv_respond(srv_request *r, struct MHD_Connection *c,
                               unsigned status, struct MHD_Response *resp)
{
    enum MHD_Result ret;

    if (!resp)
        return MHD_NO;
    r->status = status;
    srv_metrics_request(srv_route_name(r->rt), status);
    ret = MHD_queue_response(c, status, resp);
    MHD_destroy_response(resp);
    return ret;
}

enum MHD_Result srv_send_text(srv_request *r, struct MHD_Connection *c,
                                 unsigned status, const char *ctype,
                                 char *text, size_t len)
{
    struct MHD_Response *resp;

    if (!text)
        return MHD_NO;
    resp = MHD_create_response_from_buffer(len, text, MHD_RESPMEM_MUST_FREE);
    if (!resp) {
        free(text);
        return MHD_NO;
    }
    MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_TYPE, ctype);
    return srv_respond(r, c, status, resp);
}

/* A response holding o printed (takes o), with a trailing newline when
 * asked (friendlier in a terminal) and the given Content-Type; NULL when
 * out of memory. */
struct MHD_Response *srv_json_response(cJSON *o, const char *ctype, int newline)
{
    char *s = o ? cJSON_Print(o) : NULL;
    struct MHD_Response *resp;
    size_t n;

    cJSON_Delete(o);
    if (!s)
        return NULL;
    n = strlen(s);
    if (newline) {
        char *t = realloc(s, n + 2);
        if (!t) {
            free(s);
            return NULL;
        }
        s = t;
        s[n++] = '\n';
        s[n] = '\0';
    }
    resp = MHD_create_response_from_buffer(n, s, MHD_RESPMEM_MUST_FREE);
    if (!resp) {
        free(s);
        return NULL;
    }
    MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_TYPE, ctype);
    return resp;
}

enum MHD_Result srv_send_json(srv_request *r, struct MHD_Connection *c,
                                 unsigned status, cJSON *j)
{
    struct MHD_Response *resp = srv_json_response(j, "application/json", 1);

    return resp ? srv_respond(r, c, status, resp) : MHD_NO;
}

enum MHD_Result srv_send_problem(srv_request *r, struct MHD_Connection *c,
                                    const srv_problem *p, const char *job)
{
    struct MHD_Response *resp =
        srv_json_response(srv_problem_json(p, r->path, job), "application/problem+json", 0);

    if (!resp)
        return MHD_NO;
    if (p->http == 503)
        MHD_add_response_header(resp, MHD_HTTP_HEADER_RETRY_AFTER,
                                strcmp(p->code, "EDRAINING") == 0 ? "5" : "1");
    if (p->http == 401)
        MHD_add_response_header(resp, MHD_HTTP_HEADER_WWW_AUTHENTICATE,
                                "Bearer realm=\"mcfd\"");
    if (p->http == 405)
        MHD_add_response_header(resp, MHD_HTTP_HEADER_ALLOW,
                                r->rt == RT_SMOOTH ? "POST"
                                : r->rt == RT_JOBS ? "POST"
                                : r->rt == RT_JOB  ? "GET, HEAD, DELETE"
                                                   : "GET, HEAD");
    if (job)
        MHD_add_response_header(resp, "X-Job-Id", job);
    return srv_respond(r, c, p->http, resp);
}

enum MHD_Result srv_send_problemf(srv_request *r, struct MHD_Connection *c,
                                  unsigned http, const char *code,
                                  const char *fmt, ...)
{
    srv_problem p;
    va_list ap;

    p.http = http;
    snprintf(p.code, sizeof p.code, "%s", code);
    va_start(ap, fmt);
    vsnprintf(p.detail, sizeof p.detail, fmt, ap);
    va_end(ap);
    return srv_send_problem(r, c, &p, NULL);
}


struct MHD_Response *srv_empty_response(void)
{
    return MHD_create_response_from_buffer(0, NULL, MHD_RESPMEM_PERSISTENT);
}

/* ------------------------------------------------------------ job document */

cJSON *srv_job_json(const svc_job *j, svc_snap *snap)
{
    char link[96];
    const char *id = svc_job_id(j);
    svc_snap s;
    cJSON *o = svc_job_json(j, &s), *l;

    if (!o)
        return NULL;
    if (snap)
        *snap = s;
    if (s.status == SVC_JOB_FAILED || s.status == SVC_JOB_CANCELED) {
        srv_problem p;
        cJSON *e;
        srv_problem_from_svc(&p, &s.error);
        snprintf(link, sizeof link, "/v1/jobs/%s", id);
        if ((e = srv_problem_json(&p, link, id)) != NULL)
            cJSON_AddItemToObject(o, "error", e);
    }
    l = cJSON_AddObjectToObject(o, "links");
    if (l) {
        snprintf(link, sizeof link, "/v1/jobs/%s", id);
        cJSON_AddStringToObject(l, "self", link);
        snprintf(link, sizeof link, "/v1/jobs/%s/result", id);
        cJSON_AddStringToObject(l, "result", link);
        snprintf(link, sizeof link, "/v1/jobs/%s/metrics", id);
        cJSON_AddStringToObject(l, "metrics", link);
        snprintf(link, sizeof link, "/v1/jobs/%s/events", id);
        cJSON_AddStringToObject(l, "events", link);
    }
    return o;
}
