/*
 * http.c - the HTTP face of mcfd on libmicrohttpd: routing, uploads,
 * authentication, waiting on jobs, and every response.
 *
 * A request object (srv_request) is made by the URI log callback, which
 * sees the raw target with its query string, hangs on con_cls, and is
 * freed only in the completion callback, which also writes the request's
 * log line. The handler runs on MHD's small thread pool and never touches
 * a mesh: an upload is buffered (raw body, or the multipart fields mesh,
 * target, params and plain parameter fields), handed to the job system,
 * and the connection is suspended until a worker resumes it.
 *
 * What is refused is refused as early as possible: a missing token (401),
 * an unknown route (404), an unsupported Content-Type (415), a
 * Content-Length over the limit (413) and a full queue or a draining
 * daemon (503 + Retry-After) are answered on the first call, from the
 * headers alone, so a client using Expect: 100-continue never sends the
 * body. MHD cannot answer in the middle of an upload, so errors found
 * while reading (a part over its limit, broken multipart) are remembered
 * and answered once the body has been consumed.
 */
#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include "srv.h"

typedef enum {
    RT_HEALTHZ = 0,
    RT_READYZ,
    RT_METRICS,
    RT_OPENAPI,
    RT_SCHEMES,
    RT_SMOOTH,
    RT_JOBS,
    RT_JOB,
    RT_JOB_RESULT,
    RT_JOB_METRICS,
    RT_JOB_EVENTS,
    RT_OTHER
} route;

static const char *const route_names[] = {
    "healthz", "readyz", "metrics", "openapi", "schemes", "smooth", "jobs",
    "job", "job_result", "job_metrics", "job_events", "other"};

typedef enum { MODE_SYNC = 0, MODE_MIXED, MODE_NDJSON, MODE_ASYNC } mode;

typedef struct {
    char *uri;                 /* raw request target, query included */
    char path[256];
    char method[16];
    char id[SRV_ID_LEN + 1];
    double t0;
    route rt;
    unsigned status;           /* of the queued response, 0 before */
    int started;
    int deferred;              /* answered once the (absent) body is read */
    void *conn;                /* its connection's conn_state, or NULL */
    /* upload */
    int multipart;
    struct MHD_PostProcessor *pp;
    api_buf mesh, target, params;
    int has_mesh, has_target, has_params;
    cJSON *fields;             /* [[key, value], ...] plain form fields */
    size_t fields_bytes;
    char filename[128];
    size_t bytes_in;
    srv_problem perr;          /* found while reading; answered at the end */
    int has_perr;
    size_t perr_at;            /* bytes_in + 1 when perr was first seen */
    /* waiting on a job */
    mode md;
    srv_job *job;
    srv_waiter w;
    int waiting;
    int sync_owner;            /* this request takes job->result */
} srv_request;

/* The longest query string read (the request line and headers together
 * are bounded by MHD's per-connection pool, SRV_CONN_MEMORY in main.c). */
#define SRV_MAX_QUERY 8192

/* An upload still coming after --header-timeout must have averaged this
 * many bytes a second since its head (slow-body clients hold a slot). */
#define SRV_MIN_BODY_RATE 4096.0

static pthread_mutex_t g_active_mu = PTHREAD_MUTEX_INITIALIZER;
static int g_active;

int srv_http_active(void)
{
    int n;
    pthread_mutex_lock(&g_active_mu);
    n = g_active;
    pthread_mutex_unlock(&g_active_mu);
    return n;
}

static int terminal(srv_job_status s)
{
    return s == SRV_JOB_SUCCEEDED || s == SRV_JOB_FAILED ||
           s == SRV_JOB_CANCELED;
}

/* The query string of the request target, NULL when there is none. */
static const char *query_of(const srv_request *r)
{
    const char *q = strchr(r->uri, '?');
    return q ? q + 1 : NULL;
}

/* The decoded value of `key` in the raw query (last one wins), into out;
 * NULL when absent. %XX and '+' are decoded. */
static const char *query_value(const srv_request *r, const char *key,
                               char *out, size_t size)
{
    const char *p = query_of(r), *found = NULL;
    size_t klen = strlen(key);

    while (p && *p) {
        size_t n = strcspn(p, "&");
        if (n > klen && strncmp(p, key, klen) == 0 && p[klen] == '=')
            found = p + klen + 1;
        else if (n == klen && strncmp(p, key, klen) == 0)
            found = p + klen;
        p += n;
        if (*p == '&')
            p++;
    }
    if (!found)
        return NULL;
    {
        size_t i = 0;
        for (; *found && *found != '&' && i + 1 < size; found++) {
            if (*found == '%' && isxdigit((unsigned char)found[1]) &&
                isxdigit((unsigned char)found[2])) {
                char hex[3] = {found[1], found[2], 0};
                out[i++] = (char)strtol(hex, NULL, 16);
                found += 2;
            } else {
                out[i++] = *found == '+' ? ' ' : *found;
            }
        }
        out[i] = '\0';
    }
    return out;
}

/* ------------------------------------------------------------ responses */

static enum MHD_Result respond(srv_request *r, struct MHD_Connection *c,
                               unsigned status, struct MHD_Response *resp)
{
    enum MHD_Result ret;

    if (!resp)
        return MHD_NO;
    r->status = status;
    srv_metrics_request(route_names[r->rt], status);
    ret = MHD_queue_response(c, status, resp);
    MHD_destroy_response(resp);
    return ret;
}

/* A response owning a copy of the bytes. */
static struct MHD_Response *from_copy(const void *data, size_t len)
{
    char *p = malloc(len ? len : 1);
    if (!p)
        return NULL;
    memcpy(p, data, len);
    return MHD_create_response_from_buffer(len, p, MHD_RESPMEM_MUST_FREE);
}

static enum MHD_Result send_text(srv_request *r, struct MHD_Connection *c,
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
    return respond(r, c, status, resp);
}

/* A response holding o printed (takes o), with a trailing newline when
 * asked (friendlier in a terminal) and the given Content-Type; NULL when
 * out of memory. */
static struct MHD_Response *json_response(cJSON *o, const char *ctype, int newline)
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

/* Takes j. */
static enum MHD_Result send_json(srv_request *r, struct MHD_Connection *c,
                                 unsigned status, cJSON *j)
{
    struct MHD_Response *resp = json_response(j, "application/json", 1);

    return resp ? respond(r, c, status, resp) : MHD_NO;
}

static enum MHD_Result send_problem(srv_request *r, struct MHD_Connection *c,
                                    const srv_problem *p, const char *job)
{
    struct MHD_Response *resp =
        json_response(srv_problem_json(p, r->path, job), "application/problem+json", 0);

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
    return respond(r, c, p->http, resp);
}

static enum MHD_Result problem(srv_request *r, struct MHD_Connection *c,
                               unsigned http, const char *code,
                               const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 5, 6)))
#endif
    ;
static enum MHD_Result problem(srv_request *r, struct MHD_Connection *c,
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
    return send_problem(r, c, &p, NULL);
}

/* "bunny.drc" -> "bunny": letters, digits, '-', '_' and '.', at most 64. */
static void sanitize_name(char *out, size_t size, const char *in)
{
    const char *base = in ? strrchr(in, '/') : NULL;
    const char *dot;
    size_t n = 0;

    base = base ? base + 1 : in;
    if (!base || !*base)
        base = "mesh";
    dot = strrchr(base, '.');
    for (; *base && base != dot && n + 1 < size && n < 64; base++) {
        unsigned char ch = (unsigned char)*base;
        out[n++] = (isalnum(ch) || ch == '-' || ch == '_' || ch == '.')
                       ? (char)ch : '_';
    }
    out[n] = '\0';
    if (n == 0)
        snprintf(out, size, "mesh");
}

/* The job's id and the link to its metrics, on every result; and the
 * core's warnings about the result, when there are any (the metrics'
 * "warnings", comma-separated: "X-Warnings: folds, area_loss"), so that
 * a pipeline can react to a damaged mesh without reading the metrics. */
static void add_job_headers(struct MHD_Response *resp, const srv_job *j)
{
    char buf[160], *doc = NULL;
    size_t len;
    cJSON *m;
    const cJSON *w;

    MHD_add_response_header(resp, "X-Job-Id", j->id);
    snprintf(buf, sizeof buf, "</v1/jobs/%s/metrics>; rel=\"metrics\"", j->id);
    MHD_add_response_header(resp, MHD_HTTP_HEADER_LINK, buf);
    srv_lock();
    if (j->metrics_json)
        doc = strdup(j->metrics_json);
    srv_unlock();
    if (!doc && srv_spool_read(srv_jobs_config()->spool, j->id, "metrics.json",
                               &doc, &len) != 0)
        doc = NULL;
    m = doc ? cJSON_Parse(doc) : NULL;
    free(doc);
    buf[0] = '\0';
    cJSON_ArrayForEach(w, cJSON_GetObjectItemCaseSensitive(m, "warnings"))
        if (cJSON_IsString(w) &&
            strlen(buf) + strlen(w->valuestring) + 3 < sizeof buf) {
            if (buf[0])
                strcat(buf, ", ");
            strcat(buf, w->valuestring);
        }
    if (buf[0])
        MHD_add_response_header(resp, "X-Warnings", buf);
    cJSON_Delete(m);
}

/* The upload's name without extension ("mesh" when it had none). */
static const char *result_stem(const srv_job *j)
{
    return j->rec.filename[0] ? j->rec.filename : "mesh";
}

static void add_result_headers(struct MHD_Response *resp, const srv_job *j,
                               const char *format)
{
    char buf[256];
    api_format f = api_format_from_name(format);

    MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_TYPE,
                            api_format_mime(f));
    snprintf(buf, sizeof buf, "attachment; filename=\"%s-smoothed%s\"",
             result_stem(j), api_format_ext(f));
    MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_DISPOSITION, buf);
    add_job_headers(resp, j);
}

/* The encoded result: the copy the worker kept for us, else the spool. */
static char *take_result(srv_request *r, srv_job *j, size_t *len)
{
    char *data = NULL;

    srv_lock();
    if (r->sync_owner && j->result) {
        data = j->result;
        *len = j->result_len;
        j->result = NULL;
    }
    srv_unlock();
    if (!data && srv_spool_read(srv_jobs_config()->spool, j->id,
                                j->result_name, &data, len) != 0)
        return NULL;
    return data;
}

static const void *find_bytes(const char *hay, size_t n, const char *needle)
{
    size_t k = strlen(needle), i;
    for (i = 0; k <= n && i <= n - k; i++)
        if (hay[i] == needle[0] && memcmp(hay + i, needle, k) == 0)
            return hay + i;
    return NULL;
}

/* multipart/mixed: the metrics JSON part, then the mesh part. */
static enum MHD_Result send_mixed(srv_request *r, struct MHD_Connection *c,
                                  srv_job *j, char *mesh, size_t len)
{
    char boundary[96], hdr[160], *metrics;
    api_buf b;
    struct MHD_Response *resp;
    size_t n;
    api_format f;
    int k = 0;

    srv_lock();
    metrics = j->metrics_json ? strdup(j->metrics_json) : strdup("{}");
    f = api_format_from_name(j->out_format);
    srv_unlock();
    do /* a boundary that occurs in neither part */
        snprintf(boundary, sizeof boundary, "mcfd-%s-%d", j->id, k++);
    while (find_bytes(mesh, len, boundary) ||
           (metrics && find_bytes(metrics, strlen(metrics), boundary)));
    api_buf_init(&b, 0);
    api_buf_printf(&b, "--%s\r\nContent-Type: application/json\r\n"
                       "Content-Disposition: inline; name=\"metrics\"\r\n\r\n%s"
                       "\r\n--%s\r\nContent-Type: %s\r\n"
                       "Content-Disposition: attachment; name=\"mesh\"; "
                       "filename=\"%s-smoothed%s\"\r\nContent-Length: %zu\r\n\r\n",
                   boundary, metrics ? metrics : "{}", boundary,
                   api_format_mime(f), result_stem(j), api_format_ext(f), len);
    api_buf_append(&b, mesh, len);
    api_buf_printf(&b, "\r\n--%s--\r\n", boundary);
    free(metrics);
    free(mesh);
    if (!b.data) {
        api_buf_free(&b);
        return MHD_NO;
    }
    metrics = api_buf_detach(&b, &n);
    resp = MHD_create_response_from_buffer(n, metrics, MHD_RESPMEM_MUST_FREE);
    if (!resp) {
        free(metrics);
        return MHD_NO;
    }
    snprintf(hdr, sizeof hdr, "multipart/mixed; boundary=%s", boundary);
    MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_TYPE, hdr);
    add_job_headers(resp, j);
    return respond(r, c, 200, resp);
}

/* Answers a waiting /smooth request whose job has finished. */
static enum MHD_Result send_outcome(srv_request *r, struct MHD_Connection *c)
{
    srv_job *j = r->job;
    srv_job_status st;
    srv_problem err;
    char fmt[16];
    char *data;
    size_t len = 0;
    struct MHD_Response *resp;

    srv_lock();
    st = j->status;
    err = j->err;
    snprintf(fmt, sizeof fmt, "%s", j->out_format);
    srv_unlock();
    if (st != SRV_JOB_SUCCEEDED)
        return send_problem(r, c, &err, j->id);
    data = take_result(r, j, &len);
    if (!data) {
        srv_problem_set(&err, 500, "EIO", "the result of job %s is missing "
                        "from the spool", j->id);
        return send_problem(r, c, &err, j->id);
    }
    if (r->md == MODE_MIXED)
        return send_mixed(r, c, j, data, len);
    resp = MHD_create_response_from_buffer(len, data, MHD_RESPMEM_MUST_FREE);
    if (!resp) {
        free(data);
        return MHD_NO;
    }
    add_result_headers(resp, j, fmt);
    return respond(r, c, 200, resp);
}

/* Called with a waiting request (after submit, and after every resume):
 * answers when there is something to say, else suspends again. */
static enum MHD_Result wait_or_answer(srv_request *r, struct MHD_Connection *c)
{
    srv_job *j = r->job;
    srv_job_status st;
    srv_problem p;

    srv_lock();
    st = j->status;
    if (r->md == MODE_NDJSON && (st == SRV_JOB_SUCCEEDED ||
                                 (st == SRV_JOB_RUNNING && j->ready))) {
        srv_waiter_unlink(j, &r->w);
        r->waiting = 0;
        srv_unlock();
        return respond(r, c, 200, srv_stream_response(j, SRV_STREAM_NDJSON, c, -1));
    }
    if (terminal(st)) {
        srv_waiter_unlink(j, &r->w);
        r->waiting = 0;
        srv_unlock();
        return send_outcome(r, c);
    }
    if ((st == SRV_JOB_QUEUED && srv_jobs_draining_locked()) ||
        srv_jobs_closing_locked()) {
        srv_waiter_unlink(j, &r->w);
        r->waiting = 0;
        srv_unlock();
        srv_problem_set(&p, 503, "EDRAINING", "the daemon is shutting down; "
                        "job %s stays %s on disk and runs after the restart "
                        "(GET /v1/jobs/%s)", j->id, srv_job_status_name(st),
                        j->id);
        return send_problem(r, c, &p, j->id);
    }
    srv_waiter_suspend(&r->w);
    srv_unlock();
    return MHD_YES;
}

/* ------------------------------------------------------------ uploads */

static enum MHD_Result on_part(void *cls, enum MHD_ValueKind kind,
                               const char *key, const char *filename,
                               const char *content_type,
                               const char *transfer_encoding, const char *data,
                               uint64_t off, size_t size)
{
    srv_request *r = cls;
    const srv_config *cfg = srv_jobs_config();
    api_buf *dst = NULL;
    const char *limit_name = "--max-upload";
    size_t limit = cfg->lim.max_input_bytes;

    (void)kind;
    (void)content_type;
    (void)transfer_encoding;
    if (r->has_perr)
        return MHD_NO;
    if (!key || !*key) {
        /* MHD passes a part without Content-Disposition name as NULL:
         * no headers at all, only a filename or a Content-Type, or a mesh
         * whose bytes contain the boundary line. */
        srv_problem_set(&r->perr, 400, "EINVAL", "a multipart part has no "
                        "name: every part needs 'Content-Disposition: "
                        "form-data; name=\"...\"' (mesh, target, params, or a "
                        "parameter); does the mesh contain the boundary line?");
        r->has_perr = 1;
        return MHD_NO;
    }
    if (strcmp(key, "mesh") == 0) {
        dst = &r->mesh;
        r->has_mesh = 1;
        if (off == 0 && filename && !r->filename[0])
            sanitize_name(r->filename, sizeof r->filename, filename);
    } else if (strcmp(key, "target") == 0) {
        dst = &r->target;
        r->has_target = 1;
    } else if (strcmp(key, "params") == 0) {
        dst = &r->params;
        r->has_params = 1;
        limit = cfg->lim.max_json_bytes;
        limit_name = "the JSON size limit";
    } else if (filename) {
        srv_problem_set(&r->perr, 400, "EINVAL", "unknown multipart file field "
                        "'%s' (accepted: mesh, target, params, or a parameter "
                        "as a plain field)", key);
        r->has_perr = 1;
        return MHD_NO;
    } else {
        /* A parameter as a plain field: scheme=desbrun2. */
        cJSON *last = cJSON_GetArrayItem(r->fields, cJSON_GetArraySize(r->fields) - 1);
        r->fields_bytes += size + strlen(key);
        if (r->fields_bytes > cfg->lim.max_json_bytes) {
            srv_problem_set(&r->perr, 413, "ELIMIT", "multipart parameter fields "
                            "exceed %zu bytes", cfg->lim.max_json_bytes);
            r->has_perr = 1;
            return MHD_NO;
        }
        if (off == 0 || !last) {
            cJSON *pair = cJSON_CreateArray();
            char *v = malloc(size + 1);
            if (!pair || !v) {
                cJSON_Delete(pair);
                free(v);
                return MHD_NO;
            }
            memcpy(v, data, size);
            v[size] = '\0';
            cJSON_AddItemToArray(pair, cJSON_CreateString(key));
            cJSON_AddItemToArray(pair, cJSON_CreateString(v));
            free(v);
            cJSON_AddItemToArray(r->fields, pair);
        } else {
            /* the rest of a long value */
            cJSON *val = cJSON_GetArrayItem(last, 1);
            const char *old = cJSON_GetStringValue(val);
            size_t on = old ? strlen(old) : 0;
            char *v = malloc(on + size + 1);
            if (!v)
                return MHD_NO;
            memcpy(v, old ? old : "", on);
            memcpy(v + on, data, size);
            v[on + size] = '\0';
            cJSON_ReplaceItemInArray(last, 1, cJSON_CreateString(v));
            free(v);
        }
        return MHD_YES;
    }
    /* A part's first call has off 0; so may a second call when the first
     * carried no bytes. Bytes already held at off 0 are a second part:
     * refused rather than concatenated (two meshes would become one
     * non-manifold mesh). An empty first part is indistinguishable from
     * the start of the next one and harmless. */
    if (off == 0 && dst->len > 0) {
        srv_problem_set(&r->perr, 400, "EINVAL", "multipart field '%s' is "
                        "given twice: send exactly one '%s' part", key, key);
        r->has_perr = 1;
        return MHD_NO;
    }
    if (dst->len + size > limit) {
        srv_problem_set(&r->perr, 413, "ELIMIT", "multipart field '%s' is "
                        "larger than %zu bytes (%s)", key, limit, limit_name);
        r->has_perr = 1;
        return MHD_NO;
    }
    if (api_buf_append(dst, data, size) != MCF_OK) {
        srv_problem_set(&r->perr, 503, "ENOMEM", "out of memory reading "
                        "multipart field '%s'", key);
        r->has_perr = 1;
        return MHD_NO;
    }
    return MHD_YES;
}

static void consume(srv_request *r, const char *data, size_t size)
{
    const srv_config *cfg = srv_jobs_config();

    r->bytes_in += size;
    if (r->has_perr)
        return; /* discard: the error is answered at the end */
    if (r->multipart && r->bytes_in > cfg->max_body) {
        srv_problem_set(&r->perr, 413, "ELIMIT", "the multipart body exceeds "
                        "%zu bytes, the most it may hold with --max-upload %zu "
                        "(a mesh and a target of up to --max-upload each, and "
                        "the parameters)", cfg->max_body,
                        cfg->lim.max_input_bytes);
        r->has_perr = 1;
        return;
    }
    if (!r->multipart && r->bytes_in > cfg->lim.max_input_bytes) {
        srv_problem_set(&r->perr, 413, "ELIMIT", "the request body exceeds "
                        "%zu bytes (--max-upload)", cfg->lim.max_input_bytes);
        r->has_perr = 1;
        return;
    }
    if (r->multipart) {
        if (MHD_post_process(r->pp, data, size) != MHD_YES && !r->has_perr) {
            srv_problem_set(&r->perr, 400, "EDECODE", "malformed "
                            "multipart/form-data body");
            r->has_perr = 1;
        }
    } else if (api_buf_append(&r->mesh, data, size) != MCF_OK) {
        srv_problem_set(&r->perr, 503, "ENOMEM", "out of memory reading "
                        "the body");
        r->has_perr = 1;
    }
}

static char *dup_or_null(const api_buf *b, int present)
{
    if (!present)
        return NULL;
    return strdup(b->data ? b->data : "");
}

/* The body is complete: hand the job over. */
static enum MHD_Result submit(srv_request *r, struct MHD_Connection *c)
{
    srv_record rec;
    srv_problem p;
    srv_job *j = NULL;
    const char *q = strchr(r->uri, '?');
    char *mesh, *target = NULL;
    size_t mesh_len, target_len = 0;
    char loc[96];

    if (r->pp) {
        if (MHD_destroy_post_processor(r->pp) != MHD_YES && !r->has_perr) {
            srv_problem_set(&r->perr, 400, "EDECODE", "malformed or truncated "
                            "multipart/form-data body");
            r->has_perr = 1;
        }
        r->pp = NULL;
    }
    if (r->has_perr)
        return send_problem(r, c, &r->perr, NULL);
    if (r->multipart && !r->has_mesh)
        return problem(r, c, 400, "EINVAL", "multipart field 'mesh' is missing: "
                       "send the mesh as -F mesh=@file");
    if (r->mesh.len == 0)
        return problem(r, c, 400, "EINVAL", "the mesh is empty: send it as the "
                       "body or as multipart field 'mesh'");
    srv_metrics_upload(r->mesh.len);

    memset(&rec, 0, sizeof rec);
    rec.query = q && q[1] ? strdup(q + 1) : NULL;
    rec.params_json = dup_or_null(&r->params, r->has_params);
    rec.fields = r->fields;
    r->fields = NULL;
    snprintf(rec.filename, sizeof rec.filename, "%s",
             r->filename[0] ? r->filename : "mesh");
    mesh = api_buf_detach(&r->mesh, &mesh_len);
    if (r->has_target)
        target = api_buf_detach(&r->target, &target_len);
    if (srv_jobs_submit(&rec, mesh, mesh_len, target, target_len,
                        r->md == MODE_SYNC || r->md == MODE_MIXED, &j, &p) != 0)
        return send_problem(r, c, &p, NULL);
    r->job = j;
    snprintf(r->id, sizeof r->id, "%s", j->id);
    if (r->md == MODE_ASYNC) {
        struct MHD_Response *resp;
        cJSON *o;
        srv_lock();
        o = srv_job_json(j);
        srv_unlock();
        if (!(resp = json_response(o, "application/json", 0)))
            return MHD_NO;
        snprintf(loc, sizeof loc, "/v1/jobs/%s", j->id);
        MHD_add_response_header(resp, MHD_HTTP_HEADER_LOCATION, loc);
        MHD_add_response_header(resp, "X-Job-Id", j->id);
        return respond(r, c, 202, resp);
    }
    r->sync_owner = r->md != MODE_NDJSON;
    r->w.conn = c;
    r->w.want_events = 0;
    /* Nobody else knows this job's ID yet: when this client goes, so does
     * the reason to run it. */
    r->w.cancel_on_hangup = 1;
    r->waiting = 1;
    srv_lock();
    srv_waiter_link(j, &r->w);
    srv_unlock();
    return wait_or_answer(r, c);
}

/* ------------------------------------------------------------ routes */

static int parse_route(srv_request *r, const char *url)
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
        if (n != SRV_ID_LEN)
            return -1;
        memcpy(r->id, rest, n);
        r->id[n] = '\0';
        for (n = 0; n < SRV_ID_LEN; n++)
            if (!isxdigit((unsigned char)r->id[n]) ||
                isupper((unsigned char)r->id[n]))
                return -1;
        rest += SRV_ID_LEN;
        if (*rest == '\0')
            r->rt = RT_JOB;
        else if (strcmp(rest, "/result") == 0)
            r->rt = RT_JOB_RESULT;
        else if (strcmp(rest, "/metrics") == 0)
            r->rt = RT_JOB_METRICS;
        else if (strcmp(rest, "/events") == 0)
            r->rt = RT_JOB_EVENTS;
        else
            return -1;
    } else {
        r->rt = RT_OTHER;
        return -1;
    }
    return 0;
}

/* Constant time in the length of the configured token. */
static int token_ok(const char *given, size_t glen, const char *want,
                    size_t wlen)
{
    volatile unsigned char d = (unsigned char)(glen != wlen);
    size_t i;

    for (i = 0; i < wlen; i++)
        d |= (unsigned char)(want[i] ^ (i < glen ? given[i] : 0));
    return d == 0;
}

static int authorized(struct MHD_Connection *c)
{
    const srv_config *cfg = srv_jobs_config();
    const char *h;

    if (cfg->token_len == 0)
        return 1;
    h = MHD_lookup_connection_value(c, MHD_HEADER_KIND,
                                    MHD_HTTP_HEADER_AUTHORIZATION);
    if (!h || strncasecmp(h, "Bearer ", 7) != 0)
        return 0;
    h += 7;
    while (*h == ' ')
        h++;
    return token_ok(h, strlen(h), cfg->token, cfg->token_len);
}

static int is_get(const char *method)
{
    return strcmp(method, "GET") == 0 || strcmp(method, "HEAD") == 0;
}

static enum MHD_Result job_json_reply(srv_request *r, struct MHD_Connection *c,
                                      srv_job *j, unsigned status)
{
    cJSON *o;
    srv_lock();
    o = srv_job_json(j);
    srv_unlock();
    return send_json(r, c, status, o);
}

static enum MHD_Result get_job_part(srv_request *r, struct MHD_Connection *c,
                                    srv_job *j)
{
    srv_job_status st;
    srv_problem p;
    char fmt[16], name[32];
    char *metrics = NULL;
    int step, steps;

    srv_lock();
    st = j->status;
    step = j->step;
    steps = j->steps_planned;
    snprintf(fmt, sizeof fmt, "%s", j->out_format);
    snprintf(name, sizeof name, "%s", j->result_name);
    if (st == SRV_JOB_SUCCEEDED && r->rt == RT_JOB_METRICS && j->metrics_json)
        metrics = strdup(j->metrics_json);
    srv_unlock();
    if (st == SRV_JOB_QUEUED || st == SRV_JOB_RUNNING) {
        srv_problem_set(&p, 409, "ENOTREADY", "job %s is %s (step %d of %d); "
                        "poll /v1/jobs/%s until it has succeeded", j->id,
                        srv_job_status_name(st), step, steps, j->id);
        return send_problem(r, c, &p, j->id);
    }
    if (st != SRV_JOB_SUCCEEDED) {
        srv_problem_set(&p, 409, "ENORESULT", "job %s %s and has no %s; see "
                        "/v1/jobs/%s for the error", j->id,
                        srv_job_status_name(st),
                        r->rt == RT_JOB_METRICS ? "metrics" : "result", j->id);
        return send_problem(r, c, &p, j->id);
    }
    if (r->rt == RT_JOB_METRICS) {
        size_t len;
        if (!metrics && srv_spool_read(srv_jobs_config()->spool, j->id,
                                       "metrics.json", &metrics, &len) != 0) {
            srv_problem_set(&p, 500, "EIO", "metrics of job %s are missing",
                            j->id);
            return send_problem(r, c, &p, j->id);
        }
        return send_text(r, c, 200, "application/json", metrics,
                         strlen(metrics));
    } else {
        char path[1400];
        struct stat sb;
        struct MHD_Response *resp;
        int fd;

        if (srv_spool_path(path, sizeof path, srv_jobs_config()->spool, j->id,
                           name) != 0 ||
            (fd = open(path, O_RDONLY)) < 0) {
            srv_problem_set(&p, 500, "EIO", "the result of job %s is missing "
                            "from the spool", j->id);
            return send_problem(r, c, &p, j->id);
        }
        if (fstat(fd, &sb) != 0 ||
            !(resp = MHD_create_response_from_fd((size_t)sb.st_size, fd))) {
            close(fd);
            return MHD_NO;
        }
        add_result_headers(resp, j, fmt);
        return respond(r, c, 200, resp);
    }
}

static enum MHD_Result route_job(srv_request *r, struct MHD_Connection *c,
                                 const char *method)
{
    srv_job *j;
    srv_problem p;
    enum MHD_Result ret;

    if (r->rt == RT_JOB && strcmp(method, "DELETE") == 0) {
        srv_job_status before;
        int d = srv_jobs_delete(r->id, &before);
        if (d == -2)
            return problem(r, c, 500, "EIO", "job %s: the spool could not "
                           "record the DELETE (%s); %s", r->id, strerror(errno),
                           before == SRV_JOB_QUEUED || before == SRV_JOB_RUNNING
                               ? "it is canceled now, but may run again after "
                                 "a restart"
                               : "the job is kept; retry");
        if (d < 0)
            return problem(r, c, 404, "ENOTFOUND", "no job with ID %s "
                           "(never existed, deleted, or expired)", r->id);
        if (d == 2) {
            struct MHD_Response *resp = MHD_create_response_from_buffer(
                0, NULL, MHD_RESPMEM_PERSISTENT);
            return respond(r, c, 204, resp);
        }
        j = srv_jobs_get(r->id);
        if (!j) /* forgotten in between: it is gone, as asked */
            return respond(r, c, 204, MHD_create_response_from_buffer(
                                       0, NULL, MHD_RESPMEM_PERSISTENT));
        ret = job_json_reply(r, c, j, d == 1 ? 202 : 200);
        srv_job_unref(j);
        return ret;
    }
    if (!is_get(method)) {
        srv_problem_set(&p, 405, "EMETHOD", "%s is not allowed on %s", method,
                        r->path);
        return send_problem(r, c, &p, NULL);
    }
    j = srv_jobs_get(r->id);
    if (!j)
        return problem(r, c, 404, "ENOTFOUND", "no job with ID %s (never "
                       "existed, deleted, or expired)", r->id);
    if (r->rt == RT_JOB) {
        ret = job_json_reply(r, c, j, 200);
    } else if (r->rt == RT_JOB_EVENTS && strcmp(method, "HEAD") == 0) {
        /* The stream's headers without the stream: MHD would still send
         * the chunked body's terminator after the headers of a HEAD. */
        struct MHD_Response *resp = MHD_create_response_from_buffer(
            0, NULL, MHD_RESPMEM_PERSISTENT);
        if (resp) {
            MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_TYPE,
                                    "text/event-stream");
            MHD_add_response_header(resp, MHD_HTTP_HEADER_CACHE_CONTROL,
                                    "no-cache");
            MHD_add_response_header(resp, "X-Job-Id", j->id);
        }
        ret = respond(r, c, 200, resp);
    } else if (r->rt == RT_JOB_EVENTS) {
        const char *h = MHD_lookup_connection_value(c, MHD_HEADER_KIND,
                                                    "Last-Event-ID");
        long last = h ? strtol(h, NULL, 10) : -1;
        if (!srv_stream_admit(j, &p))
            ret = send_problem(r, c, &p, j->id);
        else
            ret = respond(r, c, 200,
                          srv_stream_response(j, SRV_STREAM_SSE, c, last));
    } else {
        ret = get_job_part(r, c, j);
    }
    srv_job_unref(j);
    return ret;
}

/* Media types taken as a raw mesh body (the format is then detected from
 * the bytes); everything else that is not multipart is a 415. The form
 * type is on the list because `curl --data-binary @mesh.obj` sends it by
 * default; a mesh is never a form, so nothing is lost. */
static int raw_mesh_type(const char *ct)
{
    static const char *const ok[] = {"application/octet-stream", "model/",
                                     "text/plain", "application/sla",
                                     "application/x-", "application/vnd.",
                                     "application/ply", "text/x-", NULL};
    int i;
    for (i = 0; ok[i]; i++)
        if (strncasecmp(ct, ok[i], strlen(ok[i])) == 0)
            return 1;
    return 0;
}

/* A body a busy daemon reads and discards so that its client, which is
 * sending it, hears the 503: an answer queued before the body makes MHD
 * stop reading, and the client's next bytes meet a reset. Above this, the
 * early answer (and the reset) is the lesser evil. */
#define DRAIN_MAX ((unsigned long long)16 << 20)

/* Content-Length above DRAIN_MAX: refused before it is read. */
static int big_body(struct MHD_Connection *c)
{
    const char *h = MHD_lookup_connection_value(c, MHD_HEADER_KIND,
                                                MHD_HTTP_HEADER_CONTENT_LENGTH);
    return h && strtoull(h, NULL, 10) > DRAIN_MAX;
}

static enum MHD_Result first_call(srv_request *r, struct MHD_Connection *c,
                                  const char *url, const char *method)
{
    const srv_config *cfg = srv_jobs_config();
    srv_problem p;
    const char *h, *q = query_of(r);
    char stream[32];

    snprintf(r->method, sizeof r->method, "%s", method);
    snprintf(r->path, sizeof r->path, "%s", url);
    if (parse_route(r, url) != 0)
        return problem(r, c, 404, "ENOTFOUND", "no such resource: %s", url);
    if (q && strlen(q) > SRV_MAX_QUERY)
        return problem(r, c, 414, "ELIMIT", "the query string has %zu bytes, "
                       "more than %d: send the parameters as a multipart "
                       "'params' field (JSON)", strlen(q), SRV_MAX_QUERY);
    if (r->rt != RT_HEALTHZ && r->rt != RT_READYZ && r->rt != RT_METRICS &&
        !authorized(c))
        return problem(r, c, 401, "EAUTH", "a valid 'Authorization: Bearer "
                       "<token>' header is required");
    switch (r->rt) {
    case RT_HEALTHZ:
    case RT_READYZ:
    case RT_METRICS:
    case RT_OPENAPI:
    case RT_SCHEMES:
        if (!is_get(method)) {
            srv_problem_set(&p, 405, "EMETHOD", "%s is not allowed on %s",
                            method, url);
            return send_problem(r, c, &p, NULL);
        }
        break;
    case RT_SMOOTH:
    case RT_JOBS:
        if (strcmp(method, "POST") != 0) {
            srv_problem_set(&p, 405, "EMETHOD", "%s is not allowed on %s; "
                            "POST a mesh", method, url);
            return send_problem(r, c, &p, NULL);
        }
        break;
    default:
        return route_job(r, c, method);
    }

    if (r->rt == RT_HEALTHZ) {
        cJSON *o = cJSON_CreateObject();
        cJSON_AddStringToObject(o, "status", "ok");
        return send_json(r, c, 200, o);
    }
    if (r->rt == RT_READYZ) {
        srv_gauges g = srv_jobs_gauges();
        cJSON *o;
        /* Draining and a spool that cannot be written make the daemon
         * unready. A full queue does not:
         * it is answered per request (503 + Retry-After), and an
         * orchestrator flapping every replica out of its Service under
         * load would turn those into connection errors. */
        char why[1500];
        if (g.draining)
            return problem(r, c, 503, "EDRAINING", "the daemon is shutting "
                           "down");
        /* Every job goes through the spool: one that cannot be written
         * makes every job fail. */
        if (srv_spool_ready(cfg->spool, why, sizeof why) != 0)
            return problem(r, c, 503, "ESPOOL", "%s", why);
        o = cJSON_CreateObject();
        cJSON_AddStringToObject(o, "status", "ready");
        cJSON_AddNumberToObject(o, "queue_depth", g.queue_depth);
        cJSON_AddNumberToObject(o, "workers_busy", g.workers_busy);
        return send_json(r, c, 200, o);
    }
    if (r->rt == RT_METRICS) {
        srv_gauges g = srv_jobs_gauges();
        size_t n = 0;
        char *s;
        /* This request is counted before rendering, so a scrape sees itself. */
        srv_metrics_request(route_names[r->rt], 200);
        s = srv_metrics_render(&g, &n);
        r->status = 200;
        if (!s)
            return MHD_NO;
        {
            struct MHD_Response *resp = MHD_create_response_from_buffer(
                n, s, MHD_RESPMEM_MUST_FREE);
            enum MHD_Result ret;
            if (!resp) {
                free(s);
                return MHD_NO;
            }
            MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_TYPE,
                                    "text/plain; version=0.0.4; charset=utf-8");
            ret = MHD_queue_response(c, 200, resp);
            MHD_destroy_response(resp);
            return ret;
        }
    }
    if (r->rt == RT_OPENAPI) {
        struct MHD_Response *resp = from_copy(srv_openapi_yaml,
                                              srv_openapi_yaml_len);
        if (resp)
            MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_TYPE,
                                    "application/yaml");
        return respond(r, c, 200, resp);
    }
    if (r->rt == RT_SCHEMES)
        return send_json(r, c, 200, api_json_schemes());

    /* POST /smooth, /v1/smooth, /v1/jobs: decide everything from headers. */
    h = query_value(r, "stream", stream, sizeof stream);
    if (r->rt == RT_SMOOTH) {
        const char *acc = MHD_lookup_connection_value(c, MHD_HEADER_KIND,
                                                      MHD_HTTP_HEADER_ACCEPT);
        if (h && strcmp(h, "ndjson") != 0)
            return problem(r, c, 400, "EINVAL", "parameter 'stream' must be "
                           "\"ndjson\", got \"%s\"", h);
        r->md = h ? MODE_NDJSON
                  : (acc && strstr(acc, "multipart/mixed")) ? MODE_MIXED
                                                            : MODE_SYNC;
    } else {
        if (h)
            return problem(r, c, 400, "EINVAL", "parameter 'stream' is only "
                           "for /smooth; follow /v1/jobs/ID/events instead");
        r->md = MODE_ASYNC;
    }
    h = MHD_lookup_connection_value(c, MHD_HEADER_KIND,
                                    MHD_HTTP_HEADER_CONTENT_TYPE);
    if (h && strncasecmp(h, "multipart/form-data", 19) == 0) {
        r->multipart = 1;
        r->fields = cJSON_CreateArray();
        r->pp = MHD_create_post_processor(c, 64 * 1024, on_part, r);
        if (!r->pp || !r->fields)
            return problem(r, c, 400, "EDECODE", "cannot parse the "
                           "multipart/form-data header '%s' (boundary?)", h);
    } else if (h && !raw_mesh_type(h)) {
        return problem(r, c, 415, "EFORMAT", "Content-Type '%s' is not a mesh: "
                       "send multipart/form-data with a 'mesh' field, or the "
                       "mesh bytes as application/octet-stream or model/*", h);
    }
    h = MHD_lookup_connection_value(c, MHD_HEADER_KIND,
                                    MHD_HTTP_HEADER_CONTENT_LENGTH);
    if (h) {
        char *end;
        unsigned long long n;
        size_t lim = r->multipart ? cfg->max_body : cfg->lim.max_input_bytes;
        errno = 0;
        n = strtoull(h, &end, 10);
        if (errno == 0 && end != h && n > lim) {
            if (r->multipart)
                srv_problem_set(&p, 413, "ELIMIT", "Content-Length %llu "
                                "exceeds %zu bytes, the most a multipart body "
                                "may hold with --max-upload %zu (a mesh and a "
                                "target of up to --max-upload each, and the "
                                "parameters)", n, lim, cfg->lim.max_input_bytes);
            else
                srv_problem_set(&p, 413, "ELIMIT", "Content-Length %llu exceeds "
                                "the limit of %zu bytes (--max-upload)", n, lim);
            return send_problem(r, c, &p, NULL);
        }
    }
    /* Busy or draining: say so before the body only when the client waits
     * for it (Expect: 100-continue) or the body is over DRAIN_MAX. A
     * client that is already sending would otherwise see its connection
     * reset by the close that follows an early answer, and lose the 503:
     * its body is read, discarded (never buffered) and answered. */
    h = MHD_lookup_connection_value(c, MHD_HEADER_KIND, MHD_HTTP_HEADER_EXPECT);
    if (srv_jobs_draining())
        srv_problem_set(&p, 503, "EDRAINING", "the daemon is shutting down "
                        "and accepts no new jobs");
    else if (!srv_jobs_can_accept())
        srv_problem_set(&p, 503, "EBUSY", "the job queue is full; retry "
                        "after the Retry-After delay");
    else
        return MHD_YES;
    if ((h && strncasecmp(h, "100-continue", 12) == 0) || big_body(c))
        return send_problem(r, c, &p, NULL);
    r->perr = p;
    r->has_perr = 1;
    return MHD_YES;
}

/* ------------------------------------------------------------ MHD entry */

/* What a connection holds between MHD's notifications: the request whose
 * completion callback is still due, so that it is released when the
 * connection closes without one (MHD skips it when a request overflows
 * its pool after the URI callback, e.g. hundreds of headers); and, for
 * the header deadline, whether it is waiting for a request's headers and
 * since when. Every connection is on g_conns (g_conns_mu guards the
 * list, receiving and since). */
typedef struct conn_state {
    srv_request *req;
    int fd;
    int receiving;             /* 1: no complete request head yet; 2: the
                                  head is in, the body is coming */
    size_t body;               /* body bytes so far (receiving 2) */
    double since;              /* srv_mono() when it began waiting */
    struct conn_state *prev, *next;
} conn_state;

static pthread_mutex_t g_conns_mu = PTHREAD_MUTEX_INITIALIZER;
static conn_state *g_conns;
static int g_nconns;

static void request_free(srv_request *r, int toe);

static void conn_waiting(conn_state *cs, int receiving)
{
    pthread_mutex_lock(&g_conns_mu);
    cs->receiving = receiving;
    cs->since = srv_mono();
    cs->body = 0;
    pthread_mutex_unlock(&g_conns_mu);
}

static void conn_body(conn_state *cs, size_t bytes)
{
    pthread_mutex_lock(&g_conns_mu);
    cs->body = bytes;
    pthread_mutex_unlock(&g_conns_mu);
}

void srv_http_connection(void *cls, struct MHD_Connection *c,
                         void **socket_context,
                         enum MHD_ConnectionNotificationCode code)
{
    conn_state *cs = *socket_context;

    (void)cls;
    if (code == MHD_CONNECTION_NOTIFY_STARTED) {
        const union MHD_ConnectionInfo *ci =
            MHD_get_connection_info(c, MHD_CONNECTION_INFO_CONNECTION_FD);
        cs = calloc(1, sizeof(conn_state));
        if (cs) {
            cs->fd = ci ? ci->connect_fd : -1;
            cs->receiving = 1;
            cs->since = srv_mono();
            pthread_mutex_lock(&g_conns_mu);
            cs->next = g_conns;
            if (g_conns)
                g_conns->prev = cs;
            g_conns = cs;
            g_nconns++;
            pthread_mutex_unlock(&g_conns_mu);
        }
        *socket_context = cs;
        return;
    }
    if (cs) {
        /* Off the list before MHD closes the socket (it notifies first),
         * so srv_http_expire_heads never touches a reused descriptor. */
        pthread_mutex_lock(&g_conns_mu);
        if (cs->prev)
            cs->prev->next = cs->next;
        else
            g_conns = cs->next;
        if (cs->next)
            cs->next->prev = cs->prev;
        g_nconns--;
        pthread_mutex_unlock(&g_conns_mu);
        if (cs->req)
            request_free(cs->req, -1); /* never completed: abandoned */
    }
    free(cs);
    *socket_context = NULL;
}

int srv_http_expire_heads(double timeout, int max_connections,
                          double body_timeout)
{
    double now = srv_mono();
    conn_state *cs;
    int n = 0;

    pthread_mutex_lock(&g_conns_mu);
    /* Nine tenths of the slots taken: heads get 2 s, so that a flood of
     * slow clients from many addresses leaves room for the probes and
     * for clients that send their request at once. */
    if (g_nconns * 10 >= max_connections * 9 && timeout > 2)
        timeout = 2;
    for (cs = g_conns; cs; cs = cs->next)
        if (cs->fd >= 0 &&
            ((timeout > 0 && now - cs->since > timeout &&
              (cs->receiving == 1 ||
               (cs->receiving == 2 &&
                (double)cs->body < SRV_MIN_BODY_RATE * (now - cs->since)))) ||
             /* issue 9 item 3: the ceiling on a whole body (--body-timeout),
              * for clients just above the average rate */
             (body_timeout > 0 && cs->receiving == 2 &&
              now - cs->since > body_timeout))) {
            /* MHD reads the end of the stream and closes the connection
             * itself; the descriptor stays MHD's to close. */
            shutdown(cs->fd, SHUT_RDWR);
            cs->receiving = 0;
            n++;
        }
    pthread_mutex_unlock(&g_conns_mu);
    return n;
}

void *srv_http_uri_log(void *cls, const char *uri, struct MHD_Connection *c)
{
    srv_request *r = calloc(1, sizeof *r);
    const srv_config *cfg = srv_jobs_config();
    const union MHD_ConnectionInfo *ci =
        MHD_get_connection_info(c, MHD_CONNECTION_INFO_SOCKET_CONTEXT);
    conn_state *cs = ci ? ci->socket_context : NULL;
    char *q;

    (void)cls;
    if (!r)
        return NULL;
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
    api_buf_init(&r->mesh, cfg->lim.max_input_bytes);
    api_buf_init(&r->target, cfg->lim.max_input_bytes);
    api_buf_init(&r->params, cfg->lim.max_json_bytes);
    pthread_mutex_lock(&g_active_mu);
    g_active++;
    pthread_mutex_unlock(&g_active_mu);
    return r;
}

enum MHD_Result srv_http_handle(void *cls, struct MHD_Connection *c,
                                const char *url, const char *method,
                                const char *version, const char *upload_data,
                                size_t *upload_data_size, void **con_cls)
{
    srv_request *r = *con_cls;

    (void)cls;
    (void)version;
    if (!r || !r->uri)
        return MHD_NO; /* out of memory in the URI callback */
    if (!r->started) {
        r->started = 1;
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
        return wait_or_answer(r, c);
    if (*upload_data_size > 0) {
        if (r->has_perr && !r->perr_at)
            r->perr_at = r->bytes_in + 1;
        consume(r, upload_data, *upload_data_size);
        *upload_data_size = 0;
        if (r->conn)
            conn_body(r->conn, r->bytes_in);
        /* A refused body is read and discarded so that its client hears
         * why, but only so far: then the connection is dropped. */
        if (r->perr_at && r->bytes_in - (r->perr_at - 1) > DRAIN_MAX)
            return MHD_NO;
        return MHD_YES;
    }
    if (r->conn) /* the body is complete */
        conn_waiting(r->conn, 0);
    if ((r->rt == RT_SMOOTH || r->rt == RT_JOBS) && !r->job)
        return submit(r, c);
    return MHD_YES;
}

void srv_http_completed(void *cls, struct MHD_Connection *c, void **con_cls,
                        enum MHD_RequestTerminationCode toe)
{
    srv_request *r = *con_cls;

    (void)cls;
    (void)c;
    if (!r)
        return;
    *con_cls = NULL;
    request_free(r, (int)toe);
}

/* Releases everything a request holds and writes its log line. toe: MHD's
 * termination code, -1 for a request MHD abandoned without completing. */
static void request_free(srv_request *r, int toe)
{
    cJSON *o;

    if (r->conn) {
        conn_state *cs = r->conn;
        cs->req = NULL;
        conn_waiting(cs, 1); /* keep-alive: the next request's head */
    }
    if (r->job) {
        srv_lock();
        srv_waiter_unlink(r->job, &r->w);
        if (r->sync_owner) {
            /* Nobody else will take the kept copy. */
            r->job->keep_result = 0;
            free(r->job->result);
            r->job->result = NULL;
        }
        srv_unlock();
        srv_job_unref(r->job);
    }
    if (r->pp)
        MHD_destroy_post_processor(r->pp);
    o = cJSON_CreateObject();
    if (o) {
        cJSON_AddStringToObject(o, "type", "request");
        cJSON_AddStringToObject(o, "method", r->method);
        cJSON_AddStringToObject(o, "path", r->path);
        cJSON_AddStringToObject(o, "route", route_names[r->rt]);
        cJSON_AddNumberToObject(o, "status", r->status);
        cJSON_AddNumberToObject(o, "ms", (mcf_now() - r->t0) * 1e3);
        cJSON_AddNumberToObject(o, "bytes_in", (double)r->bytes_in);
        if (r->job)
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
    cJSON_Delete(r->fields);
    free(r->uri);
    free(r);
    pthread_mutex_lock(&g_active_mu);
    g_active--;
    pthread_mutex_unlock(&g_active_mu);
}
