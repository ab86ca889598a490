/*
 * stream.c - response bodies that follow a job while it runs: ndjson for
 * POST /smooth?stream=ndjson and Server-Sent Events for
 * GET /v1/jobs/ID/events.
 *
 * Both read the job's event log (one ndjson line per accepted step, kept
 * in job->events) through a private cursor, so any number of followers
 * see every step in order, also those that join late. When the cursor
 * has caught up and the job still runs, the content reader suspends its
 * connection and returns 0; the worker's progress callback resumes it.
 * Both happen under the job lock, which is what makes the hand-over safe:
 * a resume can never come before its suspend. After the last step comes
 * one final record (the metrics and result URL, or the error) and the
 * chunked body ends.
 *
 * ndjson lines: {"step","t","dt","energy","volume"} per step, then
 * {"done":true,"job","status","result","metrics"} or {"done":...,"error"}.
 * SSE: "event: status" with the job JSON first, "id: N / event: progress"
 * per step (Last-Event-ID resumes after N), "event: done" with the job.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "srv.h"

#define CHUNK (64 * 1024)

typedef struct {
    srv_job *job;
    srv_stream_kind kind;
    srv_waiter w;
    size_t ev_off;            /* bytes of job->events already sent */
    long ev_index;            /* events passed (the SSE id of the last) */
    long last_id;             /* SSE Last-Event-ID: skip ids <= last_id */
    api_buf pend;             /* formatted, not yet handed to MHD */
    size_t pend_off;
    int started, finished;
} stream;

/* Streams open now; guarded by the job lock. */
static int g_followers;

int srv_stream_followers(void)
{
    return g_followers; /* read with the lock held (srv_jobs_gauges) */
}

int srv_stream_admit(const srv_job *j, srv_problem *p)
{
    const srv_config *cfg = srv_jobs_config();
    const srv_waiter *w;
    int here = 0, total, max_total = cfg->max_connections / 2;

    srv_lock();
    for (w = j->waiters; w; w = w->next)
        here += w->want_events;
    total = g_followers;
    srv_unlock();
    if (here >= SRV_FOLLOWERS_PER_JOB) {
        srv_problem_set(p, 503, "EBUSY", "job %s already has %d followers, "
                        "the most one job may have; poll GET /v1/jobs/%s "
                        "instead", j->id, here, j->id);
        return 0;
    }
    if (total >= max_total) {
        srv_problem_set(p, 503, "EBUSY", "%d event streams are open, the most "
                        "this daemon keeps (half of --max-connections %d)",
                        total, cfg->max_connections);
        return 0;
    }
    return 1;
}

static int terminal(srv_job_status s)
{
    return s == SRV_JOB_SUCCEEDED || s == SRV_JOB_FAILED ||
           s == SRV_JOB_CANCELED;
}

cJSON *srv_stream_final_json(const srv_job *j)
{
    char url[96];
    cJSON *o = cJSON_CreateObject();

    if (!o)
        return NULL;
    cJSON_AddBoolToObject(o, "done", terminal(j->status));
    cJSON_AddStringToObject(o, "job", j->id);
    cJSON_AddStringToObject(o, "status", srv_job_status_name(j->status));
    cJSON_AddNumberToObject(o, "steps", j->step);
    if (j->status == SRV_JOB_SUCCEEDED) {
        snprintf(url, sizeof url, "/v1/jobs/%s/result", j->id);
        cJSON_AddStringToObject(o, "result", url);
        snprintf(url, sizeof url, "/v1/jobs/%s/metrics", j->id);
        cJSON_AddStringToObject(o, "metrics_url", url);
        if (j->metrics_json) {
            cJSON *m = cJSON_Parse(j->metrics_json);
            if (m)
                cJSON_AddItemToObject(o, "metrics", m);
        }
    } else {
        srv_problem p = j->err;
        cJSON *e;
        if (!terminal(j->status))
            srv_problem_set(&p, 503, "EDRAINING", "the daemon is shutting "
                            "down; job %s stays %s and runs after the "
                            "restart", j->id, srv_job_status_name(j->status));
        snprintf(url, sizeof url, "/v1/jobs/%s", j->id);
        e = srv_problem_json(&p, url, j->id);
        if (e)
            cJSON_AddItemToObject(o, "error", e);
    }
    return o;
}

/* Appends "event: name\n[id: N\n]data: json\n\n". */
static void sse_event(api_buf *b, const char *name, long id, const char *data,
                      size_t len)
{
    if (id > 0)
        api_buf_printf(b, "id: %ld\n", id);
    api_buf_printf(b, "event: %s\ndata: ", name);
    api_buf_append(b, data, len);
    api_buf_append(b, "\n\n", 2);
}

static void sse_json(api_buf *b, const char *name, cJSON *o)
{
    char *s = o ? cJSON_PrintUnformatted(o) : NULL;
    if (s) {
        sse_event(b, name, 0, s, strlen(s));
        free(s);
    }
    cJSON_Delete(o);
}

/* With the lock held: moves what is new into s->pend. Returns 1 when
 * something was added (or the stream ended), 0 when it must wait. */
static int fill(stream *s)
{
    srv_job *j = s->job;

    if (!s->started) {
        s->started = 1;
        if (s->kind == SRV_STREAM_SSE) {
            api_buf_append(&s->pend, "retry: 2000\n", 12);
            sse_json(&s->pend, "status", srv_job_json(j));
            return 1;
        }
    }
    while (s->ev_off < j->events.len && s->pend.len < CHUNK) {
        const char *line = j->events.data + s->ev_off;
        const char *nl = memchr(line, '\n', j->events.len - s->ev_off);
        size_t n = nl ? (size_t)(nl - line) : j->events.len - s->ev_off;

        s->ev_off += n + (nl ? 1 : 0);
        s->ev_index++;
        if (s->kind == SRV_STREAM_NDJSON) {
            api_buf_append(&s->pend, line, n);
            api_buf_append(&s->pend, "\n", 1);
        } else if (s->ev_index > s->last_id) {
            sse_event(&s->pend, "progress", s->ev_index, line, n);
        }
    }
    if (s->pend.len > 0)
        return 1;
    if (terminal(j->status) ||
        (j->status == SRV_JOB_QUEUED && srv_jobs_draining_locked()) ||
        srv_jobs_closing_locked()) {
        if (s->kind == SRV_STREAM_NDJSON) {
            cJSON *o = srv_stream_final_json(j);
            char *t = o ? cJSON_PrintUnformatted(o) : NULL;
            if (t) {
                api_buf_append(&s->pend, t, strlen(t));
                api_buf_append(&s->pend, "\n", 1);
            }
            free(t);
            cJSON_Delete(o);
        } else {
            sse_json(&s->pend, "done", srv_job_json(j));
        }
        s->finished = 1;
        return 1;
    }
    return 0;
}

static ssize_t reader(void *cls, uint64_t pos, char *buf, size_t max)
{
    stream *s = cls;
    size_t n;

    (void)pos;
    if (s->pend_off == s->pend.len) {
        api_buf_free(&s->pend);
        api_buf_init(&s->pend, 0);
        s->pend_off = 0;
        if (s->finished)
            return MHD_CONTENT_READER_END_OF_STREAM;
        srv_lock();
        if (s->w.gone) {
            /* The client left while the stream slept (found by
             * srv_jobs_check_clients): end it, freeing the connection. */
            srv_unlock();
            return MHD_CONTENT_READER_END_WITH_ERROR;
        }
        if (!fill(s)) {
            /* Nothing new: sleep until the worker has more. */
            srv_waiter_suspend(&s->w);
            srv_unlock();
            return 0;
        }
        srv_unlock();
        if (s->pend.len == 0)
            return MHD_CONTENT_READER_END_OF_STREAM;
    }
    n = s->pend.len - s->pend_off;
    if (n > max)
        n = max;
    memcpy(buf, s->pend.data + s->pend_off, n);
    s->pend_off += n;
    return (ssize_t)n;
}

static void release(void *cls)
{
    stream *s = cls;

    srv_lock();
    srv_waiter_unlink(s->job, &s->w);
    g_followers--;
    srv_unlock();
    srv_job_unref(s->job);
    api_buf_free(&s->pend);
    free(s);
}

struct MHD_Response *srv_stream_response(srv_job *j, srv_stream_kind kind,
                                         struct MHD_Connection *conn,
                                         long last_id)
{
    struct MHD_Response *r;
    stream *s = calloc(1, sizeof *s);

    if (!s)
        return NULL;
    s->job = j;
    s->kind = kind;
    s->last_id = last_id;
    s->w.conn = conn;
    s->w.want_events = 1;
    api_buf_init(&s->pend, 0);
    r = MHD_create_response_from_callback(MHD_SIZE_UNKNOWN, CHUNK, reader, s,
                                          release);
    if (!r) {
        api_buf_free(&s->pend);
        free(s);
        return NULL;
    }
    srv_lock();
    j->refs++;
    srv_waiter_link(j, &s->w);
    g_followers++;
    srv_unlock();
    MHD_add_response_header(r, MHD_HTTP_HEADER_CONTENT_TYPE,
                            kind == SRV_STREAM_SSE ? "text/event-stream"
                                                   : "application/x-ndjson");
    MHD_add_response_header(r, MHD_HTTP_HEADER_CACHE_CONTROL, "no-cache");
    MHD_add_response_header(r, "X-Accel-Buffering", "no");
    MHD_add_response_header(r, "X-Job-Id", j->id);
    return r;
}
