/* SPDX-License-Identifier: MIT */
/*
 * stream.c - response bodies that follow a job while it runs: ndjson for
 * POST /smooth?stream=ndjson and Server-Sent Events for
 * GET /v1/jobs/ID/events.
 *
 * Both read the job's event log (one ndjson line per accepted step, kept
 * by the service: svc_job_events) through a private cursor, so any number
 * of followers see every step in order, also those that join late. When
 * the cursor has caught up and the job still runs, the content reader
 * suspends its connection and returns 0; the service's progress
 * notification resumes it (waiter.c: no notification is lost between the
 * snapshot and the suspend). After the last step comes one final record
 * (the metrics and result URL, or the error) and the chunked body ends.
 *
 * ndjson lines: {"step","t","dt","energy","volume"} per step, then
 * {"done":true,"job","status","result","metrics"} or {"done":...,"error"}.
 * SSE: "event: status" with the job JSON first, "id: N / event: progress"
 * per step (Last-Event-ID resumes after N), "event: done" with the job.
 * Between them, the core's milestones: {"step","phase","fraction"}, SSE's
 * "event: work" without an id, at each new phase of the run (kept with the
 * job: a late follower gets them all) and at each percent of the work
 * while no step comes (the default request's phases); in ndjson only when
 * asked for (phases=true): a client of before reads every line that is
 * not the last as a step.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "rest_internal.h"

#define CHUNK (64 * 1024)

typedef struct {
    svc_job *job;
    rest_stream_kind kind;
    int phases;               /* the core's milestones too (work_line) */
    rest_waiter w;
    int ev_index;             /* events passed (the SSE id of the last) */
    long last_id;             /* SSE Last-Event-ID: skip ids <= last_id */
    api_buf pend;             /* formatted, not yet handed to MHD */
    size_t pend_off;
    int started, finished;
    int nphases;              /* the job's phase changes sent (work_lines) */
    double told;              /* the share of the last milestone sent */
    int ev_at_work;           /* ev_index when it was sent */
} stream;

int rest_stream_admit(rest_t *d, const svc_job *j, svc_error *p)
{
    const srv_config *cfg = d->cfg;
    int here = svc_followers(j), total = rest_waiter_followers(d),
        max_total = cfg->max_connections / 2;

    if (here >= SVC_FOLLOWERS_PER_JOB) {
        svc_error_set(p, SVC_P_BUSY, "job %s already has %d followers, "
                        "the most one job may have; poll GET /v1/jobs/%s "
                        "instead", svc_job_id(j), here, svc_job_id(j));
        return 0;
    }
    if (total >= max_total) {
        svc_error_set(p, SVC_P_BUSY, "%d event streams are open, the most "
                        "this daemon keeps (half of --max-connections %d)",
                        total, cfg->max_connections);
        return 0;
    }
    return 1;
}

/* The final ndjson line of a job (metrics and result URL, or the error). */
static cJSON *final_json(const svc_job *j)
{
    char url[96];
    svc_snap s;
    cJSON *o = cJSON_CreateObject();

    if (!o)
        return NULL;
    svc_job_snapshot(j, &s);
    cJSON_AddBoolToObject(o, "done", svc_job_status_terminal(s.status));
    cJSON_AddStringToObject(o, "job", s.id);
    cJSON_AddStringToObject(o, "status", svc_job_status_name(s.status));
    cJSON_AddNumberToObject(o, "steps", s.step);
    if (s.status == SVC_JOB_SUCCEEDED) {
        char *doc;
        size_t len;
        svc_error e;
        snprintf(url, sizeof url, "/v1/jobs/%s/result", s.id);
        cJSON_AddStringToObject(o, "result", url);
        snprintf(url, sizeof url, "/v1/jobs/%s/metrics", s.id);
        cJSON_AddStringToObject(o, "metrics_url", url);
        if (svc_job_metrics(j, &doc, &len, &e) == 0) {
            cJSON *m = cJSON_Parse(doc);
            if (m)
                cJSON_AddItemToObject(o, "metrics", m);
            free(doc);
        }
    } else {
        svc_error p = s.error;
        cJSON *e;
        if (!svc_job_status_terminal(s.status))
            svc_error_set(&p, SVC_P_DRAINING, "the daemon is shutting "
                            "down; job %s stays %s and runs after the "
                            "restart", s.id, svc_job_status_name(s.status));
        snprintf(url, sizeof url, "/v1/jobs/%s", s.id);
        e = rest_problem_json(&p, url, s.id);
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

/* One milestone line: {"step","phase","fraction"}. */
static void work_line(stream *s, int step, const char *phase, double fraction)
{
    char line[96];
    int n;

    /* the phases are the core's identifiers ([a-z]): no escaping */
    n = snprintf(line, sizeof line, "{\"step\":%d,\"phase\":\"%s\","
                 "\"fraction\":%.4f}", step, phase, fraction);
    if (n <= 0 || (size_t)n >= sizeof line)
        return;
    if (s->kind == SRV_STREAM_NDJSON) {
        api_buf_append(&s->pend, line, (size_t)n);
        api_buf_append(&s->pend, "\n", 1);
    } else {
        sse_event(&s->pend, "work", 0, line, (size_t)n);
    }
    s->told = fraction;
    s->ev_at_work = s->ev_index;
}

/* The milestones not sent yet, for a stream that asked for them: every
 * phase change of the run (kept with the job: none is missed, however
 * late the stream reads), then, while the job runs and no step was sent
 * since the last milestone, its share when it moved by a percent. */
static void work_lines(stream *s, const svc_snap *sn)
{
    svc_phase ph[SVC_PHASES_MAX];
    int k, n;

    if (!s->phases)
        return;
    n = svc_job_phases(s->job, s->nphases, ph, SVC_PHASES_MAX);
    for (k = 0; s->nphases < n && k < SVC_PHASES_MAX; k++, s->nphases++)
        work_line(s, ph[k].step, ph[k].phase, ph[k].fraction);
    if (k == 0 && sn->status == SVC_JOB_RUNNING && sn->phase[0] &&
        sn->fraction >= s->told + SVC_WORK_STEP && s->ev_index == s->ev_at_work)
        work_line(s, sn->step, sn->phase, sn->fraction);
}

/* Moves what is new into s->pend. Returns 1 when something was added (or
 * the stream ended), 0 when it must wait. The snapshot comes before the
 * events: the service adds every event before the job ends, so an ended
 * job and no event after its snapshot mean the stream is complete. */
static int fill(stream *s)
{
    svc_job *j = s->job;
    svc_snap sn;

    if (!s->started) {
        s->started = 1;
        if (s->kind == SRV_STREAM_SSE) {
            api_buf_append(&s->pend, "retry: 2000\n", 12);
            sse_json(&s->pend, "status", rest_job_json(j, NULL));
            return 1;
        }
    }
    svc_job_snapshot(j, &sn);
    while (s->pend.len < CHUNK) {
        char *ev, *line;
        size_t len;
        int n;

        if (svc_job_events(j, s->ev_index, CHUNK, &ev, &len, &n) != 0) {
            /* A shared store that cannot give the events now (Redis
             * just back): never the end without them; read again at the
             * next check of the clients. */
            if (s->pend.len > 0)
                break;
            rest_waiter_retry(&s->w);
            return 0;
        }
        if (n == 0)
            break;
        for (line = ev; line < ev + len;) {
            char *nl = memchr(line, '\n', (size_t)(ev + len - line));
            size_t k = nl ? (size_t)(nl - line) : (size_t)(ev + len - line);

            s->ev_index++;
            if (s->kind == SRV_STREAM_NDJSON) {
                api_buf_append(&s->pend, line, k);
                api_buf_append(&s->pend, "\n", 1);
            } else if (s->ev_index > s->last_id) {
                sse_event(&s->pend, "progress", s->ev_index, line, k);
            }
            line += k + 1;
        }
        free(ev);
    }
    if (s->pend.len == 0)
        work_lines(s, &sn);
    if (s->pend.len > 0)
        return 1;
    if (svc_job_status_terminal(sn.status) ||
        (sn.status == SVC_JOB_QUEUED && sn.draining) || sn.closing) {
        if (s->kind == SRV_STREAM_NDJSON) {
            cJSON *o = final_json(j);
            char *t = o ? cJSON_PrintUnformatted(o) : NULL;
            if (t) {
                api_buf_append(&s->pend, t, strlen(t));
                api_buf_append(&s->pend, "\n", 1);
            }
            free(t);
            cJSON_Delete(o);
        } else {
            sse_json(&s->pend, "done", rest_job_json(j, NULL));
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
        for (;;) {
            rest_waiter_arm(&s->w);
            if (rest_waiter_gone(&s->w))
                /* The client left while the stream slept (found by
                 * rest_http_check_clients): end it, freeing the
                 * connection. */
                return MHD_CONTENT_READER_END_WITH_ERROR;
            if (fill(s))
                break;
            /* Nothing new: sleep until the worker has more. */
            if (rest_waiter_sleep(&s->w))
                return 0;
        }
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

    rest_waiter_stop(&s->w);
    svc_job_unref(s->job);
    api_buf_free(&s->pend);
    free(s);
}

struct MHD_Response *rest_stream_response(rest_t *d, svc_job *j,
                                          rest_stream_kind kind, int phases,
                                          struct MHD_Connection *conn,
                                          long last_id)
{
    struct MHD_Response *r;
    stream *s = calloc(1, sizeof *s);

    if (!s)
        return NULL;
    s->job = svc_job_ref(j);
    s->kind = kind;
    s->phases = phases;
    s->last_id = last_id;
    api_buf_init(&s->pend, 0);
    if (rest_waiter_start(&s->w, d, j, conn, 1, 0) != 0) {
        svc_job_unref(s->job);
        free(s);
        return NULL;
    }
    r = MHD_create_response_from_callback(MHD_SIZE_UNKNOWN, CHUNK, reader, s,
                                          release);
    if (!r) {
        release(s);
        return NULL;
    }
    MHD_add_response_header(r, MHD_HTTP_HEADER_CONTENT_TYPE,
                            kind == SRV_STREAM_SSE ? "text/event-stream"
                                                   : "application/x-ndjson");
    MHD_add_response_header(r, MHD_HTTP_HEADER_CACHE_CONTROL, "no-cache");
    MHD_add_response_header(r, "X-Accel-Buffering", "no");
    MHD_add_response_header(r, "X-Job-Id", svc_job_id(j));
    return r;
}
