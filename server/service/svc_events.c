/* SPDX-License-Identifier: MIT */
/*
 * svc_events.c - a job's progress events: the ndjson lines of its run,
 * kept in memory (and counted by admission) while it runs, then written
 * to the store at its end (events.ndjson and events.idx) and dropped from
 * memory; svc_job_events (svc_read.c) reads them back from either. Only
 * the job's worker appends to them or frees them (svc_job.c's hooks, and
 * svc_shared.c's lines of another replica's run under the lock).
 */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "svc_internal.h"

/* Lock held: its progress runs again from step 1; the events it put in
 * the store are put again at its end (uncounted till then). */
void svc__events_reset_locked(svc_job *j)
{
    if (j->events_disk) {
        size_t sub = j->events_disk + (size_t)j->nevents * sizeof(size_t);
        j->disk_bytes -= sub;
        if (j->in_table)
            j->svc->disk_bytes -= sub;
        j->events_disk = 0;
    }
    api_buf_free(&j->events);
    api_buf_init(&j->events, SVC_EVENTS_MAX);
    free(j->event_end);
    j->event_end = NULL;
    j->event_cap = 0;
    j->nevents = 0;
}

/* The job's events as they are now (only its worker appends). */
int svc__events_now(svc_job *j, const char **data, size_t *len,
                      const size_t **ends)
{
    int n;

    pthread_mutex_lock(&j->svc->mu);
    *data = j->events.data;
    *len = j->events.len;
    *ends = j->event_end;
    n = j->nevents;
    pthread_mutex_unlock(&j->svc->mu);
    return n;
}

/* The events written (ok: their len bytes and n ends) or lost: out of
 * memory either way. */
void svc__events_done(svc_job *j, int ok, size_t len, int n)
{
    svc_t *s = j->svc;

    pthread_mutex_lock(&s->mu);
    api_buf_free(&j->events);
    api_buf_init(&j->events, SVC_EVENTS_MAX);
    free(j->event_end);
    j->event_end = NULL;
    j->event_cap = 0;
    if (ok && n > 0) {
        size_t add = len + (size_t)n * sizeof *j->event_end;
        j->events_disk = len;
        j->disk_bytes += add;
        if (j->in_table)
            s->disk_bytes += add;
    } else {
        j->nevents = 0;
    }
    pthread_mutex_unlock(&s->mu);
}

/* When the run is over, before its outcome is published: its progress
 * events go to the store (events.ndjson and events.idx, not durable:
 * nothing depends on them after a crash) and out of memory, where
 * admission no longer counts them; svc_job_events reads them back. A
 * store that takes no write loses them (followers then see the outcome
 * alone). Only the job's worker appends to or frees them, so they are
 * written outside the lock. */
void svc__events_to_store(svc_job *j)
{
    svc_store *st = j->svc->store;
    const char *data;
    const size_t *ends;
    size_t len;
    int n = svc__events_now(j, &data, &len, &ends), ok;

    if (n == 0)
        return;
    ok = st->ops->put(st, j->id, "events.ndjson", data, len, 0) == 0 &&
         st->ops->put(st, j->id, "events.idx", ends, (size_t)n * sizeof *ends,
                      0) == 0;
    if (!ok)
        srv_logf(SRV_LOG_WARN, "job %s: its %d progress events could not be "
                 "written to the spool (%s); late followers get its outcome "
                 "alone", j->id, n, strerror(errno));
    svc__events_done(j, ok, len, n);
}

static void fmt_num(char *buf, size_t size, double v)
{
    if (isfinite(v))
        snprintf(buf, size, "%.17g", v);
    else
        snprintf(buf, size, "null");
}

int svc__event_line(const api_job_step *st, char line[SVC_EVENT_LINE])
{
    char a[32], b[32], e[32], v[32];

    fmt_num(a, sizeof a, st->t);
    fmt_num(b, sizeof b, st->dt);
    fmt_num(e, sizeof e, st->energy);
    fmt_num(v, sizeof v, st->volume);
    return snprintf(line, SVC_EVENT_LINE,
                    "{\"step\":%d,\"t\":%s,\"dt\":%s,\"energy\":%s,"
                    "\"volume\":%s}\n", st->step, a, b, e, v);
}

/* Lock held: one more ndjson line in the job's event log (dropped when
 * the log is full or memory is short: the stream then skips it). */
void svc__event_add_locked(svc_job *j, const char *line, size_t n)
{
    if (j->nevents == j->event_cap) {
        int cap = j->event_cap ? 2 * j->event_cap : 256;
        size_t *p = realloc(j->event_end, (size_t)cap * sizeof *p);
        if (!p)
            return;
        j->event_end = p;
        j->event_cap = cap;
    }
    if (api_buf_append(&j->events, line, n) == MCF_OK)
        j->event_end[j->nevents++] = j->events.len;
}
