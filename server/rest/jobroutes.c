/* SPDX-License-Identifier: MIT */
/*
 * jobroutes.c - the REST door's answers about jobs: a /smooth request
 * waiting on its job (the result, multipart/mixed, or an ndjson stream
 * once the job is ready), and the /v1/jobs/ID routes (status, result,
 * metrics, events, DELETE). Everything comes from the service through
 * snapshots and copies (service.h); the messages here are REST's (they
 * name URLs), the error codes the service's.
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "rest_internal.h"

/* The job's id and the link to its metrics, on every result; and the
 * core's warnings about the result, when there are any (the metrics'
 * "warnings", comma-separated: "X-Warnings: folds, area_loss"), so that
 * a pipeline can react to a damaged mesh without reading the metrics. */
static void add_job_headers(struct MHD_Response *resp, const svc_job *j)
{
    char buf[160], *doc = NULL;
    size_t len;
    svc_error e;
    cJSON *m;
    const cJSON *w;

    MHD_add_response_header(resp, "X-Job-Id", svc_job_id(j));
    snprintf(buf, sizeof buf, "</v1/jobs/%s/metrics>; rel=\"metrics\"",
             svc_job_id(j));
    MHD_add_response_header(resp, MHD_HTTP_HEADER_LINK, buf);
    if (svc_job_metrics(j, &doc, &len, &e) != 0)
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
static const char *result_stem(const svc_snap *s)
{
    return s->filename[0] ? s->filename : "mesh";
}

static void add_result_headers(struct MHD_Response *resp, const svc_job *j,
                               const svc_snap *s)
{
    char buf[256];
    api_format f = api_format_from_name(s->out_format);

    MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_TYPE,
                            api_format_mime(f));
    snprintf(buf, sizeof buf, "attachment; filename=\"%s-smoothed%s\"",
             result_stem(s), api_format_ext(f));
    MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_DISPOSITION, buf);
    add_job_headers(resp, j);
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
static enum MHD_Result send_mixed(rest_request *r, struct MHD_Connection *c,
                                  const svc_snap *s, char *mesh, size_t len)
{
    char boundary[96], hdr[160], *metrics = NULL;
    api_buf b;
    struct MHD_Response *resp;
    size_t n;
    api_format f = api_format_from_name(s->out_format);
    svc_error e;
    int k = 0;

    if (svc_job_metrics(r->job, &metrics, &n, &e) != 0)
        metrics = NULL;
    do /* a boundary that occurs in neither part */
        snprintf(boundary, sizeof boundary, "mcfd-%s-%d", s->id, k++);
    while (find_bytes(mesh, len, boundary) ||
           (metrics && find_bytes(metrics, strlen(metrics), boundary)));
    api_buf_init(&b, 0);
    api_buf_printf(&b, "--%s\r\nContent-Type: application/json\r\n"
                       "Content-Disposition: inline; name=\"metrics\"\r\n\r\n%s"
                       "\r\n--%s\r\nContent-Type: %s\r\n"
                       "Content-Disposition: attachment; name=\"mesh\"; "
                       "filename=\"%s-smoothed%s\"\r\nContent-Length: %zu\r\n\r\n",
                   boundary, metrics ? metrics : "{}", boundary,
                   api_format_mime(f), result_stem(s), api_format_ext(f), len);
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
    add_job_headers(resp, r->job);
    return rest_respond(r, c, 200, resp);
}

/* Answers a waiting /smooth request whose job has finished. */
static enum MHD_Result send_outcome(rest_request *r, struct MHD_Connection *c,
                                    const svc_snap *s)
{
    svc_error e;
    char *data;
    size_t len = 0;
    struct MHD_Response *resp;

    if (s->status != SVC_JOB_SUCCEEDED)
        return rest_send_problem(r, c, &s->error, s->id);
    /* The copy the worker kept for this request, else the spool. */
    if (svc_job_result(r->job, r->sync_owner ? SVC_RESULT_TAKE : 0, &data,
                       &len, &e) != 0)
        return rest_send_problem(r, c, &e, s->id);
    if (r->md == MODE_MIXED)
        return send_mixed(r, c, s, data, len);
    resp = MHD_create_response_from_buffer(len, data, MHD_RESPMEM_MUST_FREE);
    if (!resp) {
        free(data);
        return MHD_NO;
    }
    add_result_headers(resp, r->job, s);
    return rest_respond(r, c, 200, resp);
}

enum MHD_Result rest_wait_or_answer(rest_request *r, struct MHD_Connection *c)
{
    svc_snap s;
    svc_error p;

    for (;;) {
        rest_waiter_arm(&r->w);
        svc_job_snapshot(r->job, &s);
        if (r->md == MODE_NDJSON && (s.status == SVC_JOB_SUCCEEDED ||
                                     (s.status == SVC_JOB_RUNNING && s.ready))) {
            /* The stream takes over: it follows the job itself. */
            rest_waiter_stop(&r->w);
            r->waiting = 0;
            return rest_respond(r, c, 200,
                                rest_stream_response(r->door, r->job, SRV_STREAM_NDJSON,
                                                     r->phases, c, -1));
        }
        if (svc_job_status_terminal(s.status)) {
            rest_waiter_stop(&r->w);
            r->waiting = 0;
            return send_outcome(r, c, &s);
        }
        if ((s.status == SVC_JOB_QUEUED && s.draining) || s.closing) {
            rest_waiter_stop(&r->w);
            r->waiting = 0;
            svc_error_set(&p, SVC_P_DRAINING, "the daemon is shutting "
                            "down; job %s stays %s on disk and runs after the "
                            "restart (GET /v1/jobs/%s)", s.id,
                            svc_job_status_name(s.status), s.id);
            return rest_send_problem(r, c, &p, s.id);
        }
        if (rest_waiter_sleep(&r->w))
            return MHD_YES;
    }
}

void rest_request_release_job(rest_request *r)
{
    if (!r->job)
        return;
    rest_waiter_stop(&r->w);
    if (r->sync_owner) /* nobody else will take the kept copy */
        svc_job_release_result(r->job);
    svc_job_unref(r->job);
    r->job = NULL;
}

/* ------------------------------------------------------------ /v1/jobs/ID */

static enum MHD_Result job_json_reply(rest_request *r, struct MHD_Connection *c,
                                      const svc_job *j, unsigned status)
{
    return rest_send_json(r, c, status, rest_job_json(j, NULL));
}

static enum MHD_Result get_job_part(rest_request *r, struct MHD_Connection *c,
                                    svc_job *j)
{
    svc_snap s;
    svc_error e;
    svc_error p;

    svc_job_snapshot(j, &s);
    if (s.status == SVC_JOB_QUEUED || s.status == SVC_JOB_RUNNING) {
        svc_error_set(&p, SVC_P_NOT_READY, "job %s is %s (step %d of %d); "
                        "poll /v1/jobs/%s until it has succeeded", s.id,
                        svc_job_status_name(s.status), s.step, s.steps_planned,
                        s.id);
        return rest_send_problem(r, c, &p, s.id);
    }
    if (s.status != SVC_JOB_SUCCEEDED) {
        svc_error_set(&p, SVC_P_NO_RESULT, "job %s %s and has no %s; see "
                        "/v1/jobs/%s for the error", s.id,
                        svc_job_status_name(s.status),
                        r->rt == RT_JOB_METRICS   ? "metrics"
                        : r->rt == RT_JOB_FIELDS ? "fields"
                                                 : "result", s.id);
        return rest_send_problem(r, c, &p, s.id);
    }
    if (r->rt == RT_JOB_METRICS) {
        char *metrics;
        size_t len;
        if (svc_job_metrics(j, &metrics, &len, &e) != 0)
            return rest_send_problem(r, c, &e, s.id);
        return rest_send_text(r, c, 200, "application/json", metrics, len);
    } else {
        struct MHD_Response *resp;
        char *data;
        size_t size;
        int fd;

        if ((r->rt == RT_JOB_FIELDS ? svc_job_fields_open(j, &fd, &data, &size, &e)
                                    : svc_job_result_open(j, &fd, &data, &size, &e)) != 0)
            return rest_send_problem(r, c, &e, s.id);
        /* zero-copy from the store's descriptor, else its bytes */
        resp = fd >= 0 ? MHD_create_response_from_fd(size, fd)
                       : MHD_create_response_from_buffer(size, data,
                                                         MHD_RESPMEM_MUST_FREE);
        if (!resp) {
            if (fd >= 0)
                close(fd);
            free(data);
            return MHD_NO;
        }
        if (r->rt == RT_JOB_FIELDS) {
            MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_TYPE,
                                    SRV_FIELDS_MIME);
            MHD_add_response_header(resp, "X-Job-Id", s.id);
        } else {
            add_result_headers(resp, j, &s);
        }
        return rest_respond(r, c, 200, resp);
    }
}

static enum MHD_Result delete_job(rest_request *r, struct MHD_Connection *c)
{
    svc_delete_result res;
    svc_job_status before;
    svc_error e;
    svc_job *j;
    enum MHD_Result ret;

    if (svc_delete(r->door->svc, r->id, &res, &before, &e) != 0)
        return rest_send_problem(r, c, &e, NULL);
    if (res == SVC_DELETE_FORGOTTEN)
        return rest_respond(r, c, 204, rest_empty_response());
    j = svc_job_get(r->door->svc, r->id);
    if (!j) /* forgotten in between: it is gone, as asked */
        return rest_respond(r, c, 204, rest_empty_response());
    ret = job_json_reply(r, c, j, res == SVC_DELETE_STOPPING ? 202 : 200);
    svc_job_unref(j);
    return ret;
}

enum MHD_Result rest_route_job(rest_request *r, struct MHD_Connection *c,
                               const char *method)
{
    svc_job *j;
    svc_error p;
    enum MHD_Result ret;

    if (r->rt == RT_JOB && strcmp(method, "DELETE") == 0)
        return delete_job(r, c);
    if (strcmp(method, "GET") != 0 && strcmp(method, "HEAD") != 0) {
        svc_error_set(&p, SVC_P_METHOD, "%s is not allowed on %s", method,
                        r->path);
        return rest_send_problem(r, c, &p, NULL);
    }
    j = svc_job_find(r->door->svc, r->id, &p);
    if (!j)
        return rest_send_problem(r, c, &p, NULL);
    if (r->rt == RT_JOB) {
        ret = job_json_reply(r, c, j, 200);
    } else if (r->rt == RT_JOB_EVENTS && strcmp(method, "HEAD") == 0) {
        /* The stream's headers without the stream: MHD would still send
         * the chunked body's terminator after the headers of a HEAD. */
        struct MHD_Response *resp = rest_empty_response();
        if (resp) {
            MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_TYPE,
                                    "text/event-stream");
            MHD_add_response_header(resp, MHD_HTTP_HEADER_CACHE_CONTROL,
                                    "no-cache");
            MHD_add_response_header(resp, "X-Job-Id", r->id);
        }
        ret = rest_respond(r, c, 200, resp);
    } else if (r->rt == RT_JOB_EVENTS) {
        const char *h = MHD_lookup_connection_value(c, MHD_HEADER_KIND,
                                                    "Last-Event-ID");
        long last = h ? strtol(h, NULL, 10) : -1;
        if (!rest_stream_admit(r->door, j, &p))
            ret = rest_send_problem(r, c, &p, r->id);
        else
            ret = rest_respond(r, c, 200,
                               rest_stream_response(r->door, j, SRV_STREAM_SSE, 1, c, last));
    } else {
        ret = get_job_part(r, c, j);
    }
    svc_job_unref(j);
    return ret;
}
