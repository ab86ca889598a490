/*
 * jobs.c - the job system of mcfd: table, bounded queue, worker pool, the
 * job runner, and crash recovery from the spool.
 *
 * A job is accepted only after its input, request and state are on disk
 * (spool.c), so a 202 or a started synchronous smoothing survives kill -9:
 * at the next start, queued and interrupted jobs go back to the queue in
 * their original order with their IDs, finished ones are served again
 * until their TTL runs out.
 *
 * Workers are plain pthreads. Only they decode, smooth and encode; MHD's
 * threads just move bytes. One mutex (S.mu) guards the table, the queue
 * and every mutable job field; it is never held across mesh work or disk
 * I/O. Connections waiting on a job (srv_waiter) are resumed by whoever
 * changes the job, under the lock, so a waiter is never resumed before
 * it was suspended. Lock order: S.mu, then MHD's internal mutexes.
 *
 * Capacity: a submission is accepted while the jobs waiting for a worker
 * stay within --queue plus the idle workers; beyond that the client gets
 * 503 with Retry-After, before its body is read when possible.
 */
#include <errno.h>
#include <fcntl.h>
#include <sys/socket.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "srv.h"
#include "admit.h"
#include "sandbox.h"

#define NBUCKETS 4096
#define EVENTS_MAX ((size_t)16 << 20)   /* ndjson progress kept per job */
#define RESULT_MAX ((size_t)4 << 30)    /* an encoded result */

static struct {
    pthread_mutex_t mu;
    pthread_cond_t work;      /* workers: a job was queued, or stop */
    pthread_cond_t idle;      /* drain: a worker finished its job */
    const srv_config *cfg;
    srv_job *buckets[NBUCKETS];
    int njobs;
    srv_job *qhead, *qtail;
    int qlen, reserved, busy;
    size_t disk_bytes;        /* sum of disk_bytes of the jobs in the table */
    int draining, stopping;
    int closing;              /* waiters must answer now, never suspend */
    pthread_t *threads;
    int nthreads;
    int urandom;
    uint64_t counter;
} S = {.mu = PTHREAD_MUTEX_INITIALIZER,
       .work = PTHREAD_COND_INITIALIZER,
       .idle = PTHREAD_COND_INITIALIZER,
       .urandom = -1};

static const char *const status_names[] = {"queued", "running", "succeeded",
                                           "failed", "canceled"};

const char *srv_job_status_name(srv_job_status s)
{
    return (unsigned)s < 5 ? status_names[s] : "unknown";
}

static int status_from_name(const char *s, srv_job_status *out)
{
    int i;
    for (i = 0; i < 5; i++)
        if (strcmp(s, status_names[i]) == 0) {
            *out = (srv_job_status)i;
            return 0;
        }
    return -1;
}

static int is_terminal(srv_job_status s)
{
    return s == SRV_JOB_SUCCEEDED || s == SRV_JOB_FAILED ||
           s == SRV_JOB_CANCELED;
}

void srv_lock(void)
{
    pthread_mutex_lock(&S.mu);
}

void srv_unlock(void)
{
    pthread_mutex_unlock(&S.mu);
}

const srv_config *srv_jobs_config(void)
{
    return S.cfg;
}

/* ------------------------------------------------------------------ records */

void srv_record_free(srv_record *r)
{
    free(r->query);
    free(r->params_json);
    cJSON_Delete(r->fields);
    memset(r, 0, sizeof *r);
}

mcf_status srv_record_params(const srv_record *r, const api_limits *lim,
                             api_params *p, mcf_error *err)
{
    static const char *const ignore[] = {"stream", NULL};
    mcf_status rc = MCF_OK;
    const cJSON *f;

    api_params_init(p);
    if (r->params_json &&
        (rc = api_params_parse_json(p, r->params_json, strlen(r->params_json),
                                    lim, err)) != MCF_OK)
        goto fail;
    cJSON_ArrayForEach(f, r->fields) {
        const char *k = cJSON_GetStringValue(cJSON_GetArrayItem(f, 0));
        const char *v = cJSON_GetStringValue(cJSON_GetArrayItem(f, 1));
        if (k && v && (rc = api_params_set(p, k, v, lim, err)) != MCF_OK)
            goto fail;
    }
    if (r->query && r->query[0] &&
        (rc = api_params_parse_query(p, r->query, ignore, lim, err)) != MCF_OK)
        goto fail;
    return MCF_OK;
fail:
    api_params_free(p);
    return rc;
}

static cJSON *record_json(const srv_job *j)
{
    cJSON *o = cJSON_CreateObject();
    cJSON *fields;

    if (!o)
        return NULL;
    cJSON_AddStringToObject(o, "id", j->id);
    if (j->rec.query)
        cJSON_AddStringToObject(o, "query", j->rec.query);
    if (j->rec.params_json)
        cJSON_AddStringToObject(o, "params", j->rec.params_json);
    fields = j->rec.fields ? cJSON_Duplicate(j->rec.fields, 1)
                           : cJSON_CreateArray();
    if (fields)
        cJSON_AddItemToObject(o, "fields", fields);
    cJSON_AddStringToObject(o, "filename", j->rec.filename);
    cJSON_AddBoolToObject(o, "target", j->rec.has_target);
    cJSON_AddNumberToObject(o, "created", j->created);
    cJSON_AddNumberToObject(o, "memory_estimate", j->mem_estimate);
    return o;
}

static int record_from_json(srv_record *r, const cJSON *o)
{
    const cJSON *q = cJSON_GetObjectItemCaseSensitive(o, "query");
    const cJSON *p = cJSON_GetObjectItemCaseSensitive(o, "params");
    const cJSON *f = cJSON_GetObjectItemCaseSensitive(o, "fields");
    const char *fn = cJSON_GetStringValue(
        cJSON_GetObjectItemCaseSensitive(o, "filename"));

    memset(r, 0, sizeof *r);
    if ((cJSON_IsString(q) && !(r->query = strdup(q->valuestring))) ||
        (cJSON_IsString(p) && !(r->params_json = strdup(p->valuestring))) ||
        (cJSON_IsArray(f) && !(r->fields = cJSON_Duplicate(f, 1)))) {
        srv_record_free(r);
        return -1;
    }
    snprintf(r->filename, sizeof r->filename, "%s", fn ? fn : "mesh");
    r->has_target = cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(o, "target"));
    return 0;
}

/* ------------------------------------------------------------------ jobs */

static srv_job *job_new(void)
{
    srv_job *j = calloc(1, sizeof *j);
    if (!j)
        return NULL;
    j->refs = 1;
    api_buf_init(&j->events, EVENTS_MAX);
    snprintf(j->scheme, sizeof j->scheme, "unknown");
    return j;
}

static void job_free(srv_job *j)
{
    srv_record_free(&j->rec);
    free(j->input);
    free(j->target);
    free(j->params_json);
    free(j->metrics_json);
    free(j->result);
    api_buf_free(&j->events);
    free(j);
}

/* Lock held. Frees the job when the last reference goes. */
static void unref_locked(srv_job *j)
{
    if (--j->refs == 0)
        job_free(j);
}

void srv_job_unref(srv_job *j)
{
    if (!j)
        return;
    srv_lock();
    unref_locked(j);
    srv_unlock();
}

static unsigned bucket_of(const char *id)
{
    uint32_t h = 2166136261u;
    for (; *id; id++)
        h = (h ^ (unsigned char)*id) * 16777619u;
    return h % NBUCKETS;
}

static srv_job *find_locked(const char *id)
{
    srv_job *j;
    for (j = S.buckets[bucket_of(id)]; j; j = j->hnext)
        if (strcmp(j->id, id) == 0)
            return j;
    return NULL;
}

static void table_insert(srv_job *j)
{
    unsigned b = bucket_of(j->id);
    j->hnext = S.buckets[b];
    S.buckets[b] = j;
    j->in_table = 1;
    S.njobs++;
    S.disk_bytes += j->disk_bytes;
}

/* Removes j from the table and drops the table's reference. */
static void table_remove(srv_job *j)
{
    srv_job **pp = &S.buckets[bucket_of(j->id)];
    while (*pp && *pp != j)
        pp = &(*pp)->hnext;
    if (*pp) {
        *pp = j->hnext;
        j->in_table = 0;
        S.njobs--;
        S.disk_bytes -= j->disk_bytes;
        unref_locked(j);
    }
}

/* Lock held: puts back a job whose spool removal failed (the caller's
 * reference becomes the table's), unless its ID came back meanwhile. */
static void table_restore(srv_job *j)
{
    if (!j->in_table && !find_locked(j->id))
        table_insert(j);
    else
        unref_locked(j);
}

static void queue_push(srv_job *j)
{
    j->qnext = NULL;
    if (S.qtail)
        S.qtail->qnext = j;
    else
        S.qhead = j;
    S.qtail = j;
    S.qlen++;
}

static srv_job *queue_pop(void)
{
    srv_job *j = S.qhead;
    if (j) {
        S.qhead = j->qnext;
        if (!S.qhead)
            S.qtail = NULL;
        j->qnext = NULL;
        S.qlen--;
    }
    return j;
}

static int queue_remove(srv_job *j)
{
    srv_job *prev = NULL, *q;
    for (q = S.qhead; q; prev = q, q = q->qnext)
        if (q == j) {
            if (prev)
                prev->qnext = j->qnext;
            else
                S.qhead = j->qnext;
            if (S.qtail == j)
                S.qtail = prev;
            j->qnext = NULL;
            S.qlen--;
            return 1;
        }
    return 0;
}

srv_job *srv_jobs_get(const char *id)
{
    srv_job *j;
    srv_lock();
    j = find_locked(id);
    if (j)
        j->refs++;
    srv_unlock();
    return j;
}

/* 128 bits from /dev/urandom; if that ever fails, a splitmix64 of the
 * clock, pid and a counter (unique, merely not unguessable). */
static void new_id(char *out)
{
    unsigned char b[16];
    size_t got = 0;
    int i;

    while (S.urandom >= 0 && got < sizeof b) {
        ssize_t r = read(S.urandom, b + got, sizeof b - got);
        if (r < 0 && errno == EINTR)
            continue;
        if (r <= 0)
            break;
        got += (size_t)r;
    }
    if (got < sizeof b) {
        uint64_t x = (uint64_t)(srv_wall() * 1e9) ^ ((uint64_t)getpid() << 32);
        for (i = 0; i < 16; i += 8) {
            uint64_t z = x + (++S.counter) * 0x9e3779b97f4a7c15ull;
            z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
            z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
            z ^= z >> 31;
            memcpy(b + i, &z, 8);
        }
    }
    for (i = 0; i < 16; i++)
        snprintf(out + 2 * i, 3, "%02x", b[i]);
}

/* ------------------------------------------------------------------ waiters */

void srv_waiter_link(srv_job *j, srv_waiter *w)
{
    if (w->linked)
        return;
    w->prev = NULL;
    w->next = j->waiters;
    if (j->waiters)
        j->waiters->prev = w;
    j->waiters = w;
    w->linked = 1;
}

void srv_waiter_unlink(srv_job *j, srv_waiter *w)
{
    if (!w->linked)
        return;
    if (w->prev)
        w->prev->next = w->next;
    else
        j->waiters = w->next;
    if (w->next)
        w->next->prev = w->prev;
    w->prev = w->next = NULL;
    w->linked = 0;
}

void srv_waiter_suspend(srv_waiter *w)
{
    w->suspended = 1;
    MHD_suspend_connection(w->conn);
}

void srv_job_wake(srv_job *j, int progress_only)
{
    srv_waiter *w;
    for (w = j->waiters; w; w = w->next)
        if (w->suspended && (!progress_only || w->want_events)) {
            w->suspended = 0;
            MHD_resume_connection(w->conn);
        }
}

void srv_jobs_resume_all(void)
{
    int b;
    srv_job *j;

    srv_lock();
    S.closing = 1;
    for (b = 0; b < NBUCKETS; b++)
        for (j = S.buckets[b]; j; j = j->hnext)
            srv_job_wake(j, 0);
    srv_unlock();
}

/* ------------------------------------------------------------------ JSON */

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

cJSON *srv_job_json(const srv_job *j)
{
    char link[96];
    cJSON *o = cJSON_CreateObject(), *p, *l;

    if (!o)
        return NULL;
    cJSON_AddStringToObject(o, "id", j->id);
    cJSON_AddStringToObject(o, "status", srv_job_status_name(j->status));
    add_time(o, "created", j->created);
    add_time(o, "started", j->started);
    add_time(o, "finished", j->finished);
    p = cJSON_AddObjectToObject(o, "progress");
    if (p) {
        double frac = 0;
        cJSON_AddNumberToObject(p, "step", j->step);
        if (j->steps_planned > 0) {
            cJSON_AddNumberToObject(p, "steps", j->steps_planned);
            frac = (double)j->step / j->steps_planned;
        } else {
            cJSON_AddNullToObject(p, "steps");
            if (j->time_planned > 0)
                frac = j->t / j->time_planned;
        }
        if (j->status == SRV_JOB_SUCCEEDED)
            frac = 1;
        /* Before the first step there is nothing to report. */
        add_num(p, "t", j->step > 0 ? j->t : NAN);
        add_num(p, "dt", j->step > 0 ? j->dt : NAN);
        add_num(p, "energy", j->step > 0 ? j->energy : NAN);
        add_num(p, "volume", j->step > 0 ? j->volume : NAN);
        cJSON_AddNumberToObject(p, "fraction", frac < 0 ? 0 : frac > 1 ? 1 : frac);
    }
    if (j->cancel && j->cancel_reason == SRV_CANCEL_USER &&
        j->status == SRV_JOB_RUNNING)
        cJSON_AddBoolToObject(o, "cancel_requested", 1);
    if (j->params_json) {
        cJSON *pj = cJSON_Parse(j->params_json);
        if (pj)
            cJSON_AddItemToObject(o, "params", pj);
    }
    if (j->in_format[0])
        cJSON_AddStringToObject(o, "input_format", j->in_format);
    if (j->status == SRV_JOB_SUCCEEDED && j->metrics_json) {
        cJSON *m = cJSON_Parse(j->metrics_json);
        if (m)
            cJSON_AddItemToObject(o, "metrics", m);
    }
    if (j->status == SRV_JOB_FAILED || j->status == SRV_JOB_CANCELED) {
        snprintf(link, sizeof link, "/v1/jobs/%s", j->id);
        cJSON *e = srv_problem_json(&j->err, link, j->id);
        if (e)
            cJSON_AddItemToObject(o, "error", e);
    }
    l = cJSON_AddObjectToObject(o, "links");
    if (l) {
        snprintf(link, sizeof link, "/v1/jobs/%s", j->id);
        cJSON_AddStringToObject(l, "self", link);
        snprintf(link, sizeof link, "/v1/jobs/%s/result", j->id);
        cJSON_AddStringToObject(l, "result", link);
        snprintf(link, sizeof link, "/v1/jobs/%s/metrics", j->id);
        cJSON_AddStringToObject(l, "metrics", link);
        snprintf(link, sizeof link, "/v1/jobs/%s/events", j->id);
        cJSON_AddStringToObject(l, "events", link);
    }
    return o;
}

/* state.json: everything needed to serve the job after a restart. */
static char *state_json(const srv_job *j)
{
    char *s;
    cJSON *o = cJSON_CreateObject();

    if (!o)
        return NULL;
    cJSON_AddStringToObject(o, "id", j->id);
    cJSON_AddStringToObject(o, "status", srv_job_status_name(j->status));
    cJSON_AddNumberToObject(o, "created", j->created);
    cJSON_AddNumberToObject(o, "started", j->started);
    cJSON_AddNumberToObject(o, "finished", j->finished);
    cJSON_AddStringToObject(o, "scheme", j->scheme);
    cJSON_AddNumberToObject(o, "steps_planned", j->steps_planned);
    cJSON_AddNumberToObject(o, "time_planned", j->time_planned);
    cJSON_AddNumberToObject(o, "step", j->step);
    add_num(o, "t", j->t);
    cJSON_AddStringToObject(o, "in_format", j->in_format);
    cJSON_AddStringToObject(o, "out_format", j->out_format);
    cJSON_AddStringToObject(o, "result", j->result_name);
    /* A cancel asked of a running job holds across a restart. */
    if (!is_terminal(j->status) && j->cancel &&
        (j->cancel_reason == SRV_CANCEL_USER ||
         j->cancel_reason == SRV_CANCEL_CLIENT))
        cJSON_AddStringToObject(o, "cancel_requested",
                                j->cancel_reason == SRV_CANCEL_USER ? "user"
                                                                    : "client");
    cJSON_AddNumberToObject(o, "result_bytes", (double)j->result_len);
    if (j->params_json)
        cJSON_AddStringToObject(o, "params", j->params_json);
    if (j->status == SRV_JOB_FAILED || j->status == SRV_JOB_CANCELED) {
        cJSON *e = cJSON_AddObjectToObject(o, "error");
        if (e) {
            cJSON_AddNumberToObject(e, "http", j->err.http);
            cJSON_AddStringToObject(e, "code", j->err.code);
            cJSON_AddStringToObject(e, "detail", j->err.detail);
        }
    }
    s = cJSON_PrintUnformatted(o);
    cJSON_Delete(o);
    return s;
}

/* Writers of state.json, one at a time: a snapshot and its write go
 * together, so the last snapshot taken is the last written (a DELETE and
 * the worker's outcome raced, and the older one could land last). Taken
 * before the job lock; held across the write, never by MHD's threads for
 * long (one small file). */
static pthread_mutex_t g_state_mu = PTHREAD_MUTEX_INITIALIZER;

/* Snapshot under the lock, write outside it. */
static int write_state(srv_job *j, int durable)
{
    char *s;
    int rc;

    pthread_mutex_lock(&g_state_mu);
    srv_lock();
    s = state_json(j);
    srv_unlock();
    if (!s) {
        pthread_mutex_unlock(&g_state_mu);
        return -1;
    }
    rc = srv_spool_write(S.cfg->spool, j->id, "state.json", s, strlen(s),
                         durable);
    pthread_mutex_unlock(&g_state_mu);
    free(s);
    return rc;
}

/* ----------------------------------------------------------------- submit */

/* A fixed-step run over a time has a step count the parameters alone
 * decide (the rule of api_params_finish): over max_iterations it is the
 * request's fault, a 400 at once rather than a failed job. */
static int steps_over_budget(const api_params *p, const api_limits *lim,
                             srv_problem *prob)
{
    double steps;

    if (!(p->flow.time > 0) || p->flow.adaptive || p->flow.dt_auto ||
        !(p->flow.dt > 0))
        return 0;
    steps = ceil(p->flow.time / p->flow.dt - 1e-9);
    if (steps <= lim->max_iterations)
        return 0;
    srv_problem_set(prob, 400, "ELIMIT", "parameters 'time' and 'dt': %g / %g "
                    "= %.3g steps exceed max_iterations (%d); raise 'dt', "
                    "lower 'time', or use 'adaptive'", p->flow.time, p->flow.dt,
                    steps, lim->max_iterations);
    return 1;
}

/* The estimate admit.c works with: the mesh's job and, with a target,
 * its copy of the input and a second mesh of the same counts. */
static double job_memory_estimate(const char *input, size_t input_len,
                                  size_t target_len, const api_params *p)
{
    api_mem_estimate e;
    api_estimate_memory(input, input_len, p, &e);
    return e.job_bytes + (target_len ? 3.0 * (double)target_len +
                                           48.0 * (double)e.vertices : 0);
}

int srv_jobs_submit(srv_record *rec, char *input, size_t input_len,
                    char *target, size_t target_len, int keep_result,
                    srv_job **out, srv_problem *prob)
{
    const srv_config *cfg = S.cfg;
    srv_job *j = NULL;
    api_params prm;
    mcf_error err = {MCF_OK, ""};
    mcf_status rc;
    cJSON *pj, *rj;
    char *rs = NULL;
    int reserved = 0;
    const mcf_scheme_info *si;
    double mem;

    /* Parameters first: a misspelled key is a 400 even when busy. */
    if ((rc = srv_record_params(rec, &cfg->lim, &prm, &err)) != MCF_OK) {
        srv_problem_from(prob, rc, SRV_STAGE_PARAMS, NULL, &err);
        goto fail;
    }
    if (steps_over_budget(&prm, &cfg->lim, prob)) {
        api_params_free(&prm);
        goto fail;
    }
    /* Memory admission (admit.c): the estimate from what the input
     * declares; over --max-job-memory it is refused now. */
    mem = job_memory_estimate(input, input_len, target_len, &prm);
    if (srv_admit_refuse(cfg, mem, prob)) {
        api_params_free(&prm);
        goto fail;
    }
    j = job_new();
    if (!j) {
        api_params_free(&prm);
        srv_problem_set(prob, 503, "ENOMEM", "out of memory accepting a job");
        goto fail;
    }
    si = mcf_scheme_get(prm.flow.scheme);
    snprintf(j->scheme, sizeof j->scheme, "%s", si ? si->name : "unknown");
    j->time_planned = prm.flow.time > 0 ? prm.flow.time : 0;
    j->steps_planned = (prm.flow.time > 0 || prm.flow.adaptive)
                           ? 0 : prm.flow.iterations;
    pj = api_params_to_json(&prm);
    j->params_json = pj ? cJSON_PrintUnformatted(pj) : NULL;
    cJSON_Delete(pj);
    api_params_free(&prm);

    srv_lock();
    if (S.draining) {
        srv_unlock();
        srv_problem_set(prob, 503, "EDRAINING",
                        "the daemon is shutting down and accepts no new jobs");
        goto fail;
    }
    if (S.qlen + S.reserved >= cfg->queue + (S.nthreads - S.busy)) {
        int q = S.qlen;
        srv_unlock();
        srv_problem_set(prob, 503, "EBUSY",
                        "the job queue is full (%d queued, %d workers busy, "
                        "--queue %d)", q, S.nthreads, cfg->queue);
        goto fail;
    }
    /* The spool's quota: every job stays there until its TTL (a flood of
     * tiny jobs kept 687 MB). */
    if (cfg->spool_max_jobs > 0 &&
        S.njobs + S.reserved >= cfg->spool_max_jobs) {
        int n = S.njobs;
        srv_unlock();
        srv_problem_set(prob, 503, "ESPOOLFULL", "the spool holds %d jobs, "
                        "--spool-max-jobs %d; finished jobs leave after "
                        "--result-ttl %g s or a DELETE", n, cfg->spool_max_jobs,
                        cfg->result_ttl);
        goto fail;
    }
    if (S.disk_bytes + input_len + target_len > cfg->spool_max_bytes) {
        size_t used = S.disk_bytes;
        srv_unlock();
        srv_problem_set(prob, 503, "ESPOOLFULL", "the spool holds %zu bytes of "
                        "jobs; %zu more would pass --spool-max-bytes %zu; "
                        "finished jobs leave after --result-ttl %g s or a "
                        "DELETE", used, input_len + target_len,
                        cfg->spool_max_bytes, cfg->result_ttl);
        goto fail;
    }
    S.reserved++;
    reserved = 1;
    new_id(j->id);
    srv_unlock();

    j->rec = *rec;
    memset(rec, 0, sizeof *rec);
    j->rec.has_target = target != NULL;
    j->input = input;
    j->input_len = input_len;
    j->target = target;
    j->target_len = target_len;
    input = target = NULL;
    j->keep_result = keep_result;
    j->mem_estimate = mem;
    j->disk_bytes = input_len + target_len;
    j->created = srv_wall();
    j->status = SRV_JOB_QUEUED;

    /* Durable before anyone hears of the ID: input, request, state. */
    rj = record_json(j);
    rs = rj ? cJSON_PrintUnformatted(rj) : NULL;
    cJSON_Delete(rj);
    if (!rs || srv_spool_mkjob(cfg->spool, j->id) != 0 ||
        srv_spool_write(cfg->spool, j->id, "input", j->input, j->input_len,
                        1) != 0 ||
        (j->target && srv_spool_write(cfg->spool, j->id, "target", j->target,
                                      j->target_len, 1) != 0) ||
        srv_spool_write(cfg->spool, j->id, "request.json", rs, strlen(rs),
                        1) != 0 ||
        write_state(j, 1) != 0) {
        srv_problem_set(prob, 500, "EIO", "cannot write job %s to the spool "
                        "%s: %s", j->id, cfg->spool, strerror(errno));
        srv_spool_remove(cfg->spool, j->id);
        goto fail;
    }
    free(rs);
    rs = NULL;
    /* On disk now: a queued job holds no copy in memory (80 queued
     * uploads of 7 MB held 735 MB); the worker reads it back. */
    free(j->input);
    j->input = NULL;
    free(j->target);
    j->target = NULL;

    srv_lock();
    S.reserved--;
    reserved = 0;
    table_insert(j);
    queue_push(j);
    j->refs++; /* the caller's */
    pthread_cond_signal(&S.work);
    srv_unlock();
    *out = j;
    return 0;

fail:
    if (reserved) {
        srv_lock();
        S.reserved--;
        srv_unlock();
    }
    free(rs);
    free(input);
    free(target);
    srv_record_free(rec);
    if (j)
        job_free(j);
    return -1;
}

/* ------------------------------------------------------------------ runner */

typedef struct {
    srv_job *job;
    const mcf_flow_stats *st; /* the run's statistics: its step log */
    double deadline;          /* srv_mono() seconds, 0: none */
} run_ctx;

static void fmt_num(char *buf, size_t size, double v)
{
    if (isfinite(v))
        snprintf(buf, size, "%.17g", v);
    else
        snprintf(buf, size, "null");
}

static int on_progress(void *ctx, int step, double t, double dt, double energy)
{
    run_ctx *c = ctx;
    srv_job *j = c->job;
    /* The step's volume is the step log's (the core fills entry step - 1
     * before this call): the quantity of flow.volume0/volume1 and
     * mcf_mesh_volume, in input units (api_metrics.c). */
    double vol = c->st->log && step >= 1 && step <= c->st->nlog
                     ? c->st->log[step - 1].volume : NAN;
    char line[320], a[32], b[32], e[32], v[32];
    int stop, n;

    fmt_num(a, sizeof a, t);
    fmt_num(b, sizeof b, dt);
    fmt_num(e, sizeof e, energy);
    fmt_num(v, sizeof v, vol);
    n = snprintf(line, sizeof line,
                 "{\"step\":%d,\"t\":%s,\"dt\":%s,\"energy\":%s,\"volume\":%s}\n",
                 step, a, b, e, v);
    srv_lock();
    j->step = step;
    j->t = t;
    j->dt = dt;
    j->energy = energy;
    j->volume = vol;
    if (n > 0 && api_buf_append(&j->events, line, (size_t)n) == MCF_OK)
        j->nevents++;
    srv_job_wake(j, 1);
    if (!j->cancel && c->deadline > 0 && srv_mono() > c->deadline) {
        j->cancel = 1;
        j->cancel_reason = SRV_CANCEL_TIMEOUT;
    }
    stop = j->cancel;
    srv_unlock();
    return stop;
}

/* The metrics document of a finished job: api's, the CLI's too
 * (api_metrics_json), with the daemon's own facts. */
static char *metrics_doc(const srv_job *j, const api_metrics *mt,
                         const api_params *prm, const mcf_flow_stats *st,
                         api_format in_fmt, api_format out_fmt, double qerr,
                         size_t in_bytes, size_t out_bytes, double t_queue,
                         double t_decode, double t_flow, double t_encode,
                         double t_metrics)
{
    api_metrics_run run;
    cJSON *o;
    char *s;

    api_metrics_run_init(&run);
    run.job = j->id;
    run.input_name = j->rec.filename[0] ? j->rec.filename : NULL;
    run.output_name = j->result_name;
    run.target_name = j->rec.has_target ? "target" : NULL;
    run.input_format = in_fmt;
    run.output_format = out_fmt;
    run.input_bytes = in_bytes;
    run.output_bytes = out_bytes;
    run.quantization_max_error = qerr;
    run.queue_s = t_queue;
    run.decode_s = t_decode;
    run.flow_s = t_flow;
    run.encode_s = t_encode;
    run.metrics_s = t_metrics;
    run.total_s = t_decode + t_flow + t_encode + t_metrics;
    o = api_metrics_json(mt, prm, st, &run);
    s = o ? cJSON_PrintUnformatted(o) : NULL;
    cJSON_Delete(o);
    return s;
}

static void log_job(const srv_job *j, int nv, int nf, double run_s)
{
    cJSON *o = cJSON_CreateObject();
    if (!o)
        return;
    cJSON_AddStringToObject(o, "type", "job");
    cJSON_AddStringToObject(o, "job", j->id);
    cJSON_AddStringToObject(o, "scheme", j->scheme);
    cJSON_AddStringToObject(o, "status", srv_job_status_name(j->status));
    cJSON_AddNumberToObject(o, "vertices", nv);
    cJSON_AddNumberToObject(o, "faces", nf);
    cJSON_AddNumberToObject(o, "steps", j->step);
    cJSON_AddNumberToObject(o, "queue_ms",
                            j->started > 0 ? (j->started - j->created) * 1e3 : 0);
    cJSON_AddNumberToObject(o, "run_ms", run_s * 1e3);
    if (j->recovered)
        cJSON_AddBoolToObject(o, "recovered", 1);
    if (j->status == SRV_JOB_FAILED || j->status == SRV_JOB_CANCELED) {
        cJSON_AddNumberToObject(o, "http", j->err.http);
        cJSON_AddStringToObject(o, "code", j->err.code);
        cJSON_AddStringToObject(o, "detail", j->err.detail);
    }
    srv_log_json(j->status == SRV_JOB_FAILED && j->err.http >= 500
                     ? SRV_LOG_ERROR : SRV_LOG_INFO, o);
}

/* The problem of a job stopped by its cancel flag after `steps` steps
 * (-1: while decoding); 1 when it must run again after a restart. */
static int canceled_problem(srv_job *j, int steps, srv_problem *prob)
{
    const srv_config *cfg = S.cfg;
    char when[48];
    int reason;

    srv_lock();
    reason = j->cancel_reason;
    srv_unlock();
    if (steps >= 0)
        snprintf(when, sizeof when, "after step %d", steps);
    else
        snprintf(when, sizeof when, "while its input was decoded");
    if (reason == SRV_CANCEL_SHUTDOWN) {
        srv_problem_set(prob, 503, "EDRAINING", "the daemon shut down "
                        "while job %s ran; it runs again after the restart",
                        j->id);
        return 1;
    }
    if (reason == SRV_CANCEL_TIMEOUT)
        srv_problem_set(prob, 422, "ELIMIT", "the job ran longer than "
                        "--job-timeout %g s and was stopped %s",
                        cfg->job_timeout, when);
    else if (reason == SRV_CANCEL_CLIENT)
        srv_problem_set(prob, 409, "ECANCELED", "canceled %s: the client "
                        "closed its connection before the answer", when);
    else
        srv_problem_set(prob, 409, "ECANCELED", "canceled by DELETE "
                        "/v1/jobs/%s %s", j->id, when);
    return 0;
}

/* After decoding: the estimate from the real counts; over the per-job
 * bound a 422, else the reservation grows (waiting for memory). 0 when
 * the job may go on, else prob is set and -1 (it failed) or 1 (canceled
 * by the shutdown: it runs again after the restart). */
static int job_memory_regrow(srv_job *j, int nv, int nf, size_t input_len,
                             size_t target_len, const api_params *p,
                             srv_problem *prob)
{
    double est = api_estimate_job_bytes(nv, nf, input_len, p) +
                 (target_len ? 3.0 * (double)target_len + 48.0 * nv : 0);
    if (srv_admit_refuse(S.cfg, est, prob))
        return -1;
    if (srv_admit_grow(S.cfg, &j->mem_held, est, &j->cancel) != 0)
        return canceled_problem(j, -1, prob) ? 1 : -1;
    return 0;
}

static void run_job(srv_job *j)
{
    const srv_config *cfg = S.cfg;
    api_params prm;
    int have_prm = 0;
    mcf_mesh *m = NULL, *tgt = NULL;
    api_attrs *attrs = NULL;   /* the input's texcoords, colours, normals */
    api_format fmt = API_FMT_UNKNOWN, tfmt;
    mcf_error err = {MCF_OK, ""};
    mcf_status rc;
    mcf_flow_stats st;
    api_metrics mt;
    api_buf out;
    api_encode_opts eo;
    srv_problem prob;
    int failed = 1, requeue = 0, nv = 0, nf = 0;
    char *input = NULL, *target = NULL, *metrics = NULL;
    size_t input_len = 0, target_len = 0;
    srv_job_status final;
    char *state = NULL;
    double t0 = mcf_now(), t_decode = 0, t_flow = 0, t_encode = 0, t_queue,
           t_metrics = 0, t_after, qerr = NAN;
    run_ctx ctx;

    memset(&st, 0, sizeof st);
    api_metrics_init(&mt);
    memset(&prob, 0, sizeof prob);
    api_buf_init(&out, RESULT_MAX);
    srv_lock();
    input = j->input;
    input_len = j->input_len;
    target = j->target;
    target_len = j->target_len;
    j->input = j->target = NULL;
    t_queue = j->started - j->created;
    srv_unlock();
    write_state(j, 0);

    if (!input &&
        srv_spool_read(cfg->spool, j->id, "input", &input, &input_len) != 0) {
        srv_problem_set(&prob, 500, "EIO", "cannot read the input of job %s "
                        "from the spool: %s", j->id, strerror(errno));
        goto done;
    }
    if (j->rec.has_target && !target &&
        srv_spool_read(cfg->spool, j->id, "target", &target, &target_len) != 0) {
        srv_problem_set(&prob, 500, "EIO", "cannot read the target of job %s "
                        "from the spool: %s", j->id, strerror(errno));
        goto done;
    }
    if ((rc = srv_record_params(&j->rec, &cfg->lim, &prm, &err)) != MCF_OK) {
        srv_problem_from(&prob, rc, SRV_STAGE_PARAMS, NULL, &err);
        goto done;
    }
    have_prm = 1;
    /* sandbox.c: Draco decodes in a limited child process. */
    if ((rc = srv_decode_upload(input, input_len, cfg, &j->cancel, "mesh", &m,
                                &attrs, &fmt, &prob)) != MCF_OK)
        goto decode_failed;
    free(input);
    input = NULL;
    nv = mcf_mesh_nvertices(m);
    nf = mcf_mesh_nfaces(m);
    /* admit.c: estimated again from the decoded counts (polygons split,
     * STL welded); a larger estimate is refused or waits for memory. */
    if ((requeue = job_memory_regrow(j, nv, nf, input_len, target_len,
                                     &prm, &prob)) != 0) {
        requeue = requeue > 0;
        goto done;
    }
    if ((rc = api_params_finish(&prm, nv, &cfg->lim, &err)) != MCF_OK) {
        /* A budget exceeded here (steps x vertices) depends on the mesh:
         * 422. What the parameters alone exceed was refused at submit. */
        srv_problem_from(&prob, rc, rc == MCF_ELIMIT ? SRV_STAGE_RUN
                                                     : SRV_STAGE_PARAMS,
                         NULL, &err);
        goto done;
    }
    if (target) {
        if ((rc = srv_decode_upload(target, target_len, cfg, &j->cancel,
                                    "target", &tgt, NULL, &tfmt, &prob)) != MCF_OK)
            goto decode_failed;
        if (mcf_mesh_nvertices(tgt) != nv || mcf_mesh_nfaces(tgt) != nf) {
            srv_problem_set(&prob, 422, "EINVAL", "target: %d vertices and %d "
                            "faces, the mesh has %d and %d; the target must "
                            "share the mesh's connectivity",
                            mcf_mesh_nvertices(tgt), mcf_mesh_nfaces(tgt), nv, nf);
            goto done;
        }
    }
    if (prm.noise_rho > 0 &&
        (rc = mcf_flow_add_noise(m, &prm.flow, prm.noise_rho, prm.seed, &err)) != MCF_OK) {
        srv_problem_from(&prob, rc, SRV_STAGE_RUN, "noise", &err);
        goto done;
    }
    t_decode = mcf_now() - t0;
    t_metrics = mcf_now();
    if ((rc = api_metrics_before(&mt, m, tgt, &err)) != MCF_OK) {
        srv_problem_from(&prob, rc, SRV_STAGE_RUN, "metrics", &err);
        goto done;
    }
    t_metrics = mcf_now() - t_metrics;

    memset(&ctx, 0, sizeof ctx);
    ctx.job = j;
    ctx.st = &st;
    ctx.deadline = cfg->job_timeout > 0 ? srv_mono() + cfg->job_timeout : 0;
    prm.flow.progress = on_progress;
    prm.flow.progress_ctx = &ctx;
    prm.flow.cancel = &j->cancel;
    /* The step log: the metrics' flow.log (as the CLI's) and the volume of
     * each streamed step. */
    prm.flow.log_steps = 1;

    srv_lock();
    j->ready = 1;
    snprintf(j->in_format, sizeof j->in_format, "%s", api_format_name(fmt));
    srv_job_wake(j, 0);
    srv_unlock();

    t_flow = mcf_now();
    rc = mcf_flow_run(m, &prm.flow, &st, &err);
    t_flow = mcf_now() - t_flow;
    if (rc == MCF_ECANCELED) {
        requeue = canceled_problem(j, st.steps, &prob);
        goto done;
    }
    if (rc != MCF_OK) {
        srv_problem_from(&prob, rc, SRV_STAGE_RUN, "flow", &err);
        goto done;
    }

    t_encode = mcf_now();
    if (prm.encode.format == API_FMT_UNKNOWN)
        prm.encode.format = fmt; /* the metrics' params say what was written */
    eo = prm.encode;
    eo.attrs = attrs;
    rc = eo.format == API_FMT_DRACO ? api_draco_encode(m, &eo, &out, &qerr, &err)
                                    : api_mesh_encode(m, &eo, &out, &err);
    if (rc != MCF_OK) {
        srv_problem_from(&prob, rc, SRV_STAGE_RUN, "encode", &err);
        goto done;
    }
    t_encode = mcf_now() - t_encode;
    t_after = mcf_now();
    if ((rc = api_metrics_after(&mt, m, tgt, &err)) != MCF_OK) {
        srv_problem_from(&prob, rc, SRV_STAGE_RUN, "metrics", &err);
        goto done;
    }
    t_metrics += mcf_now() - t_after;
    srv_lock();
    snprintf(j->out_format, sizeof j->out_format, "%s",
             api_format_name(eo.format));
    snprintf(j->result_name, sizeof j->result_name, "result%s",
             api_format_ext(eo.format));
    srv_unlock();
    metrics = metrics_doc(j, &mt, &prm, &st, fmt, eo.format, qerr, input_len,
                          out.len, t_queue, t_decode, t_flow, t_encode,
                          t_metrics);
    if (!metrics) {
        srv_problem_set(&prob, 503, "ENOMEM", "out of memory writing metrics");
        goto done;
    }
    if (srv_spool_write(cfg->spool, j->id, j->result_name, out.data, out.len,
                        1) != 0 ||
        srv_spool_write(cfg->spool, j->id, "metrics.json", metrics,
                        strlen(metrics), 1) != 0) {
        srv_problem_set(&prob, 500, "EIO", "cannot write the result of job %s "
                        "to the spool: %s", j->id, strerror(errno));
        goto done;
    }
    failed = 0;
    goto done;

decode_failed:
    /* srv_decode_upload filled prob, except for a cancel. */
    if (rc == MCF_ECANCELED)
        requeue = canceled_problem(j, -1, &prob);
done:
    /* Until the outcome is published: no other state.json write between
     * its snapshot and the publication (a DELETE's would be stale). */
    pthread_mutex_lock(&g_state_mu);
    srv_lock();
    if (requeue) {
        /* Back to queued on disk; the process is exiting. */
        final = SRV_JOB_QUEUED;
        j->ready = 0;
        j->err = prob;
    } else if (failed) {
        final = j->cancel && (j->cancel_reason == SRV_CANCEL_USER ||
                              j->cancel_reason == SRV_CANCEL_CLIENT)
                    ? SRV_JOB_CANCELED : SRV_JOB_FAILED;
        j->err = prob;
        j->finished = srv_wall();
    } else {
        final = SRV_JOB_SUCCEEDED;
        j->finished = srv_wall();
        j->metrics_json = metrics;
        metrics = NULL;
        j->result_len = out.len;
        if (j->keep_result) {
            size_t len;
            j->result = api_buf_detach(&out, &len);
        }
    }
    /* The outcome on disk before anyone can see it (GET polls, waiters):
     * a client told "succeeded" can always find the result again. */
    j->status = final;
    state = state_json(j);
    j->status = SRV_JOB_RUNNING;
    srv_unlock();
    if (!state || srv_spool_write(cfg->spool, j->id, "state.json", state,
                                  strlen(state), 1) != 0) {
        int e = state ? errno : ENOMEM;
        srv_lock();
        if (final == SRV_JOB_SUCCEEDED) {
            /* Not durable, so not a success: after a restart the job,
             * still `running` on disk, runs again. */
            final = SRV_JOB_FAILED;
            srv_problem_set(&j->err, 500, "EIO", "job %s finished but its "
                            "state could not be written to the spool %s: %s",
                            j->id, cfg->spool, strerror(e));
            free(j->result);
            j->result = NULL;
        }
        srv_unlock();
        srv_logf(SRV_LOG_ERROR, "spool: cannot record the outcome of job %s: "
                 "%s", j->id, strerror(e));
    }
    free(state);
    srv_lock();
    j->status = final;
    if (final == SRV_JOB_SUCCEEDED) {
        size_t add = j->result_len +
                     (j->metrics_json ? strlen(j->metrics_json) : 0);
        j->disk_bytes += add;
        if (j->in_table)
            S.disk_bytes += add;
    }
    srv_unlock();
    pthread_mutex_unlock(&g_state_mu);
    /* Counted before anyone hears, so /metrics agrees with what clients
     * have seen. */
    if (!requeue) {
        srv_metrics_job(j->scheme, srv_job_status_name(j->status),
                        mcf_now() - t0);
        log_job(j, nv, nf, mcf_now() - t0);
    }
    srv_lock();
    srv_job_wake(j, 0);
    srv_unlock();
    if (have_prm)
        api_params_free(&prm);
    mcf_flow_stats_free(&st);
    mcf_mesh_free(m);
    mcf_mesh_free(tgt);
    api_attrs_free(attrs);
    api_buf_free(&out);
    free(input);
    free(target);
    free(metrics);
}

static void *worker_main(void *arg)
{
    (void)arg;
    srv_lock();
    for (;;) {
        srv_job *j;
        /* The head of the queue starts when its memory estimate fits
         * (admit.c); else it waits for a running job to end. */
        while (!S.stopping && (S.draining || !S.qhead ||
                               !srv_admit_try(S.cfg, S.qhead->mem_estimate)))
            pthread_cond_wait(&S.work, &S.mu);
        if (S.stopping)
            break;
        j = queue_pop();
        j->mem_held = j->mem_estimate;
        j->refs++;
        j->status = SRV_JOB_RUNNING;
        j->started = srv_wall();
        S.busy++;
        srv_job_wake(j, 0);
        srv_unlock();
        run_job(j);
        srv_admit_release(j->mem_held); /* admit.c: its memory is free */
        srv_lock();
        pthread_cond_broadcast(&S.work);
        S.busy--;
        unref_locked(j);
        pthread_cond_broadcast(&S.idle);
    }
    srv_unlock();
    return NULL;
}

/* ------------------------------------------------------------------ cancel */

/* Lock held: a queued job becomes canceled and its waiters hear. The
 * caller then unlocks and calls finish_canceled_queued (which drops the
 * reference taken here). */
static void cancel_queued_locked(srv_job *j, int reason)
{
    /* Not in the queue only when a shutdown just put it back. */
    (void)queue_remove(j);
    j->status = SRV_JOB_CANCELED;
    j->cancel = 1;
    j->cancel_reason = reason;
    j->finished = srv_wall();
    if (reason == SRV_CANCEL_CLIENT)
        srv_problem_set(&j->err, 409, "ECANCELED", "canceled while queued: "
                        "the client closed its connection before the answer");
    else
        srv_problem_set(&j->err, 409, "ECANCELED", "canceled by DELETE "
                        "/v1/jobs/%s while queued", j->id);
    j->refs++;
    srv_job_wake(j, 0);
}

static int finish_canceled_queued(srv_job *j)
{
    int rc = write_state(j, 1);
    srv_metrics_job(j->scheme, "canceled", 0);
    log_job(j, 0, 0, 0);
    srv_job_unref(j);
    return rc;
}

/* Whether the peer of a suspended connection has closed it: a peek finds
 * the end of the stream or an error. A pipelined request (bytes waiting)
 * is a client still there. A client that half-closes its side after the
 * request counts as gone, as in most servers. */
static int client_gone(struct MHD_Connection *c)
{
    const union MHD_ConnectionInfo *ci =
        MHD_get_connection_info(c, MHD_CONNECTION_INFO_CONNECTION_FD);
    char b;
    ssize_t n;

    if (!ci || ci->connect_fd == MHD_INVALID_SOCKET)
        return 0;
    n = recv(ci->connect_fd, &b, 1, MSG_PEEK | MSG_DONTWAIT);
    return n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK &&
                      errno != EINTR);
}

int srv_jobs_check_clients(void)
{
    srv_job **gone = NULL;
    int n = 0, cap = 0, b, i, canceled = 0;
    srv_job *j;

    srv_lock();
    for (b = 0; b < NBUCKETS; b++)
        for (j = S.buckets[b]; j; j = j->hnext) {
            srv_waiter *w;
            int hung = 0;
            /* Event streams whose client left: resumed to end (stream.c),
             * which frees their connection now, not when the job moves. */
            for (w = j->waiters; w; w = w->next)
                if (w->want_events && w->suspended && !w->gone &&
                    client_gone(w->conn)) {
                    w->gone = 1;
                    w->suspended = 0;
                    MHD_resume_connection(w->conn);
                }
            if (j->cancel || (j->status != SRV_JOB_QUEUED &&
                              j->status != SRV_JOB_RUNNING))
                continue;
            /* A suspended waiter's connection is left alone by MHD until
             * it is resumed, which needs this lock: its socket is valid. */
            for (w = j->waiters; w && !hung; w = w->next)
                hung = w->cancel_on_hangup && w->suspended &&
                       client_gone(w->conn);
            if (!hung)
                continue;
            canceled++;
            if (j->status == SRV_JOB_RUNNING) {
                j->cancel = 1;
                j->cancel_reason = SRV_CANCEL_CLIENT;
                continue;
            }
            if (n == cap) {
                int ncap = cap ? 2 * cap : 16;
                void *p = realloc(gone, (size_t)ncap * sizeof *gone);
                if (!p) {
                    canceled--;
                    continue; /* the next check tries again */
                }
                gone = p;
                cap = ncap;
            }
            cancel_queued_locked(j, SRV_CANCEL_CLIENT);
            gone[n++] = j;
        }
    srv_unlock();
    for (i = 0; i < n; i++)
        finish_canceled_queued(gone[i]);
    free(gone);
    return canceled;
}

/* ------------------------------------------------------------------ delete */

int srv_jobs_delete(const char *id, srv_job_status *before)
{
    srv_job *j;

    srv_lock();
    j = find_locked(id);
    if (!j) {
        srv_unlock();
        return -1;
    }
    *before = j->status;
    if (j->status == SRV_JOB_QUEUED) {
        cancel_queued_locked(j, SRV_CANCEL_USER);
        srv_unlock();
        return finish_canceled_queued(j) == 0 ? 0 : -2;
    }
    if (j->status == SRV_JOB_RUNNING) {
        int rc;
        j->cancel = 1;
        j->cancel_reason = SRV_CANCEL_USER;
        j->refs++;
        srv_unlock();
        /* On disk too: should the process end before the current step
         * does, the restart finds the job canceled, not queued. */
        rc = write_state(j, 1);
        srv_job_unref(j);
        return rc == 0 ? 1 : -2;
    }
    /* Finished: forget it, out of the table first (a visible job always
     * has its files), then off the disk; a job that cannot be removed
     * is put back, rather than coming back after a restart. */
    j->refs++;
    table_remove(j);
    srv_unlock();
    if (srv_spool_remove(S.cfg->spool, id) != 0) {
        int e = errno;
        srv_logf(SRV_LOG_ERROR, "spool: cannot remove job %s: %s", id,
                 strerror(e));
        srv_lock();
        table_restore(j);
        srv_unlock();
        errno = e;
        return -2;
    }
    srv_job_unref(j);
    return 2;
}

/* ------------------------------------------------------------------ sweep */

void srv_jobs_sweep(void)
{
    srv_job **gone = NULL;
    int n = 0, cap = 0, b, i;
    double now = srv_wall();
    srv_job *j, *next;

    srv_lock();
    for (b = 0; b < NBUCKETS; b++)
        for (j = S.buckets[b]; j; j = next) {
            next = j->hnext;
            if (!is_terminal(j->status))
                continue;
            /* Progress lines are only replayed to late SSE subscribers:
             * drop them once nobody follows a finished job. */
            if (j->refs == 1 && j->events.data && now - j->finished > 10) {
                api_buf_free(&j->events);
                api_buf_init(&j->events, EVENTS_MAX);
                j->nevents = 0;
            }
            if (now - j->finished < S.cfg->result_ttl)
                continue;
            if (n == cap) {
                int ncap = cap ? 2 * cap : 64;
                void *p = realloc(gone, (size_t)ncap * sizeof *gone);
                if (!p)
                    break;
                gone = p;
                cap = ncap;
            }
            /* Out of the table before its files go (a visible job always
             * has its files), held by a reference of ours. */
            j->refs++;
            table_remove(j);
            gone[n++] = j;
        }
    srv_unlock();
    /* A removal that fails puts the job back (tried again at the next
     * sweep) instead of leaving files that bring it back after a
     * restart. */
    for (i = 0; i < n; i++) {
        j = gone[i];
        if (srv_spool_remove(S.cfg->spool, j->id) != 0) {
            srv_logf(SRV_LOG_WARN, "spool: cannot remove expired job %s: %s",
                     j->id, strerror(errno));
            srv_lock();
            table_restore(j);
            srv_unlock();
            continue;
        }
        srv_logf(SRV_LOG_DEBUG, "job %s expired after --result-ttl %g s",
                 j->id, S.cfg->result_ttl);
        srv_job_unref(j);
    }
    free(gone);
}

/* ------------------------------------------------------------------ recovery */

typedef struct {
    srv_job **queued;
    int n, cap;
    int restored, requeued, dropped;
} recover_ctx;

static int by_created(const void *a, const void *b)
{
    const srv_job *x = *(srv_job *const *)a, *y = *(srv_job *const *)b;
    if (x->created != y->created)
        return x->created < y->created ? -1 : 1;
    return strcmp(x->id, y->id);
}

static int valid_id(const char *id)
{
    size_t i;
    for (i = 0; id[i]; i++)
        if (!((id[i] >= '0' && id[i] <= '9') || (id[i] >= 'a' && id[i] <= 'f')))
            return 0;
    return i == SRV_ID_LEN;
}

static double num_of(const cJSON *o, const char *k)
{
    const cJSON *x = cJSON_GetObjectItemCaseSensitive(o, k);
    return cJSON_IsNumber(x) ? x->valuedouble : 0;
}

static const char *str_of(const cJSON *o, const char *k)
{
    const char *s = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(o, k));
    return s ? s : "";
}

static void recover_one(const char *id, void *arg)
{
    recover_ctx *rc = arg;
    const srv_config *cfg = S.cfg;
    char *state = NULL, *req = NULL;
    size_t len;
    cJSON *so = NULL, *ro = NULL;
    srv_job *j = NULL;
    const cJSON *e;

    if (!valid_id(id))
        return; /* not ours: leave it alone */
    if (srv_spool_read(cfg->spool, id, "state.json", &state, &len) != 0 ||
        srv_spool_read(cfg->spool, id, "request.json", &req, &len) != 0 ||
        !(so = cJSON_Parse(state)) || !(ro = cJSON_Parse(req)) ||
        !(j = job_new()) || record_from_json(&j->rec, ro) != 0 ||
        status_from_name(str_of(so, "status"), &j->status) != 0) {
        /* Never acknowledged (crash between mkdir and state.json). */
        srv_logf(SRV_LOG_WARN, "spool: removing incomplete job %s", id);
        srv_spool_remove(cfg->spool, id);
        rc->dropped++;
        goto out;
    }
    snprintf(j->id, sizeof j->id, "%s", id);
    j->disk_bytes = srv_spool_du(cfg->spool, id);
    j->recovered = 1;
    j->mem_estimate = num_of(ro, "memory_estimate"); /* admit.c */
    j->created = num_of(so, "created");
    j->started = num_of(so, "started");
    j->finished = num_of(so, "finished");
    snprintf(j->scheme, sizeof j->scheme, "%s", str_of(so, "scheme"));
    j->steps_planned = (int)num_of(so, "steps_planned");
    j->time_planned = num_of(so, "time_planned");
    snprintf(j->in_format, sizeof j->in_format, "%s", str_of(so, "in_format"));
    snprintf(j->out_format, sizeof j->out_format, "%s", str_of(so, "out_format"));
    snprintf(j->result_name, sizeof j->result_name, "%s", str_of(so, "result"));
    j->result_len = (size_t)num_of(so, "result_bytes");
    if (*str_of(so, "params"))
        j->params_json = strdup(str_of(so, "params"));
    if ((e = cJSON_GetObjectItemCaseSensitive(so, "error")) != NULL) {
        j->err.http = (unsigned)num_of(e, "http");
        snprintf(j->err.code, sizeof j->err.code, "%s", str_of(e, "code"));
        snprintf(j->err.detail, sizeof j->err.detail, "%s", str_of(e, "detail"));
    }
    if (is_terminal(j->status)) {
        if (srv_wall() - j->finished >= cfg->result_ttl) {
            srv_spool_remove(cfg->spool, id);
            goto out;
        }
        j->step = (int)num_of(so, "step");
        j->t = num_of(so, "t");
        if (j->status == SRV_JOB_SUCCEEDED &&
            srv_spool_read(cfg->spool, id, "metrics.json", &j->metrics_json,
                           &len) != 0) {
            srv_logf(SRV_LOG_WARN, "spool: job %s has no metrics.json", id);
        }
        table_insert(j);
        j = NULL;
        rc->restored++;
        goto out;
    }
    if (*str_of(so, "cancel_requested")) {
        /* Canceled while it ran, and the process ended before the step
         * did: it stays canceled. */
        char *s;
        j->status = SRV_JOB_CANCELED;
        j->finished = srv_wall();
        j->step = (int)num_of(so, "step");
        srv_problem_set(&j->err, 409, "ECANCELED", "canceled %s while it "
                        "ran, before the daemon restarted; it did not run "
                        "again", strcmp(str_of(so, "cancel_requested"),
                                        "user") == 0
                                 ? "by DELETE" : "when its client hung up");
        if ((s = state_json(j)) != NULL) {
            if (srv_spool_write(cfg->spool, id, "state.json", s, strlen(s),
                                1) != 0)
                srv_logf(SRV_LOG_WARN, "spool: cannot record job %s as "
                         "canceled: %s", id, strerror(errno));
            free(s);
        }
        table_insert(j);
        j = NULL;
        rc->restored++;
        goto out;
    }
    /* queued, or running when the process died: run it again */
    j->status = SRV_JOB_QUEUED;
    j->started = 0;
    if (rc->n == rc->cap) {
        int ncap = rc->cap ? 2 * rc->cap : 64;
        void *p = realloc(rc->queued, (size_t)ncap * sizeof *rc->queued);
        if (!p)
            goto out;
        rc->queued = p;
        rc->cap = ncap;
    }
    rc->queued[rc->n++] = j;
    j = NULL;
out:
    if (j)
        job_free(j);
    cJSON_Delete(so);
    cJSON_Delete(ro);
    free(state);
    free(req);
}

int srv_jobs_start(const srv_config *cfg, char *msg, size_t msgsize)
{
    recover_ctx rc;
    int i;

    memset(&rc, 0, sizeof rc);
    S.cfg = cfg;
    S.urandom = open("/dev/urandom", O_RDONLY);
    {
        /* The drain's timed wait on the monotonic clock, like every
         * deadline of the daemon. */
        pthread_condattr_t ca;
        if (pthread_condattr_init(&ca) == 0) {
            if (pthread_condattr_setclock(&ca, CLOCK_MONOTONIC) == 0) {
                pthread_cond_destroy(&S.idle);
                pthread_cond_init(&S.idle, &ca);
            }
            pthread_condattr_destroy(&ca);
        }
    }
    srv_lock();
    if (srv_spool_list(cfg->spool, recover_one, &rc) != 0) {
        srv_unlock();
        snprintf(msg, msgsize, "cannot list the spool %s: %s", cfg->spool,
                 strerror(errno));
        return -1;
    }
    if (rc.n > 1)
        qsort(rc.queued, (size_t)rc.n, sizeof *rc.queued, by_created);
    for (i = 0; i < rc.n; i++) {
        table_insert(rc.queued[i]);
        queue_push(rc.queued[i]);
    }
    srv_unlock();
    free(rc.queued);
    if (rc.n || rc.restored || rc.dropped)
        srv_logf(SRV_LOG_INFO, "spool %s: %d jobs queued again, %d finished "
                 "jobs restored, %d incomplete removed", cfg->spool, rc.n,
                 rc.restored, rc.dropped);

    S.threads = calloc((size_t)cfg->workers, sizeof *S.threads);
    if (!S.threads) {
        snprintf(msg, msgsize, "out of memory");
        return -1;
    }
    for (i = 0; i < cfg->workers; i++) {
        if (pthread_create(&S.threads[i], NULL, worker_main, NULL) != 0) {
            snprintf(msg, msgsize, "cannot start worker %d: %s", i,
                     strerror(errno));
            srv_lock();
            S.stopping = 1;
            pthread_cond_broadcast(&S.work);
            srv_unlock();
            while (i-- > 0)
                pthread_join(S.threads[i], NULL);
            return -1;
        }
        srv_lock();
        S.nthreads = i + 1;
        srv_unlock();
    }
    return 0;
}

/* ------------------------------------------------------------------ drain */

void srv_jobs_drain(void)
{
    srv_job *j;

    srv_lock();
    S.draining = 1;
    /* Clients waiting on queued jobs hear now: those run after restart. */
    for (j = S.qhead; j; j = j->qnext)
        srv_job_wake(j, 0);
    pthread_cond_broadcast(&S.work);
    srv_unlock();
}

int srv_jobs_draining_locked(void)
{
    return S.draining;
}

int srv_jobs_closing_locked(void)
{
    return S.closing;
}

int srv_jobs_can_accept(void)
{
    int ok;
    srv_lock();
    ok = !S.draining &&
         S.qlen + S.reserved < S.cfg->queue + (S.nthreads - S.busy);
    srv_unlock();
    return ok;
}

int srv_jobs_draining(void)
{
    int d;
    srv_lock();
    d = S.draining;
    srv_unlock();
    return d;
}

int srv_jobs_wait_idle(double timeout)
{
    struct timespec ts;
    double end = srv_mono() + timeout;
    int idle;

    srv_lock();
    while (S.busy > 0) {
        double now = srv_mono(); /* S.idle waits on CLOCK_MONOTONIC */
        if (now >= end)
            break;
        ts.tv_sec = (time_t)end;
        ts.tv_nsec = (long)((end - (double)ts.tv_sec) * 1e9);
        pthread_cond_timedwait(&S.idle, &S.mu, &ts);
    }
    idle = S.busy == 0;
    srv_unlock();
    return idle;
}

void srv_jobs_checkpoint_running(void)
{
    int b;
    srv_job *j;

    srv_lock();
    for (b = 0; b < NBUCKETS; b++)
        for (j = S.buckets[b]; j; j = j->hnext)
            /* A job its user (or its hung-up client) canceled stays
             * canceled: it is not put back in the queue. */
            if (j->status == SRV_JOB_RUNNING &&
                !(j->cancel && (j->cancel_reason == SRV_CANCEL_USER ||
                                j->cancel_reason == SRV_CANCEL_CLIENT))) {
                j->cancel = 1;
                j->cancel_reason = SRV_CANCEL_SHUTDOWN;
            }
    srv_unlock();
}

void srv_jobs_stop(void)
{
    int i, b;
    srv_job *j, *next;

    srv_lock();
    S.stopping = 1;
    pthread_cond_broadcast(&S.work);
    srv_unlock();
    for (i = 0; i < S.nthreads; i++)
        pthread_join(S.threads[i], NULL);
    free(S.threads);
    S.threads = NULL;
    S.nthreads = 0;
    srv_lock();
    while (queue_pop())
        ;
    for (b = 0; b < NBUCKETS; b++)
        for (j = S.buckets[b]; j; j = next) {
            next = j->hnext;
            table_remove(j);
        }
    srv_unlock();
    if (S.urandom >= 0)
        close(S.urandom);
    S.urandom = -1;
}

srv_gauges srv_jobs_gauges(void)
{
    srv_gauges g;
    srv_lock();
    g.queue_depth = S.qlen;
    g.queue_capacity = S.cfg ? S.cfg->queue : 0;
    g.workers = S.nthreads;
    g.workers_busy = S.busy;
    g.jobs_in_memory = S.njobs;
    g.draining = S.draining;
    g.followers = srv_stream_followers();
    g.spool_bytes = (double)S.disk_bytes;
    srv_unlock();
    return g;
}
