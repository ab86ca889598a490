/*
 * svc_state.c - what the job service keeps of a job: the record of what
 * the client sent (and the parameters rebuilt from it) persisted as
 * request.json, and state.json (everything needed to serve the job after
 * a restart), written through spool.c and read back by recovery.c; and
 * the one log line of a finished job.
 *
 * A failure is stored as {"kind","code","mcf","stage","cancel","detail"}
 * (svc_error). Spools written before the service split stored
 * {"http","code","detail"}: those still load, their kind and stage
 * derived from the HTTP status, so each door answers them as before.
 */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "svc_internal.h"

pthread_mutex_t svc_state_mu = PTHREAD_MUTEX_INITIALIZER;

static const char *const stage_names[] = {"", "params", "decode", "run"};
static const char *const cancel_names[] = {"", "user", "shutdown", "timeout",
                                           "client"};

static int index_of(const char *s, const char *const *names, int n)
{
    int i;
    for (i = 0; i < n; i++)
        if (strcmp(s, names[i]) == 0)
            return i;
    return -1;
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

static void add_num(cJSON *o, const char *key, double v)
{
    if (isfinite(v))
        cJSON_AddNumberToObject(o, key, v);
    else
        cJSON_AddNullToObject(o, key);
}

/* ----------------------------------------------------------------- records */

void svc_record_free(svc_record *r)
{
    free(r->query);
    free(r->params_json);
    cJSON_Delete(r->fields);
    memset(r, 0, sizeof *r);
}

mcf_status svc_record_params(const svc_record *r, const api_limits *lim,
                             api_params *p, mcf_error *err)
{
    static const char *const ignore[] = {"stream", "fields", NULL};
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

int svc_record_fields(const svc_record *r, int *on, svc_error *err)
{
    const char *p = r->query;

    *on = 0;
    while (p && *p) {
        size_t n = strcspn(p, "&");
        if (n >= 7 && strncmp(p, "fields=", 7) == 0) {
            static const char *const yes[] = {"true", "1", "yes"}, *const no[] = {"false", "0", "no"};
            size_t k, v = n - 7;
            int found = 0;
            for (k = 0; k < 3 && !found; k++) {
                if (strlen(yes[k]) == v && strncmp(p + 7, yes[k], v) == 0)
                    found = 1, *on = 1;
                else if (strlen(no[k]) == v && strncmp(p + 7, no[k], v) == 0)
                    found = 1, *on = 0;
            }
            if (!found) {
                mcf_error me;
                mcf_error_set(&me, MCF_EINVAL, "parameter 'fields' must be true "
                              "or false (or 1/0, yes/no), got \"%.*s\"",
                              (int)(v > 40 ? 40 : v), p + 7);
                svc_error_from_mcf(err, MCF_EINVAL, SVC_STAGE_PARAMS, NULL, &me);
                return -1;
            }
        }
        p += n;
        if (*p == '&')
            p++;
    }
    return 0;
}

/* ------------------------------------------------------------ request.json */

char *svc__request_json(const svc_job *j)
{
    cJSON *o = cJSON_CreateObject(), *fields;
    char *s;

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
    s = cJSON_PrintUnformatted(o);
    cJSON_Delete(o);
    return s;
}

int svc__record_from_json(svc_record *r, const cJSON *o)
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
        svc_record_free(r);
        return -1;
    }
    snprintf(r->filename, sizeof r->filename, "%s", fn ? fn : "mesh");
    r->has_target = cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(o, "target"));
    return 0;
}

/* -------------------------------------------------------------- state.json */

static void error_to_json(cJSON *o, const svc_error *e)
{
    cJSON_AddStringToObject(o, "kind", svc_code_name(e->code));
    cJSON_AddStringToObject(o, "code", e->name);
    if (e->mcf != MCF_OK)
        cJSON_AddStringToObject(o, "mcf", mcf_status_name(e->mcf));
    if (e->stage != SVC_STAGE_NONE)
        cJSON_AddStringToObject(o, "stage", stage_names[e->stage]);
    if (e->cancel != SVC_CANCEL_NONE)
        cJSON_AddStringToObject(o, "cancel", cancel_names[e->cancel]);
    cJSON_AddStringToObject(o, "detail", e->detail);
}

static mcf_status mcf_of_name(const char *s)
{
#define X(name, code, text) if (strcmp(s, #name) == 0) return MCF_##name;
    MCF_ERRORS(X)
#undef X
    return MCF_OK;
}

/* The form written before the service split: {"http","code","detail"}.
 * The HTTP status tells the stage of an mcf code back (reply.c's map:
 * 400 parameters, 413 and 415 decoding, 422 the run). */
static void error_from_old_json(svc_error *e, const cJSON *o)
{
    const char *code = str_of(o, "code");
    unsigned http = (unsigned)num_of(o, "http");
    mcf_status s = mcf_of_name(code);
    static const struct { const char *name; svc_code code; } own[] = {
        {"EDRAINING", SVC_EDRAINING}, {"EBUSY", SVC_EBUSY},
        {"ESPOOLFULL", SVC_EQUOTA},   {"ENOTFOUND", SVC_ENOTFOUND},
        {"ENOTREADY", SVC_ENOTREADY}, {"ENORESULT", SVC_ENORESULT}};
    size_t i;

    for (i = 0; i < sizeof own / sizeof *own; i++)
        if (strcmp(code, own[i].name) == 0) {
            svc_error_set(e, own[i].code, code, "%s", str_of(o, "detail"));
            return;
        }
    if (strcmp(code, "ELIMIT") == 0 && http == 422 &&
        strstr(str_of(o, "detail"), "--job-timeout")) {
        svc_error_set(e, SVC_ETIMEOUT, code, "%s", str_of(o, "detail"));
        return;
    }
    if (strcmp(code, "EIO") == 0 && http == 500) {
        svc_error_set(e, SVC_ESTORAGE, code, "%s", str_of(o, "detail"));
        return;
    }
    if (s == MCF_OK && strcmp(code, "OK") != 0) {
        svc_error_set(e, SVC_EINTERNAL, code, "%s", str_of(o, "detail"));
        return;
    }
    svc_error_from_mcf(e, s, http == 400 ? SVC_STAGE_PARAMS
                             : http == 413 || http == 415 ? SVC_STAGE_DECODE
                                                          : SVC_STAGE_RUN,
                       NULL, NULL);
    snprintf(e->detail, sizeof e->detail, "%s", str_of(o, "detail"));
}

static void error_from_json(svc_error *e, const cJSON *o)
{
    const char *kind = str_of(o, "kind");
    int i;

    if (!*kind) {
        error_from_old_json(e, o);
        return;
    }
    for (i = 0; i < (int)SVC_EINTERNAL && strcmp(kind, svc_code_name(i)); i++)
        ;
    svc_error_set(e, (svc_code)i, str_of(o, "code"), "%s", str_of(o, "detail"));
    e->mcf = mcf_of_name(str_of(o, "mcf"));
    i = index_of(str_of(o, "stage"), stage_names, 4);
    e->stage = i > 0 ? (svc_stage)i : SVC_STAGE_NONE;
    i = index_of(str_of(o, "cancel"), cancel_names, 5);
    e->cancel = i > 0 ? (svc_cancel_reason)i : SVC_CANCEL_NONE;
}

char *svc__state_json(const svc_job *j)
{
    char *s;
    cJSON *o = cJSON_CreateObject();

    if (!o)
        return NULL;
    cJSON_AddStringToObject(o, "id", j->id);
    cJSON_AddStringToObject(o, "status", svc_job_status_name(j->status));
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
    if (!svc_job_status_terminal(j->status) && j->cancel_asked)
        cJSON_AddStringToObject(o, "cancel_requested",
                                cancel_names[j->cancel_asked]);
    else if (!svc_job_status_terminal(j->status) && j->cancel &&
             (j->cancel_reason == SVC_CANCEL_USER ||
              j->cancel_reason == SVC_CANCEL_CLIENT))
        cJSON_AddStringToObject(o, "cancel_requested",
                                cancel_names[j->cancel_reason]);
    cJSON_AddNumberToObject(o, "result_bytes", (double)j->result_len);
    if (j->params_json)
        cJSON_AddStringToObject(o, "params", j->params_json);
    if (j->status == SVC_JOB_FAILED || j->status == SVC_JOB_CANCELED) {
        cJSON *e = cJSON_AddObjectToObject(o, "error");
        if (e)
            error_to_json(e, &j->err);
    }
    s = cJSON_PrintUnformatted(o);
    cJSON_Delete(o);
    return s;
}

int svc__state_load(svc_job *j, const cJSON *so)
{
    const cJSON *e;
    int i = index_of(str_of(so, "status"), (const char *const[]){
                         "queued", "running", "succeeded", "failed",
                         "canceled"}, 5);

    if (i < 0)
        return -1;
    j->status = (svc_job_status)i;
    j->created = num_of(so, "created");
    j->started = num_of(so, "started");
    j->finished = num_of(so, "finished");
    snprintf(j->scheme, sizeof j->scheme, "%s", str_of(so, "scheme"));
    j->steps_planned = (int)num_of(so, "steps_planned");
    j->time_planned = num_of(so, "time_planned");
    j->step = (int)num_of(so, "step");
    j->t = num_of(so, "t");
    snprintf(j->in_format, sizeof j->in_format, "%s", str_of(so, "in_format"));
    snprintf(j->out_format, sizeof j->out_format, "%s", str_of(so, "out_format"));
    snprintf(j->result_name, sizeof j->result_name, "%s", str_of(so, "result"));
    j->result_len = (size_t)num_of(so, "result_bytes");
    i = index_of(str_of(so, "cancel_requested"), cancel_names, 5);
    if (i > 0) {
        j->cancel = 1;
        j->cancel_reason = (svc_cancel_reason)i;
    }
    if (*str_of(so, "params") && !(j->params_json = strdup(str_of(so, "params"))))
        return -1;
    if ((e = cJSON_GetObjectItemCaseSensitive(so, "error")) != NULL)
        error_from_json(&j->err, e);
    return 0;
}

/* Writers of state.json, one at a time: a snapshot and its write go
 * together, so the last snapshot taken is the last written (a DELETE and
 * the worker's outcome raced, and the older one could land last). Taken
 * before the job lock; held across the write (one small file). */
int svc__write_state(svc_job *j, int durable)
{
    char *s;
    int rc;

    pthread_mutex_lock(&svc_state_mu);
    svc__lock();
    s = svc__state_json(j);
    svc__unlock();
    if (!s) {
        pthread_mutex_unlock(&svc_state_mu);
        return -1;
    }
    rc = srv_spool_write(svc__S.cfg.spool, j->id, "state.json", s, strlen(s),
                         durable);
    pthread_mutex_unlock(&svc_state_mu);
    free(s);
    return rc;
}

/* --------------------------------------------------------------------- log */

void svc__log_job(const svc_job *j, int nv, int nf, double run_s)
{
    cJSON *o = cJSON_CreateObject();
    if (!o)
        return;
    cJSON_AddStringToObject(o, "type", "job");
    cJSON_AddStringToObject(o, "job", j->id);
    cJSON_AddStringToObject(o, "scheme", j->scheme);
    cJSON_AddStringToObject(o, "status", svc_job_status_name(j->status));
    cJSON_AddNumberToObject(o, "vertices", nv);
    cJSON_AddNumberToObject(o, "faces", nf);
    cJSON_AddNumberToObject(o, "steps", j->step);
    cJSON_AddNumberToObject(o, "queue_ms",
                            j->started > 0 ? (j->started - j->created) * 1e3 : 0);
    cJSON_AddNumberToObject(o, "run_ms", run_s * 1e3);
    if (j->recovered)
        cJSON_AddBoolToObject(o, "recovered", 1);
    if (j->status == SVC_JOB_FAILED || j->status == SVC_JOB_CANCELED) {
        cJSON_AddStringToObject(o, "kind", svc_code_name(j->err.code));
        cJSON_AddStringToObject(o, "code", j->err.name);
        cJSON_AddStringToObject(o, "detail", j->err.detail);
    }
    srv_log_json(j->status == SVC_JOB_FAILED &&
                         (j->err.code == SVC_ESTORAGE ||
                          j->err.code == SVC_EINTERNAL ||
                          j->err.code == SVC_ENOMEM)
                     ? SRV_LOG_ERROR : SRV_LOG_INFO, o);
}
