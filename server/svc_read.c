/*
 * svc_read.c - the job service's readers (service.h): snapshots, the job
 * as JSON, the parameters, the metrics document, the progress events from
 * a given index on, and the result bytes. Every reader copies under the
 * service lock and does its disk I/O (the spool's metrics, result and, for
 * a finished job, events files) outside it.
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
    s->created = j->created;
    s->started = j->started;
    s->finished = j->finished;
    snprintf(s->scheme, sizeof s->scheme, "%s", j->scheme);
    snprintf(s->in_format, sizeof s->in_format, "%s", j->in_format);
    snprintf(s->out_format, sizeof s->out_format, "%s", j->out_format);
    snprintf(s->filename, sizeof s->filename, "%s", j->rec.filename);
    snprintf(s->result_name, sizeof s->result_name, "%s", j->result_name);
    s->result_len = j->result_len;
    s->nevents = j->nevents;
    s->error = j->err;
    s->draining = svc__S.draining;
    s->closing = svc__S.closing;
}

void svc_job_snapshot(const svc_job *j, svc_snap *s)
{
    svc__lock();
    snapshot_locked(j, s);
    svc__unlock();
}

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

cJSON *svc_job_json(const svc_job *j, svc_snap *snap)
{
    cJSON *o = cJSON_CreateObject(), *p;
    char *params = NULL, *metrics = NULL;
    svc_snap s;

    if (!o)
        return NULL;
    svc__lock();
    snapshot_locked(j, &s);
    if (j->params_json)
        params = strdup(j->params_json);
    svc__unlock();
    if (snap)
        *snap = s;
    /* A finished job's metrics are on disk only (its memory is disk's). */
    if (s.status == SVC_JOB_SUCCEEDED) {
        size_t len;
        if (srv_spool_read(svc__S.cfg.spool, s.id, "metrics.json", &metrics,
                           &len) != 0)
            metrics = NULL;
    }

    cJSON_AddStringToObject(o, "id", s.id);
    cJSON_AddStringToObject(o, "status", svc_job_status_name(s.status));
    add_time(o, "created", s.created);
    add_time(o, "started", s.started);
    add_time(o, "finished", s.finished);
    p = cJSON_AddObjectToObject(o, "progress");
    if (p) {
        double frac = 0;
        cJSON_AddNumberToObject(p, "step", s.step);
        if (s.steps_planned > 0) {
            cJSON_AddNumberToObject(p, "steps", s.steps_planned);
            frac = (double)s.step / s.steps_planned;
        } else {
            cJSON_AddNullToObject(p, "steps");
            if (s.time_planned > 0)
                frac = s.t / s.time_planned;
        }
        if (s.status == SVC_JOB_SUCCEEDED)
            frac = 1;
        /* Before the first step there is nothing to report. */
        add_num(p, "t", s.step > 0 ? s.t : NAN);
        add_num(p, "dt", s.step > 0 ? s.dt : NAN);
        add_num(p, "energy", s.step > 0 ? s.energy : NAN);
        add_num(p, "volume", s.step > 0 ? s.volume : NAN);
        cJSON_AddNumberToObject(p, "fraction", frac < 0 ? 0 : frac > 1 ? 1 : frac);
    }
    if (s.cancel_requested)
        cJSON_AddBoolToObject(o, "cancel_requested", 1);
    if (params) {
        cJSON *pj = cJSON_Parse(params);
        if (pj)
            cJSON_AddItemToObject(o, "params", pj);
    }
    if (s.in_format[0])
        cJSON_AddStringToObject(o, "input_format", s.in_format);
    if (metrics) {
        cJSON *m = cJSON_Parse(metrics);
        if (m)
            cJSON_AddItemToObject(o, "metrics", m);
    }
    free(params);
    free(metrics);
    return o;
}

char *svc_job_params(const svc_job *j)
{
    char *s;
    svc__lock();
    s = j->params_json ? strdup(j->params_json) : NULL;
    svc__unlock();
    return s;
}

/* Lock held: ENOTREADY or ENORESULT unless j succeeded. */
static int has_result_locked(const svc_job *j, const char *what,
                             svc_error *err)
{
    if (j->status == SVC_JOB_SUCCEEDED)
        return 1;
    if (svc_job_status_terminal(j->status))
        svc_error_set(err, SVC_ENORESULT, NULL, "job %s %s and has no %s",
                      j->id, svc_job_status_name(j->status), what);
    else
        svc_error_set(err, SVC_ENOTREADY, NULL, "job %s is %s (step %d of "
                      "%d)", j->id, svc_job_status_name(j->status), j->step,
                      j->steps_planned);
    return 0;
}

int svc_job_metrics(const svc_job *j, char **json, size_t *len,
                    svc_error *err)
{
    svc__lock();
    if (!has_result_locked(j, "metrics", err)) {
        svc__unlock();
        return -1;
    }
    svc__unlock();
    if (srv_spool_read(svc__S.cfg.spool, j->id, "metrics.json", json, len) != 0) {
        svc_error_set(err, SVC_ESTORAGE, "EIO", "metrics of job %s are missing",
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

/* Events of a finished job read back from the spool (svc_job_events):
 * the ends of events from - 1 to from + EVENTS_BATCH from events.idx,
 * then the lines they span from events.ndjson. size and count: the
 * files' as the job recorded them; an index that disagrees is EIO. */
#define EVENTS_BATCH 1024
static int events_from_spool(const char *id, int from, int count,
                             size_t size, size_t max_bytes, char **data,
                             size_t *len, int *n)
{
    size_t ends[EVENTS_BATCH + 1], a, b;
    int m = count - from < EVENTS_BATCH ? count - from : EVENTS_BATCH,
        skip = from > 0, k;

    if (srv_spool_read_at(svc__S.cfg.spool, id, "events.idx",
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
    if (srv_spool_read_at(svc__S.cfg.spool, id, "events.ndjson", a, *data,
                          b - a) != 0) {
        free(*data);
        *data = NULL;
        return -1;
    }
    (*data)[b - a] = '\0';
    *len = b - a;
    *n = k;
    return 0;
}

int svc_job_events(const svc_job *j, int from, size_t max_bytes, char **data,
                   size_t *len, int *n)
{
    size_t a, b, on_disk;
    int k, count;

    *data = NULL;
    *len = 0;
    *n = 0;
    svc__lock();
    if (from < 0)
        from = 0;
    count = j->nevents;
    on_disk = j->events_disk;
    if (from >= count) {
        svc__unlock();
        return 0;
    }
    if (on_disk) {
        svc__unlock();
        return events_from_spool(j->id, from, count, on_disk, max_bytes, data,
                                 len, n);
    }
    a = from > 0 ? j->event_end[from - 1] : 0;
    k = events_fit(j->event_end + from, count - from, a, max_bytes);
    b = j->event_end[from + k - 1];
    *data = malloc(b - a + 1);
    if (!*data) {
        svc__unlock();
        return -1;
    }
    memcpy(*data, j->events.data + a, b - a);
    (*data)[b - a] = '\0';
    svc__unlock();
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
    svc_error_set(err, SVC_ESTORAGE, "EIO", "the result of job %s on the "
                  "spool is damaged: %zu bytes, %zu recorded", j->id, got,
                  want);
    srv_logf(SRV_LOG_ERROR, "spool: %s", err->detail);
    return 1;
}

int svc_job_result(svc_job *j, unsigned flags, char **data, size_t *len,
                   svc_error *err)
{
    char name[32];
    size_t want;

    *data = NULL;
    svc__lock();
    if (!has_result_locked(j, "result", err)) {
        svc__unlock();
        return -1;
    }
    if ((flags & SVC_RESULT_TAKE) && j->result) {
        *data = j->result;
        *len = j->result_len;
        j->result = NULL;
    }
    snprintf(name, sizeof name, "%s", j->result_name);
    want = j->result_len;
    svc__unlock();
    if (!*data &&
        srv_spool_read(svc__S.cfg.spool, j->id, name, data, len) != 0) {
        svc_error_set(err, SVC_ESTORAGE, "EIO", "the result of job %s is "
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

/* A file of a succeeded job's directory opened read-only, and its size. */
static int open_job_file(const svc_job *j, const char *name, const char *what,
                         int *fd, size_t *size, svc_error *err)
{
    char path[1400];
    struct stat sb;

    if (srv_spool_path(path, sizeof path, svc__S.cfg.spool, j->id, name) != 0 ||
        (*fd = open(path, O_RDONLY)) < 0) {
        svc_error_set(err, SVC_ESTORAGE, "EIO", "the %s of job %s is "
                      "missing from the spool", what, j->id);
        return -1;
    }
    if (fstat(*fd, &sb) != 0) {
        svc_error_set(err, SVC_ESTORAGE, "EIO", "the %s of job %s: %s",
                      what, j->id, strerror(errno));
        close(*fd);
        *fd = -1;
        return -1;
    }
    *size = (size_t)sb.st_size;
    return 0;
}

int svc_job_result_open(const svc_job *j, int *fd, size_t *size,
                        svc_error *err)
{
    char name[32];
    size_t want;

    svc__lock();
    if (!has_result_locked(j, "result", err)) {
        svc__unlock();
        return -1;
    }
    snprintf(name, sizeof name, "%s", j->result_name);
    want = j->result_len;
    svc__unlock();
    if (open_job_file(j, name, "result", fd, size, err) != 0)
        return -1;
    if (result_damaged(j, *size, want, err)) {
        close(*fd);
        *fd = -1;
        return -1;
    }
    return 0;
}

int svc_job_fields_open(const svc_job *j, int *fd, size_t *size,
                        svc_error *err)
{
    svc_error e;
    int asked = 0;

    svc__lock();
    if (!has_result_locked(j, "fields", err)) {
        svc__unlock();
        return -1;
    }
    /* the record is constant once submitted; a bad value was refused */
    svc__unlock();
    if (svc_record_fields(&j->rec, &asked, &e) != 0 || !asked) {
        svc_error_set(err, SVC_ENORESULT, NULL, "job %s was submitted without "
                      "fields=true and has no fields", j->id);
        return -1;
    }
    return open_job_file(j, SVC_FIELDS_FILE, "fields", fd, size, err);
}

void svc_job_release_result(svc_job *j)
{
    svc__lock();
    j->keep_result = 0;
    free(j->result);
    j->result = NULL;
    svc__unlock();
}
