/* SPDX-License-Identifier: MIT */
/*
 * http.c - the REST door's entry points on libmicrohttpd: the URI, request,
 * completion and connection callbacks, connection bookkeeping (the header
 * deadline against slowloris clients), routing, authentication, and the
 * routes that need no job (health, readiness, metrics, the API
 * description, the schemes). Uploads are upload.c's, job routes
 * jobroutes.c's, waiting waiter.c's, streams stream.c's, answers reply.c's.
 *
 * A request object (rest_request) is made by the URI log callback, which
 * sees the raw target with its query string, hangs on con_cls, and is
 * freed only in the completion callback, which also writes the request's
 * log line.
 *
 * What is refused is refused as early as possible: a missing token (401),
 * an unknown route (404), an unsupported Content-Type (415), a
 * Content-Length over the limit (413) and a full queue or a draining
 * daemon (503 + Retry-After) are answered on the first call, from the
 * headers alone, so a client using Expect: 100-continue never sends the
 * body. So is a request whose framing is in doubt (framing_refused), and
 * one on a connection past --max-connections-per-ip (503 + Retry-After);
 * both close their connection.
 */
#define _XOPEN_SOURCE 700 /* tsearch */
#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <search.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include "http.h"

/* The longest query string read (the request line and headers together
 * are bounded by MHD's per-connection pool, SRV_CONN_MEMORY in main.c). */
#define SRV_MAX_QUERY 8192

/* An upload still coming after --header-timeout must have averaged this
 * many bytes a second since its head (slow-body clients hold a slot). */
#define SRV_MIN_BODY_RATE 4096.0

/* A response owning a copy of the bytes. */
static struct MHD_Response *from_copy(const void *data, size_t len)
{
    char *p = malloc(len ? len : 1);
    if (!p)
        return NULL;
    memcpy(p, data, len);
    return MHD_create_response_from_buffer(len, p, MHD_RESPMEM_MUST_FREE);
}

/* ------------------------------------------------------------ routes */

static int parse_route(rest_request *r, const char *url)
{
    const char *rest;

    if (strcmp(url, "/healthz") == 0)
        r->rt = RT_HEALTHZ;
    else if (strcmp(url, "/readyz") == 0)
        r->rt = RT_READYZ;
    else if (strcmp(url, "/metrics") == 0)
        r->rt = RT_METRICS;
    else if (strcmp(url, "/openapi.yaml") == 0)
        r->rt = RT_OPENAPI;
    else if (strcmp(url, "/v1/schemes") == 0)
        r->rt = RT_SCHEMES;
    else if (strcmp(url, "/smooth") == 0 || strcmp(url, "/v1/smooth") == 0)
        r->rt = RT_SMOOTH;
    else if (strcmp(url, "/v1/jobs") == 0)
        r->rt = RT_JOBS;
    else if (strncmp(url, "/v1/jobs/", 9) == 0) {
        size_t n;
        rest = url + 9;
        n = strcspn(rest, "/");
        if (n != SVC_ID_LEN)
            return -1;
        memcpy(r->id, rest, n);
        r->id[n] = '\0';
        for (n = 0; n < SVC_ID_LEN; n++)
            if (!isxdigit((unsigned char)r->id[n]) ||
                isupper((unsigned char)r->id[n]))
                return -1;
        rest += SVC_ID_LEN;
        if (*rest == '\0')
            r->rt = RT_JOB;
        else if (strcmp(rest, "/result") == 0)
            r->rt = RT_JOB_RESULT;
        else if (strcmp(rest, "/metrics") == 0)
            r->rt = RT_JOB_METRICS;
        else if (strcmp(rest, "/events") == 0)
            r->rt = RT_JOB_EVENTS;
        else if (strcmp(rest, "/fields") == 0)
            r->rt = RT_JOB_FIELDS;
        else
            return -1;
    } else if (rest_ui_find(url, &r->asset)) {
        r->rt = RT_UI;
    } else {
        r->rt = RT_OTHER;
        return -1;
    }
    return 0;
}

/* The offset in the raw target of the path's first control byte, raw or
 * encoded as libmicrohttpd decodes (%00 ended the path: /v1/jobs/ID%00x). */
static long path_control_byte(const char *uri)
{
    for (const char *p = uri; *p && *p != '?'; p++) {
        unsigned char b = (unsigned char)*p;
        if (b == '%' && isxdigit((unsigned char)p[1]) && isxdigit((unsigned char)p[2])) {
            char hex[3] = {p[1], p[2], '\0'};
            b = (unsigned char)strtoul(hex, NULL, 16);
        }
        if (b < 0x20 || b == 0x7f)
            return (long)(p - uri);
    }
    return -1;
}

/* The bearer token, checked as the gRPC door checks it (srv_bearer_ok:
 * constant time in the token's length). */
static int authorized(const rest_t *d, struct MHD_Connection *c)
{
    return srv_bearer_ok(d->cfg,
                         MHD_lookup_connection_value(c, MHD_HEADER_KIND,
                                                     MHD_HTTP_HEADER_AUTHORIZATION));
}

static int is_get(const char *method)
{
    return strcmp(method, "GET") == 0 || strcmp(method, "HEAD") == 0;
}

/* The daemon's gauges: the service's, the door's event streams, the
 * other door's. */
static srv_gauges gauges(rest_t *d)
{
    svc_gauges s = svc_get_gauges(d->svc);
    srv_gauges g;

    memset(&g, 0, sizeof g);
    g.queue_depth = s.queue_depth;
    g.queue_capacity = s.queue_capacity;
    g.workers = s.workers;
    g.workers_busy = s.workers_busy;
    g.jobs_in_memory = s.jobs_in_memory;
    g.draining = s.draining;
    g.followers = rest_waiter_followers(d);
    g.spool_bytes = s.spool_bytes;
    if (d->dm.gauges)
        d->dm.gauges(d->dm.ctx, &g);
    return g;
}

/* The checks every request meets before its route's answer: a printable
 * path, a route, a bounded query, the token (not for the probes, the
 * metrics and the page, whose API calls carry it), the method of a fixed
 * route. 0 when it goes on; else 1 and *ret, the answer sent. */
static int refused(rest_request *r, struct MHD_Connection *c, const char *url,
                   const char *method, enum MHD_Result *ret)
{
    const char *q = rest_query_of(r);
    long at;

    if ((at = path_control_byte(r->uri)) >= 0) {
        snprintf(r->path, sizeof r->path, "%.*s", (int)strcspn(r->uri, "?"), r->uri);
        *ret = rest_send_problemf(r, c, SVC_P_PARAM_INVALID, "the path has a control "
                                  "byte at byte %ld (%.3s): a path is printable", at,
                                  r->uri[at] == '%' ? r->uri + at : "raw");
    } else if (parse_route(r, url) != 0)
        *ret = rest_send_problemf(r, c, SVC_P_NOT_FOUND, "no such resource: %s", url);
    else if (q && strlen(q) > SRV_MAX_QUERY)
        *ret = rest_send_problemf(r, c, SVC_P_URI_LIMIT, "the query string has %zu bytes, "
                                  "more than %d: send the parameters as a multipart "
                                  "'params' field (JSON)", strlen(q), SRV_MAX_QUERY);
    else if (r->rt != RT_HEALTHZ && r->rt != RT_READYZ && r->rt != RT_METRICS &&
             r->rt != RT_UI && !authorized(r->door, c))
        *ret = rest_send_problemf(r, c, SVC_P_AUTH, "a valid 'Authorization: Bearer "
                                  "<token>' header is required");
    else if ((r->rt == RT_SMOOTH || r->rt == RT_JOBS) && strcmp(method, "POST") != 0)
        *ret = rest_send_problemf(r, c, SVC_P_METHOD, "%s is not allowed on %s; "
                                  "POST a mesh", method, url);
    else if ((r->rt <= RT_SCHEMES || r->rt == RT_UI) && !is_get(method))
        *ret = rest_send_problemf(r, c, SVC_P_METHOD, "%s is not allowed on %s", method, url);
    else
        return 0;
    return 1;
}

/* /healthz and /readyz. A door that no longer accepts (the gRPC door:
 * h2gate_health) makes the daemon unhealthy, so an orchestrator restarts
 * it. Draining and a spool that cannot be written make it unready (every
 * job goes through the spool). A full queue does not: it is answered per
 * request (503 + Retry-After), and an orchestrator flapping every replica
 * out of its Service under load would turn those into connection errors. */
static enum MHD_Result send_probe(rest_request *r, struct MHD_Connection *c)
{
    rest_t *d = r->door;
    char sick[300], why[1500];
    srv_gauges g;
    cJSON *o;

    if (d->dm.health && d->dm.health(d->dm.ctx, sick, sizeof sick) != 0)
        return rest_send_problemf(r, c, SVC_P_UNHEALTHY, "%s", sick);
    if (r->rt == RT_HEALTHZ) {
        o = cJSON_CreateObject();
        cJSON_AddStringToObject(o, "status", "ok");
        return rest_send_json(r, c, 200, o);
    }
    g = gauges(d);
    if (g.draining || atomic_load(&d->draining))
        return rest_send_problemf(r, c, SVC_P_DRAINING, "the daemon is shutting down");
    if (svc_ready(d->svc, why, sizeof why) != 0)
        return rest_send_problemf(r, c, SVC_P_SPOOL_UNREADY, "%s", why);
    o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "status", "ready");
    cJSON_AddNumberToObject(o, "queue_depth", g.queue_depth);
    cJSON_AddNumberToObject(o, "workers_busy", g.workers_busy);
    return rest_send_json(r, c, 200, o);
}

/* /metrics, Prometheus's text format. This request is counted before
 * rendering, so a scrape sees itself. */
static enum MHD_Result send_metrics(rest_request *r, struct MHD_Connection *c)
{
    srv_gauges g = gauges(r->door);
    struct MHD_Response *resp;
    enum MHD_Result ret;
    size_t n = 0;
    char *s;

    srv_metrics_request(rest_route_name(r->rt), 200);
    s = srv_metrics_render(&g, &n);
    r->status = 200;
    if (!s)
        return MHD_NO;
    if (!(resp = MHD_create_response_from_buffer(n, s, MHD_RESPMEM_MUST_FREE))) {
        free(s);
        return MHD_NO;
    }
    MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_TYPE,
                            "text/plain; version=0.0.4; charset=utf-8");
    ret = MHD_queue_response(c, 200, resp);
    MHD_destroy_response(resp);
    return ret;
}

/* A request's first call: its checks, then its route's answer (an
 * upload's first bytes come in the next calls). */
static enum MHD_Result first_call(rest_request *r, struct MHD_Connection *c,
                                  const char *url, const char *method)
{
    struct MHD_Response *resp;
    enum MHD_Result ret;

    snprintf(r->method, sizeof r->method, "%s", method);
    snprintf(r->path, sizeof r->path, "%s", url);
    if (refused(r, c, url, method, &ret))
        return ret;
    switch (r->rt) {
    case RT_HEALTHZ:
    case RT_READYZ:
        return send_probe(r, c);
    case RT_METRICS:
        return send_metrics(r, c);
    case RT_OPENAPI:
        if ((resp = from_copy(rest_openapi_yaml, rest_openapi_yaml_len)))
            MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_TYPE, "application/yaml");
        return rest_respond(r, c, 200, resp);
    case RT_SCHEMES:
        return rest_send_json(r, c, 200, api_json_schemes());
    case RT_UI:
        return rest_ui_send(r, c, r->asset);
    case RT_SMOOTH:
    case RT_JOBS:
        return rest_upload_begin(r, c);
    default:
        return rest_route_job(r, c, method);
    }
}

/* ----------------------------------------------------------- framing */

/* The framing headers of a request, every line of them: libmicrohttpd
 * 0.9.75 reads only the first Transfer-Encoding and the first
 * Content-Length, reads a body of an unknown coding until the client
 * closes, and frames by Transfer-Encoding when both are there. */
typedef struct {
    int te;                    /* Transfer-Encoding lines */
    int chunked;               /* "chunked" codings among them */
    char other[40];            /* the first other coding ("" when none) */
    int cl;                    /* Content-Length lines */
    int cl_differ;             /* two that differ */
    char cl_first[40];
} framing;

static enum MHD_Result framing_header(void *cls, enum MHD_ValueKind kind,
                                      const char *key, const char *value)
{
    framing *f = cls;
    const char *p = value ? value : "";

    (void)kind;
    if (strcasecmp(key, MHD_HTTP_HEADER_CONTENT_LENGTH) == 0) {
        if (f->cl++ == 0)
            snprintf(f->cl_first, sizeof f->cl_first, "%s", p);
        else if (strcmp(f->cl_first, p) != 0)
            f->cl_differ = 1;
    } else if (strcasecmp(key, MHD_HTTP_HEADER_TRANSFER_ENCODING) == 0) {
        f->te++;
        /* a comma-separated list of codings, each with optional
         * parameters after ';' (RFC 9112 7) */
        while (*p) {
            size_t n;
            p += strspn(p, " \t,");
            n = strcspn(p, ",;");
            while (n > 0 && (p[n - 1] == ' ' || p[n - 1] == '\t'))
                n--;
            if (n == 7 && strncasecmp(p, "chunked", 7) == 0)
                f->chunked++;
            else if (n > 0 && !f->other[0])
                snprintf(f->other, sizeof f->other, "%.*s", (int)n, p);
            p += strcspn(p, ",");
        }
        if (!f->chunked && !f->other[0]) /* an empty value */
            snprintf(f->other, sizeof f->other, "(empty)");
    }
    return MHD_YES;
}

/* RFC 9112 6.1 and 6.3: a request whose body cannot be framed without
 * doubt is answered from its head, and its connection closed
 * (libmicrohttpd closes after an answer queued on the first call): 501
 * for a transfer coding other than chunked (the only one MHD decodes),
 * 400 for Content-Length beside Transfer-Encoding (a proxy framing by
 * one and the daemon by the other is request smuggling), Transfer-Encoding
 * in HTTP/1.0, chunked twice, or Content-Lengths that differ. 1 and p set,
 * or 0. */
static int framing_refused(struct MHD_Connection *c, const char *version,
                           svc_error *p)
{
    framing f;

    memset(&f, 0, sizeof f);
    MHD_get_connection_values(c, MHD_HEADER_KIND, framing_header, &f);
    if (f.te && f.cl)
        svc_error_set(p, SVC_P_FRAMING, "Content-Length and "
                        "Transfer-Encoding together (RFC 9112 6.3): send one");
    else if (f.te && strcmp(version, MHD_HTTP_VERSION_1_0) == 0)
        svc_error_set(p, SVC_P_FRAMING, "Transfer-Encoding in an HTTP/1.0 "
                        "request (RFC 9112 6.1): send Content-Length");
    else if (f.other[0])
        svc_error_set(p, SVC_P_NOT_IMPLEMENTED, "Transfer-Encoding '%s' is "
                        "not supported: send the body with Content-Length or "
                        "Transfer-Encoding: chunked alone", f.other);
    else if (f.chunked > 1)
        svc_error_set(p, SVC_P_FRAMING, "Transfer-Encoding chunked %d "
                        "times (RFC 9112 7: once)", f.chunked);
    else if (f.cl_differ)
        svc_error_set(p, SVC_P_FRAMING, "two Content-Length headers that "
                        "differ");
    else
        return 0;
    return 1;
}

/* ------------------------------------------------------------ MHD entry */

/* What a connection holds between MHD's notifications: the request whose
 * completion callback is still due, so that it is released when the
 * connection closes without one (MHD skips it when a request overflows
 * its pool after the URI callback, e.g. hundreds of headers); and, for
 * the header deadline, whether it is waiting for a request's headers and
 * since when. Every connection is on the door's list (conns_mu guards
 * the list, receiving and since, and the per-address counts). */
typedef struct ip_count ip_count;
struct conn_state {
    rest_request *req;
    int fd;
    ip_count *ip;              /* its address's count, NULL: none kept */
    int over;                  /* opened past --max-connections-per-ip */
    int receiving;             /* 1: no complete request head yet; 2: the
                                  head is in, the body is coming */
    size_t body;               /* body bytes so far (receiving 2) */
    double since;              /* srv_mono() when it began waiting */
    rest_t *door;
    struct conn_state *prev, *next;
};

static void request_free(rest_request *r, int toe);

/* --max-connections-per-ip: the connections of each client address,
 * counted here rather than by libmicrohttpd, which closes a connection
 * past its limit at accept, so that its client hears a 503 with
 * Retry-After instead of a reset. A tsearch tree (the door's ips) under
 * conns_mu, one node per address with connections open. */
struct ip_count {
    unsigned char key[17];     /* address length (4, 16), then its bytes */
    int n;
};

static int ip_cmp(const void *a, const void *b)
{
    return memcmp(((const ip_count *)a)->key, ((const ip_count *)b)->key,
                  sizeof ((const ip_count *)a)->key);
}

/* conns_mu held: one more connection from sa; its node, or NULL (an
 * address of another family, or out of memory: not counted). */
static ip_count *ip_take(rest_t *d, const struct sockaddr *sa)
{
    ip_count probe, *ip;
    void *found;

    memset(&probe, 0, sizeof probe);
    if (sa && sa->sa_family == AF_INET) {
        probe.key[0] = 4;
        memcpy(probe.key + 1, &((const struct sockaddr_in *)(const void *)sa)->sin_addr, 4);
    } else if (sa && sa->sa_family == AF_INET6) {
        probe.key[0] = 16;
        memcpy(probe.key + 1, &((const struct sockaddr_in6 *)(const void *)sa)->sin6_addr, 16);
    } else {
        return NULL;
    }
    found = tfind(&probe, &d->ips, ip_cmp);
    if (found) {
        ip = *(ip_count **)found;
    } else {
        if (!(ip = malloc(sizeof *ip)))
            return NULL;
        *ip = probe;
        if (!tsearch(ip, &d->ips, ip_cmp)) {
            free(ip);
            return NULL;
        }
    }
    ip->n++;
    return ip;
}

/* conns_mu held: a connection of ip closed. */
static void ip_drop(rest_t *d, ip_count *ip)
{
    if (ip && --ip->n == 0) {
        tdelete(ip, &d->ips, ip_cmp);
        free(ip);
    }
}

/* Whether r came on a connection opened past --max-connections-per-ip:
 * then 1 and its 503 in p (answered on the first call, so the
 * connection closes). */
static int over_cap(const rest_request *r, svc_error *p)
{
    int cap = r->door->cfg->max_connections_per_ip;

    if (!r->conn || !((const conn_state *)r->conn)->over)
        return 0;
    svc_error_set(p, SVC_P_BUSY_ADDRESS, "this address has more than %d "
                    "connections open, the most one address may have "
                    "(--max-connections-per-ip %d): retry once one closes",
                    cap, cap);
    return 1;
}

unsigned rest_http_ip_backstop(const srv_config *cfg)
{
    unsigned cap = (unsigned)cfg->max_connections_per_ip;
    return cap ? cap + (cap + 3) / 4 : 0;
}

static void conn_waiting(conn_state *cs, int receiving)
{
    pthread_mutex_lock(&cs->door->conns_mu);
    cs->receiving = receiving;
    cs->since = srv_mono();
    cs->body = 0;
    pthread_mutex_unlock(&cs->door->conns_mu);
}

static void conn_body(conn_state *cs, size_t bytes)
{
    pthread_mutex_lock(&cs->door->conns_mu);
    cs->body = bytes;
    pthread_mutex_unlock(&cs->door->conns_mu);
}

void rest_http_connection(void *cls, struct MHD_Connection *c,
                          void **socket_context,
                          enum MHD_ConnectionNotificationCode code)
{
    rest_t *d = cls;
    conn_state *cs = *socket_context;

    if (code == MHD_CONNECTION_NOTIFY_STARTED) {
        const union MHD_ConnectionInfo *ci =
            MHD_get_connection_info(c, MHD_CONNECTION_INFO_CONNECTION_FD);
        const union MHD_ConnectionInfo *ai =
            MHD_get_connection_info(c, MHD_CONNECTION_INFO_CLIENT_ADDRESS);
        int cap = d->cfg->max_connections_per_ip;
        cs = calloc(1, sizeof(conn_state));
        if (cs) {
            cs->fd = ci ? ci->connect_fd : -1;
            cs->receiving = 1;
            cs->since = srv_mono();
            cs->door = d;
            pthread_mutex_lock(&d->conns_mu);
            if (cap > 0 &&
                (cs->ip = ip_take(d, ai ? ai->client_addr : NULL)))
                cs->over = cs->ip->n > cap;
            cs->next = d->conns;
            if (d->conns)
                d->conns->prev = cs;
            d->conns = cs;
            d->nconns++;
            pthread_mutex_unlock(&d->conns_mu);
        }
        *socket_context = cs;
        return;
    }
    if (cs) {
        /* Off the list before MHD closes the socket (it notifies first),
         * so rest_http_expire_heads never touches a reused descriptor. */
        pthread_mutex_lock(&d->conns_mu);
        if (cs->prev)
            cs->prev->next = cs->next;
        else
            d->conns = cs->next;
        if (cs->next)
            cs->next->prev = cs->prev;
        d->nconns--;
        ip_drop(d, cs->ip);
        pthread_mutex_unlock(&d->conns_mu);
        if (cs->req)
            request_free(cs->req, -1); /* never completed: abandoned */
    }
    free(cs);
    *socket_context = NULL;
}

int rest_http_expire_heads(rest_t *d, double timeout, int max_connections,
                           double body_timeout)
{
    double now = srv_mono();
    conn_state *cs;
    int n = 0;

    pthread_mutex_lock(&d->conns_mu);
    /* Nine tenths of the slots taken: heads get 2 s, so that a flood of
     * slow clients from many addresses leaves room for the probes and
     * for clients that send their request at once. */
    if (d->nconns * 10 >= max_connections * 9 && timeout > 2)
        timeout = 2;
    for (cs = d->conns; cs; cs = cs->next)
        if (cs->fd >= 0 &&
            /* past --max-connections-per-ip: 2 s for the head its 503
             * answers, also with no --header-timeout */
            ((cs->over && cs->receiving == 1 && now - cs->since > 2) ||
             (timeout > 0 && now - cs->since > timeout &&
              (cs->receiving == 1 ||
               (cs->receiving == 2 &&
                (double)cs->body < SRV_MIN_BODY_RATE * (now - cs->since)))) ||
             /* the ceiling on a whole body (--body-timeout),
              * for clients just above the average rate */
             (body_timeout > 0 && cs->receiving == 2 &&
              now - cs->since > body_timeout))) {
            /* MHD reads the end of the stream and closes the connection
             * itself; the descriptor stays MHD's to close. */
            shutdown(cs->fd, SHUT_RDWR);
            cs->receiving = 0;
            n++;
        }
    pthread_mutex_unlock(&d->conns_mu);
    return n;
}

void *rest_http_uri_log(void *cls, const char *uri, struct MHD_Connection *c)
{
    rest_t *d = cls;
    rest_request *r = calloc(1, sizeof *r);
    const srv_config *cfg = d->cfg;
    const union MHD_ConnectionInfo *ci =
        MHD_get_connection_info(c, MHD_CONNECTION_INFO_SOCKET_CONTEXT);
    conn_state *cs = ci ? ci->socket_context : NULL;
    char *q;

    if (!r)
        return NULL;
    r->door = d;
    r->uri = strdup(uri ? uri : "");
    /* MHD would next parse the query into its per-connection pool, a
     * record per parameter: a few hundred short ones exhaust it, and MHD
     * then neither answers nor completes the request. The daemon reads
     * the query from its own copy (r->uri: api_params_parse_query, and
     * query_value for `stream`), so MHD gets an empty one: the '?' it
     * found before this callback stays, the byte after it ends the
     * string. (uri points into MHD's writable request buffer; the
     * parameter is const only in the API.) */
    q = uri ? strchr(uri, '?') : NULL;
    if (q)
        ((char *)(uintptr_t)q)[1] = '\0';
    if (cs) {
        if (cs->req) /* the previous request never completed */
            request_free(cs->req, -1);
        cs->req = r;
        r->conn = cs;
    }
    r->t0 = mcf_now();
    r->rt = RT_OTHER;
    api_buf_init(&r->mesh, cfg->svc.lim.max_input_bytes);
    api_buf_init(&r->target, cfg->svc.lim.max_input_bytes);
    api_buf_init(&r->params, cfg->svc.lim.max_json_bytes);
    pthread_mutex_lock(&d->active_mu);
    d->active++;
    pthread_mutex_unlock(&d->active_mu);
    return r;
}

/* The bytes of a refused body read and discarded (rest_internal.h,
 * SRV_DRAIN_MAX): refused from its head, all it declared (no more than
 * SRV_DRAIN_MAX: its head was checked); else SRV_DRAIN_MAX past the
 * error. */
static size_t drain_bound(const rest_request *r)
{
    return r->perr_head && r->declared > 0 ? r->declared
                                           : r->perr_at - 1 + SRV_DRAIN_MAX;
}

enum MHD_Result rest_http_handle(void *cls, struct MHD_Connection *c,
                                 const char *url, const char *method,
                                 const char *version, const char *upload_data,
                                 size_t *upload_data_size, void **con_cls)
{
    rest_request *r = *con_cls;

    (void)cls;
    if (!r || !r->uri)
        return MHD_NO; /* out of memory in the URI callback */
    if (!r->started) {
        svc_error p;
        r->started = 1;
        if (framing_refused(c, version, &p) || over_cap(r, &p)) {
            snprintf(r->method, sizeof r->method, "%s", method);
            snprintf(r->path, sizeof r->path, "%s", url);
            return rest_send_problem(r, c, &p, NULL);
        }
        if (r->conn) /* the head is in; an upload's body comes next */
            conn_waiting(r->conn, strcmp(method, "POST") == 0 ? 2 : 0);
        /* MHD takes an answer queued on this first call, before it knows
         * there is no body, as an early one and closes the connection
         * after it: no keep-alive, pipelined requests lost. Only uploads
         * are answered early (401, 404, 413, 415 and 503 before the body);
         * everything else on the next call. */
        if (strcmp(method, "POST") != 0) {
            r->deferred = 1;
            return MHD_YES;
        }
        return first_call(r, c, url, method);
    }
    if (r->deferred) {
        if (*upload_data_size > 0) { /* a body where none belongs: ignored */
            r->bytes_in += *upload_data_size;
            *upload_data_size = 0;
            return MHD_YES;
        }
        r->deferred = 0;
        return first_call(r, c, url, method);
    }
    if (r->waiting)
        return rest_wait_or_answer(r, c);
    if (*upload_data_size > 0) {
        rest_upload_consume(r, upload_data, *upload_data_size);
        *upload_data_size = 0;
        if (r->conn)
            conn_body(r->conn, r->bytes_in);
        if (r->has_perr && !r->perr_at) {
            /* refused: what it holds goes now, the rest is discarded */
            r->perr_at = r->bytes_in + 1;
            api_buf_free(&r->mesh);
            api_buf_free(&r->target);
            svc_upload_release(r->door->svc, &r->mem_held);
            /* found in the body (over --max-upload on the way, broken
             * multipart): answered now, a client that reads while it
             * sends stops there */
            if (!r->perr_head) {
                rest_send_problem_raw(r, c, &r->perr);
                r->answered = 1;
            }
        }
        /* A refused body is read and discarded so that its client hears
         * why, but only so far (SRV_DRAIN_MAX): then the answer goes
         * straight to the socket (if it has not yet), and the connection
         * is closed. */
        if (r->perr_at && r->bytes_in > drain_bound(r)) {
            if (!r->answered)
                rest_send_problem_raw(r, c, &r->perr);
            return MHD_NO;
        }
        return MHD_YES;
    }
    if (r->answered) /* the rest of a refused body: the answer is out */
        return MHD_NO;
    if (r->conn) /* the body is complete */
        conn_waiting(r->conn, 0);
    if ((r->rt == RT_SMOOTH || r->rt == RT_JOBS) && !r->job)
        return rest_upload_submit(r, c);
    return MHD_YES;
}

void rest_http_completed(void *cls, struct MHD_Connection *c, void **con_cls,
                         enum MHD_RequestTerminationCode toe)
{
    rest_request *r = *con_cls;

    (void)cls;
    (void)c;
    if (!r)
        return;
    *con_cls = NULL;
    request_free(r, (int)toe);
}

/* Releases everything a request holds and writes its log line. toe: MHD's
 * termination code, -1 for a request MHD abandoned without completing. */
static void request_free(rest_request *r, int toe)
{
    rest_t *d = r->door;
    cJSON *o;
    int had_job;

    if (r->conn) {
        conn_state *cs = r->conn;
        cs->req = NULL;
        conn_waiting(cs, 1); /* keep-alive: the next request's head */
    }
    had_job = r->job != NULL;
    rest_request_release_job(r);
    if (r->pp)
        MHD_destroy_post_processor(r->pp);
    o = cJSON_CreateObject();
    if (o) {
        cJSON_AddStringToObject(o, "type", "request");
        cJSON_AddStringToObject(o, "method", r->method);
        cJSON_AddStringToObject(o, "path", r->path);
        cJSON_AddStringToObject(o, "route", rest_route_name(r->rt));
        cJSON_AddNumberToObject(o, "status", r->status);
        cJSON_AddNumberToObject(o, "ms", (mcf_now() - r->t0) * 1e3);
        cJSON_AddNumberToObject(o, "bytes_in", (double)r->bytes_in);
        if (had_job)
            cJSON_AddStringToObject(o, "job", r->id);
        if (toe < 0)
            cJSON_AddStringToObject(o, "terminated", "abandoned by MHD");
        else if (toe != MHD_REQUEST_TERMINATED_COMPLETED_OK)
            cJSON_AddNumberToObject(o, "terminated", toe);
        srv_log_json(r->rt == RT_HEALTHZ || r->rt == RT_READYZ ||
                     r->rt == RT_METRICS ? SRV_LOG_DEBUG : SRV_LOG_INFO, o);
    }
    api_buf_free(&r->mesh);
    api_buf_free(&r->target);
    api_buf_free(&r->params);
    svc_upload_release(d->svc, &r->mem_held);
    cJSON_Delete(r->fields);
    free(r->uri);
    free(r);
    pthread_mutex_lock(&d->active_mu);
    d->active--;
    pthread_mutex_unlock(&d->active_mu);
}

