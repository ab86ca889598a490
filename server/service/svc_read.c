/* SPDX-License-Identifier: MIT */
/*
 * svc_read.c - the job service's readers (service.h): a job by its ID
 * (svc_job_get: the table's, or loaded from a shared store by
 * svc_shared.c), snapshots (with the parameters and the metrics document:
 * everything a door shows), the metrics, the progress events from a given
 * index on, and the result bytes. Every reader copies under the service
 * lock and reads the store outside it.
 */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "svc_internal.h"

static void snapshot_locked(const svc_job *j, svc_snap *s)
{
    const svc_t *sv = j->svc;
    double frac = 0;

    memset(s, 0, sizeof *s);
    snprintf(s->id, sizeof s->id, "%s", j->id);
    s->status = j->status;
    s->ready = j->ready;
    s->cancel_requested = j->cancel && j->cancel_reason == SVC_CANCEL_USER &&
                          j->status == SVC_JOB_RUNNING;
    s->recovered = j->recovered;
    s->step = j->step;
    s->t = j->t;
    s->dt = j->dt;
    s->energy = j->energy;
    s->volume = j->volume;
    s->steps_planned = j->steps_planned;
    s->time_planned = j->time_planned;
    s->cpu_s = j->cpu_used;
    s->cpu_threads_s = j->cpu_threads;
    s->cores = j->cores;
    if (j->status == SVC_JOB_SUCCEEDED)
        frac = 1;
    else if (j->work > 0)
        frac = j->work;
    else if (j->steps_planned > 0)
        frac = (double)j->step / j->steps_planned;
    else if (j->time_planned > 0)
        frac = j->t / j->time_planned;
    s->fraction = frac < 0 ? 0 : frac > 1 ? 1 : frac;
    if (j->status == SVC_JOB_RUNNING)
        snprintf(s->phase, sizeof s->phase, "%s", j->phase);
    s->created = j->created;
    s->started = j->started;
    s->finished = j->finished;
    snprintf(s->scheme, sizeof s->scheme, "%s", j->scheme);
    snprintf(s->in_format, sizeof s->in_format, "%s", j->in_format);
    snprintf(s->out_format, sizeof s->out_format, "%s", j->out_format);
    snprintf(s->filename, sizeof s->filename, "%s", j->filename);
    snprintf(s->result_name, sizeof s->result_name, "%s", j->result_name);
    s->result_len = j->result_len;
    s->nevents = j->nevents;
    s->error = j->err;
    s->draining = sv->draining;
    s->closing = sv->closing;
}

void svc_job_snapshot(const svc_job *j, svc_snap *s)
{
    pthread_mutex_lock(&j->svc->mu);
    snapshot_locked(j, s);
    pthread_mutex_unlock(&j->svc->mu);
}

int svc_job_document(const svc_job *j, svc_snap *s)
{
    svc_store *st = j->svc->store;
    size_t len;

    /* params_json is constant once the job is in the table */
    svc_job_snapshot(j, s);
    if (j->params_json && !(s->params = strdup(j->params_json)))
        return -1;
    /* A finished job's metrics are in the store only. */
    if (s->status == SVC_JOB_SUCCEEDED &&
        st->ops->get(st, s->id, "metrics.json", &s->metrics, &len) != 0)
        s->metrics = NULL;
    return 0;
}

void svc_snap_free(svc_snap *s)
{
    free(s->params);
    free(s->metrics);
    s->params = s->metrics = NULL;
}

/* Lock held: ENOTREADY or ENORESULT unless j succeeded. */
static int has_result_locked(const svc_job *j, const char *what,
                             svc_error *err)
{
    if (j->status == SVC_JOB_SUCCEEDED)
        return 1;
    if (svc_job_status_terminal(j->status))
        svc_error_set(err, SVC_P_NO_RESULT, "job %s %s and has no %s",
                      j->id, svc_job_status_name(j->status), what);
    else
        svc_error_set(err, SVC_P_NOT_READY, "job %s is %s (step %d of "
                      "%d)", j->id, svc_job_status_name(j->status), j->step,
                      j->steps_planned);
    return 0;
}

int svc_job_metrics(const svc_job *j, char **json, size_t *len,
                    svc_error *err)
{
    svc_store *st = j->svc->store;

    pthread_mutex_lock(&j->svc->mu);
    if (!has_result_locked(j, "metrics", err)) {
        pthread_mutex_unlock(&j->svc->mu);
        return -1;
    }
    pthread_mutex_unlock(&j->svc->mu);
    if (st->ops->get(st, j->id, "metrics.json", json, len) != 0) {
        svc_error_set(err, SVC_P_STORAGE, "metrics of job %s are missing",
                      j->id);
        return -1;
    }
    return 0;
}

/* How many of the events ending at ends[0..m) (m >= 1) fit in max_bytes
 * from byte a: at least one. */
static int events_fit(const size_t *ends, int m, size_t a, size_t max_bytes)
{
    int k;
    for (k = 1; k < m && ends[k] - a <= max_bytes; k++)
        ;
    return k;
}

/* Events of a finished job read back from the store (svc_job_events):
 * the ends of events from - 1 to from + EVENTS_BATCH from events.idx,
 * then the lines they span from events.ndjson. size and count: the
 * blobs' as the job recorded them; an index that disagrees is EIO. */
#define EVENTS_BATCH 1024
static int events_from_store(svc_store *st, const char *id, int from,
                             int count, size_t size, size_t max_bytes,
                             char **data, size_t *len, int *n)
{
    size_t ends[EVENTS_BATCH + 1], a, b;
    int m = count - from < EVENTS_BATCH ? count - from : EVENTS_BATCH,
        skip = from > 0, k;

    if (st->ops->get_at(st, id, "events.idx",
                        (size_t)(from - skip) * sizeof *ends, ends,
                        (size_t)(m + skip) * sizeof *ends) != 0)
        return -1;
    a = skip ? ends[0] : 0;
    k = events_fit(ends + skip, m, a, max_bytes);
    b = ends[skip + k - 1];
    if (!(a < b && b <= size)) {
        errno = EIO;
        return -1;
    }
    if (!(*data = malloc(b - a + 1)))
        return -1;
    if (st->ops->get_at(st, id, "events.ndjson", a, *data, b - a) != 0) {
        free(*data);
        *data = NULL;
        return -1;
    }
    (*data)[b - a] = '\0';
    *len = b - a;
    *n = k;
    return 0;
}

int svc_job_phases(const svc_job *j, int from, svc_phase *out, int n)
{
    int count, k;

    pthread_mutex_lock(&j->svc->mu);
    count = j->nphases;
    for (k = 0; from >= 0 && from + k < count && k < n; k++)
        out[k] = j->phases[from + k];
    pthread_mutex_unlock(&j->svc->mu);
    return count;
}

int svc_job_events(const svc_job *j, int from, size_t max_bytes, char **data,
                   size_t *len, int *n)
{
    size_t a, b, on_disk;
    int k, count;

    *data = NULL;
    *len = 0;
    *n = 0;
    pthread_mutex_lock(&j->svc->mu);
    if (from < 0)
        from = 0;
    count = j->nevents;
    on_disk = j->events_disk;
    if (from >= count) {
        pthread_mutex_unlock(&j->svc->mu);
        return 0;
    }
    if (on_disk) {
        pthread_mutex_unlock(&j->svc->mu);
        return events_from_store(j->svc->store, j->id, from, count, on_disk,
                                 max_bytes, data, len, n);
    }
    a = from > 0 ? j->event_end[from - 1] : 0;
    k = events_fit(j->event_end + from, count - from, a, max_bytes);
    b = j->event_end[from + k - 1];
    *data = malloc(b - a + 1);
    if (!*data) {
        pthread_mutex_unlock(&j->svc->mu);
        return -1;
    }
    memcpy(*data, j->events.data + a, b - a);
    (*data)[b - a] = '\0';
    pthread_mutex_unlock(&j->svc->mu);
    *len = b - a;
    *n = k;
    return 0;
}

/* A result whose size is not the one state.json records (0: spools from
 * before it did) is never served: ESTORAGE. */
static int result_damaged(const svc_job *j, size_t got, size_t want,
                          svc_error *err)
{
    if (want == 0 || got == want)
        return 0;
    svc_error_set(err, SVC_P_STORAGE, "the result of job %s on the "
                  "spool is damaged: %zu bytes, %zu recorded", j->id, got,
                  want);
    srv_logf(SRV_LOG_ERROR, "spool: %s", err->detail);
    return 1;
}

int svc_job_result(svc_job *j, unsigned flags, char **data, size_t *len,
                   svc_error *err)
{
    svc_store *st = j->svc->store;
    char name[32];
    size_t want;

    *data = NULL;
    pthread_mutex_lock(&j->svc->mu);
    if (!has_result_locked(j, "result", err)) {
        pthread_mutex_unlock(&j->svc->mu);
        return -1;
    }
    if ((flags & SVC_RESULT_TAKE) && j->result) {
        *data = j->result;
        *len = j->result_len;
        j->result = NULL;
    }
    snprintf(name, sizeof name, "%s", j->result_name);
    want = j->result_len;
    pthread_mutex_unlock(&j->svc->mu);
    if (!*data && st->ops->get(st, j->id, name, data, len) != 0) {
        svc_error_set(err, SVC_P_STORAGE, "the result of job %s is "
                      "missing from the spool", j->id);
        return -1;
    }
    if (result_damaged(j, *len, want, err)) {
        free(*data);
        *data = NULL;
        return -1;
    }
    return 0;
}

/* A blob of a succeeded job: a read-only descriptor when the store has
 * them, else its bytes. */
static int open_blob(const svc_job *j, const char *name, const char *what,
                     int *fd, char **data, size_t *size, svc_error *err)
{
    svc_store *st = j->svc->store;

    *fd = -1;
    *data = NULL;
    if (st->ops->open(st, j->id, name, fd, size) == 0)
        return 0;
    if (errno == ENOTSUP && st->ops->get(st, j->id, name, data, size) == 0)
        return 0;
    svc_error_set(err, SVC_P_STORAGE, "the %s of job %s is missing from the "
                  "spool: %s", what, j->id, strerror(errno));
    return -1;
}

int svc_job_result_open(const svc_job *j, int *fd, char **data, size_t *size,
                        svc_error *err)
{
    char name[32];
    size_t want;

    pthread_mutex_lock(&j->svc->mu);
    if (!has_result_locked(j, "result", err)) {
        pthread_mutex_unlock(&j->svc->mu);
        return -1;
    }
    snprintf(name, sizeof name, "%s", j->result_name);
    want = j->result_len;
    pthread_mutex_unlock(&j->svc->mu);
    if (open_blob(j, name, "result", fd, data, size, err) != 0)
        return -1;
    if (result_damaged(j, *size, want, err)) {
        if (*fd >= 0)
            close(*fd);
        free(*data);
        *fd = -1;
        *data = NULL;
        return -1;
    }
    return 0;
}

int svc_job_fields_open(const svc_job *j, int *fd, char **data, size_t *size,
                        svc_error *err)
{
    pthread_mutex_lock(&j->svc->mu);
    if (!has_result_locked(j, "fields", err)) {
        pthread_mutex_unlock(&j->svc->mu);
        return -1;
    }
    pthread_mutex_unlock(&j->svc->mu);
    /* keep_fields is constant once the job is in the table */
    if (!j->keep_fields) {
        svc_error_set(err, SVC_P_NO_RESULT, "job %s was submitted without "
                      "fields=true and has no fields", j->id);
        return -1;
    }
    return open_blob(j, SVC_FIELDS_FILE, "fields", fd, data, size, err);
}

void svc_job_release_result(svc_job *j)
{
    pthread_mutex_lock(&j->svc->mu);
    j->keep_result = 0;
    free(j->result);
    j->result = NULL;
    pthread_mutex_unlock(&j->svc->mu);
}

/* ------------------------------------------------------------------ lookup */

svc_job *svc_job_get(svc_t *s, const char *id)
{
    svc_job *j;

    if (s->store->ops->shared)
        return svc__shared_get(s, id);
    pthread_mutex_lock(&s->mu);
    j = svc__find_locked(s, id);
    if (j)
        j->refs++;
    pthread_mutex_unlock(&s->mu);
    if (!j)
        errno = ENOENT;
    return j;
}

svc_job *svc_job_find(svc_t *s, const char *id, svc_error *err)
{
    svc_job *j = svc_job_get(s, id);
    int e = errno;

    if (j)
        return j;
    if (e == ENOENT) {
        svc_error_set(err, SVC_P_NOT_FOUND, "no job with ID %.64s (never "
                      "existed, deleted, or expired)", id);
    } else if (e == ENOMEM) {
        svc_error_set(err, SVC_P_NOMEM, "out of memory reading job %.64s", id);
    } else if (e == EBADMSG) {
        svc_error_set(err, SVC_P_STORAGE, "job %.64s is damaged in the store "
                      "(its state.json or request.json does not parse)", id);
    } else {
        /* a shared store down: it cannot say the job does not exist */
        svc_error_set(err, SVC_P_SPOOL_UNREADY, "the store cannot read job "
                      "%.64s now: %s", id, strerror(e));
        err->retry_after = 5;
    }
    return NULL;
}
