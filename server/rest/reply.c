/* SPDX-License-Identifier: MIT */
/*
 * reply.c - what the REST client reads: responses (queued and counted),
 * errors as RFC 9457 problem+json documents (their status and code from
 * service.h's table of problems), and the job document with its links.
 */
#include <ctype.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>

#include "rest_internal.h"

const char *rest_http_reason(unsigned status)
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

cJSON *rest_problem_json(const svc_error *e, const char *instance,
                         const char *job_id)
{
    char type[64];
    size_t i, n;
    unsigned http = svc_problem_http(e->problem);
    cJSON *o = cJSON_CreateObject();

    if (!o)
        return NULL;
    /* A stable, non-dereferenceable identifier per error code; the codes
     * are listed in /openapi.yaml (components.schemas.Problem). */
    n = (size_t)snprintf(type, sizeof type, "urn:mcfd:problem:%s",
                         svc_problem_name(e->problem));
    for (i = sizeof "urn:mcfd:problem:" - 1; i < n && i < sizeof type; i++)
        type[i] = (char)tolower((unsigned char)type[i]);
    if (!cJSON_AddStringToObject(o, "type", type) ||
        !cJSON_AddStringToObject(o, "title", rest_http_reason(http)) ||
        !cJSON_AddNumberToObject(o, "status", http) ||
        !cJSON_AddStringToObject(o, "detail", e->detail) ||
        !cJSON_AddStringToObject(o, "code", svc_problem_name(e->problem)) ||
        (instance && !cJSON_AddStringToObject(o, "instance", instance)) ||
        (job_id && !cJSON_AddStringToObject(o, "job", job_id))) {
        cJSON_Delete(o);
        return NULL;
    }
    return o;
}

/* ---------------------------------------------------------------- responses */

enum MHD_Result rest_respond(rest_request *r, struct MHD_Connection *c,
                               unsigned status, struct MHD_Response *resp)
{
    enum MHD_Result ret;

    if (!resp)
        return MHD_NO;
    r->status = status;
    srv_metrics_request(rest_route_name(r->rt), status);
    ret = MHD_queue_response(c, status, resp);
    MHD_destroy_response(resp);
    return ret;
}

enum MHD_Result rest_send_text(rest_request *r, struct MHD_Connection *c,
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
    return rest_respond(r, c, status, resp);
}

/* A response holding o printed (takes o), with a trailing newline when
 * asked (friendlier in a terminal) and the given Content-Type; NULL when
 * out of memory. */
struct MHD_Response *rest_json_response(cJSON *o, const char *ctype, int newline)
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

enum MHD_Result rest_send_json(rest_request *r, struct MHD_Connection *c,
                                 unsigned status, cJSON *j)
{
    struct MHD_Response *resp = rest_json_response(j, "application/json", 1);

    return resp ? rest_respond(r, c, status, resp) : MHD_NO;
}

enum MHD_Result rest_send_problem(rest_request *r, struct MHD_Connection *c,
                                  const svc_error *e, const char *job)
{
    unsigned http = svc_problem_http(e->problem);
    struct MHD_Response *resp =
        rest_json_response(rest_problem_json(e, r->path, job), "application/problem+json", 0);
    char retry[24];

    if (!resp)
        return MHD_NO;
    /* the error's delay, the one gRPC sends too; any other 503 says 1 s */
    if (e->retry_after > 0 || http == 503) {
        snprintf(retry, sizeof retry, "%.0f",
                 e->retry_after > 0 ? ceil(e->retry_after) : 1.0);
        MHD_add_response_header(resp, MHD_HTTP_HEADER_RETRY_AFTER, retry);
    }
    if (http == 401)
        MHD_add_response_header(resp, MHD_HTTP_HEADER_WWW_AUTHENTICATE,
                                "Bearer realm=\"mcfd\"");
    if (http == 405)
        MHD_add_response_header(resp, MHD_HTTP_HEADER_ALLOW,
                                r->rt == RT_SMOOTH ? "POST"
                                : r->rt == RT_JOBS ? "POST"
                                : r->rt == RT_JOB  ? "GET, HEAD, DELETE"
                                                   : "GET, HEAD");
    if (job)
        MHD_add_response_header(resp, "X-Job-Id", job);
    return rest_respond(r, c, http, resp);
}

void rest_send_problem_raw(rest_request *r, struct MHD_Connection *c,
                           const svc_error *e)
{
    const union MHD_ConnectionInfo *ci =
        MHD_get_connection_info(c, MHD_CONNECTION_INFO_CONNECTION_FD);
    cJSON *o = rest_problem_json(e, r->path, NULL);
    char *body = o ? cJSON_PrintUnformatted(o) : NULL, head[256], retry[40] = "";
    unsigned http = svc_problem_http(e->problem);
    int n;

    cJSON_Delete(o);
    r->status = http;
    srv_metrics_request(rest_route_name(r->rt), http);
    if (!ci || !body) {
        free(body);
        return;
    }
    if (http == 503)
        snprintf(retry, sizeof retry, "Retry-After: %.0f\r\n",
                 e->retry_after > 0 ? ceil(e->retry_after) : 1.0);
    n = snprintf(head, sizeof head, "HTTP/1.1 %u %s\r\nContent-Type: "
                 "application/problem+json\r\nContent-Length: %zu\r\n"
                 "%sConnection: close\r\n\r\n", http, rest_http_reason(http),
                 strlen(body), retry);
    /* a few hundred bytes into an idle socket's send buffer: whole, or
     * (a client that reads nothing) lost with the connection */
    if (send(ci->connect_fd, head, (size_t)n, MSG_NOSIGNAL | MSG_DONTWAIT) ==
        n)
        (void)send(ci->connect_fd, body, strlen(body),
                   MSG_NOSIGNAL | MSG_DONTWAIT);
    /* nothing more to say: the client reads the answer, then the end,
     * while the daemon goes on reading what it sends */
    (void)shutdown(ci->connect_fd, SHUT_WR);
    free(body);
}

enum MHD_Result rest_send_problemf(rest_request *r, struct MHD_Connection *c,
                                   svc_problem p, const char *fmt, ...)
{
    svc_error e;
    va_list ap;

    svc_error_set(&e, p, "%s", "");
    va_start(ap, fmt);
    vsnprintf(e.detail, sizeof e.detail, fmt, ap);
    va_end(ap);
    return rest_send_problem(r, c, &e, NULL);
}


struct MHD_Response *rest_empty_response(void)
{
    return MHD_create_response_from_buffer(0, NULL, MHD_RESPMEM_PERSISTENT);
}

/* ------------------------------------------------------------ job document */

static void add_time(cJSON *o, const char *key, double t)
{
    char buf[40];
    if (t > 0) {
        srv_time_rfc3339(t, buf, sizeof buf);
        cJSON_AddStringToObject(o, key, buf);
    } else {
        cJSON_AddNullToObject(o, key);
    }
}

static void add_num(cJSON *o, const char *key, double v)
{
    if (isfinite(v))
        cJSON_AddNumberToObject(o, key, v);
    else
        cJSON_AddNullToObject(o, key);
}

/* The progress object: before the first step there is nothing to
 * report. */
static void add_progress(cJSON *o, const svc_snap *s)
{
    cJSON *p = cJSON_AddObjectToObject(o, "progress");

    if (!p)
        return;
    cJSON_AddNumberToObject(p, "step", s->step);
    if (s->steps_planned > 0)
        cJSON_AddNumberToObject(p, "steps", s->steps_planned);
    else
        cJSON_AddNullToObject(p, "steps");
    add_num(p, "t", s->step > 0 ? s->t : NAN);
    add_num(p, "dt", s->step > 0 ? s->dt : NAN);
    add_num(p, "energy", s->step > 0 ? s->energy : NAN);
    add_num(p, "volume", s->step > 0 ? s->volume : NAN);
    cJSON_AddNumberToObject(p, "fraction", s->fraction);
    if (s->phase[0])
        cJSON_AddStringToObject(p, "phase", s->phase);
    else
        cJSON_AddNullToObject(p, "phase");
}

static void add_links(cJSON *o, const char *id)
{
    static const char *const rel[] = {"self", "", "result", "/result",
                                      "metrics", "/metrics", "events", "/events"};
    char link[96];
    cJSON *l = cJSON_AddObjectToObject(o, "links");
    size_t i;

    for (i = 0; l && i < sizeof rel / sizeof *rel; i += 2) {
        snprintf(link, sizeof link, "/v1/jobs/%s%s", id, rel[i + 1]);
        cJSON_AddStringToObject(l, rel[i], link);
    }
}

cJSON *rest_job_json(const svc_job *j, svc_snap *snap)
{
    char link[96];
    svc_snap s;
    cJSON *o = cJSON_CreateObject(), *x;

    if (!o || svc_job_document(j, &s) != 0) {
        cJSON_Delete(o);
        return NULL;
    }
    cJSON_AddStringToObject(o, "id", s.id);
    cJSON_AddStringToObject(o, "status", svc_job_status_name(s.status));
    add_time(o, "created", s.created);
    add_time(o, "started", s.started);
    add_time(o, "finished", s.finished);
    add_progress(o, &s);
    if (s.cancel_requested)
        cJSON_AddBoolToObject(o, "cancel_requested", 1);
    if (s.params && (x = cJSON_Parse(s.params)) != NULL)
        cJSON_AddItemToObject(o, "params", x);
    if (s.in_format[0])
        cJSON_AddStringToObject(o, "input_format", s.in_format);
    if (s.metrics && (x = cJSON_Parse(s.metrics)) != NULL)
        cJSON_AddItemToObject(o, "metrics", x);
    if (s.status == SVC_JOB_FAILED || s.status == SVC_JOB_CANCELED) {
        snprintf(link, sizeof link, "/v1/jobs/%s", s.id);
        if ((x = rest_problem_json(&s.error, link, s.id)) != NULL)
            cJSON_AddItemToObject(o, "error", x);
    }
    add_links(o, s.id);
    svc_snap_free(&s);
    if (snap)
        *snap = s;
    return o;
}
