/* SPDX-License-Identifier: MIT */
/*
 * svc_state.c - what the job service keeps of a job in its store, to
 * text and back, from plain copies and without a lock: request.json (what
 * the client asked: the parameters it gave, the upload's name, whether a
 * target and the fields document came with it), state.json (everything
 * needed to serve the job after a restart); the parameters of a request
 * in the form the REST door receives them and older request.json files
 * hold them; and the one log line of a finished job.
 *
 * request.json: {"id", "params" (api_params_given_json: parses back to
 * the same parameters), "fields": [] (form fields, older spools),
 * "filename", "target", "created", "memory_estimate", and "query":
 * "fields=true" when the fields document was asked for}.
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

static const char *const stage_names[] = {"", "params", "decode", "run"};
static const char *const cancel_names[] = {"", "user", "shutdown", "timeout",
                                           "client", "cpu"};

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

/* -------------------------------------------------- a request's parameters */

const char *const svc_query_keys[] = {"stream", "phases", "fields", "measures", NULL};

int svc_query_flag(const char *query, const char *key, int *on, svc_error *err)
{
    static const char *const yes[] = {"true", "1", "yes"}, *const no[] = {"false", "0", "no"};
    const char *p = query;
    size_t kl = strlen(key);

    *on = 0;
    while (p && *p) {
        size_t n = strcspn(p, "&");
        if (n > kl && strncmp(p, key, kl) == 0 && p[kl] == '=') {
            size_t k, v = n - kl - 1;
            const char *val = p + kl + 1;
            int found = 0;
            for (k = 0; k < 3 && !found; k++) {
                if (strlen(yes[k]) == v && strncmp(val, yes[k], v) == 0)
                    found = 1, *on = 1;
                else if (strlen(no[k]) == v && strncmp(val, no[k], v) == 0)
                    found = 1, *on = 0;
            }
            if (!found) {
                svc_error_set(err, SVC_P_PARAM_INVALID, "parameter '%s' "
                              "must be true or false (or 1/0, yes/no), got "
                              "\"%.*s\"", key, (int)(v > 40 ? 40 : v), val);
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
    cJSON *o = cJSON_CreateObject();
    char *s = NULL;
    int ok = o != NULL;

    ok = ok && cJSON_AddStringToObject(o, "id", j->id);
    ok = ok && (!(j->keep_fields || j->measures) ||
                cJSON_AddStringToObject(o, "query", j->keep_fields && j->measures
                                                        ? "fields=true&measures=true"
                                                        : j->keep_fields ? "fields=true"
                                                                         : "measures=true"));
    ok = ok && cJSON_AddStringToObject(o, "params", j->params_given ? j->params_given : "{}");
    ok = ok && cJSON_AddArrayToObject(o, "fields");
    ok = ok && cJSON_AddStringToObject(o, "filename", j->filename);
    ok = ok && cJSON_AddBoolToObject(o, "target", j->has_target);
    ok = ok && cJSON_AddNumberToObject(o, "created", j->created);
    ok = ok && cJSON_AddNumberToObject(o, "memory_estimate", j->mem_estimate);
    if (ok)
        s = cJSON_PrintUnformatted(o);
    cJSON_Delete(o);
    return s;
}

/* The texts of params: the given ones (request.json's) and the shown. */
static int params_texts(svc_job *j)
{
    cJSON *g = api_params_given_json(&j->params), *a = api_params_to_json(&j->params);

    free(j->params_given);
    j->params_given = g ? cJSON_PrintUnformatted(g) : NULL;
    if (!j->params_json)
        j->params_json = a ? cJSON_PrintUnformatted(a) : NULL;
    cJSON_Delete(g);
    cJSON_Delete(a);
    return j->params_given && j->params_json ? 0 : -1;
}

int svc__request_load(svc_job *j, const cJSON *o, const api_limits *lim)
{
    const char *query = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(o, "query"));
    const char *params = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(o, "params"));
    const char *fn = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(o, "filename"));
    const cJSON *fields = cJSON_GetObjectItemCaseSensitive(o, "fields");
    mcf_error err;
    svc_error e;
    double mem = num_of(o, "memory_estimate");

    if (!cJSON_IsObject(o) ||
        api_params_parse_request(&j->params, params, cJSON_IsArray(fields) ? fields : NULL,
                                 query, svc_query_keys, lim, &err) != MCF_OK ||
        svc_query_flag(query, "fields", &j->keep_fields, &e) != 0 ||
        svc_query_flag(query, "measures", &j->measures, &e) != 0)
        return -1;
    snprintf(j->filename, sizeof j->filename, "%s", fn ? fn : "mesh");
    j->has_target = cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(o, "target"));
    j->created = num_of(o, "created");
    /* svc_admit.c; 0 (re-estimated after decoding) when absent */
    j->mem_estimate = mem > 0 ? mem : 0;
    return params_texts(j);
}

/* -------------------------------------------------------------- state.json */

/* The stage a job error's code stands for (params, decode, run), "" for
 * the service's own codes. */
static const char *stage_of(svc_code c)
{
    return c == SVC_EPARAMS ? stage_names[1] : c == SVC_EINPUT ? stage_names[2]
           : c == SVC_EMESH ? stage_names[3] : "";
}

static void error_to_json(cJSON *o, const svc_error *e)
{
    svc_code c = svc_error_code(e);
    mcf_status s = svc_problem_mcf(e->problem);

    cJSON_AddStringToObject(o, "kind", svc_code_name(c));
    cJSON_AddStringToObject(o, "code", svc_problem_name(e->problem));
    if (s != MCF_OK)
        cJSON_AddStringToObject(o, "mcf", mcf_status_name(s));
    if (*stage_of(c))
        cJSON_AddStringToObject(o, "stage", stage_of(c));
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

/* A failure of the core or the codecs with its detail as stored. */
static void error_from_mcf_json(svc_error *e, mcf_status s, api_job_stage stage,
                                const cJSON *o)
{
    svc_error_from_mcf(e, s, stage, NULL, NULL);
    snprintf(e->detail, sizeof e->detail, "%s", str_of(o, "detail"));
}

/* The form written before the service split: {"http","code","detail"}.
 * The HTTP status tells the stage of an mcf code back (400 parameters,
 * 413 and 415 decoding, 422 the run). */
static void error_from_old_json(svc_error *e, const cJSON *o)
{
    const char *code = str_of(o, "code");
    unsigned http = (unsigned)num_of(o, "http");
    mcf_status s = mcf_of_name(code);
    static const struct { const char *name; svc_problem p; } own[] = {
        {"EDRAINING", SVC_P_DRAINING}, {"EBUSY", SVC_P_BUSY},
        {"ESPOOLFULL", SVC_P_SPOOL_FULL}, {"ENOTFOUND", SVC_P_NOT_FOUND},
        {"ENOTREADY", SVC_P_NOT_READY}, {"ENORESULT", SVC_P_NO_RESULT}};
    size_t i;

    for (i = 0; i < sizeof own / sizeof *own; i++)
        if (strcmp(code, own[i].name) == 0) {
            svc_error_set(e, own[i].p, "%s", str_of(o, "detail"));
            return;
        }
    if (strcmp(code, "ELIMIT") == 0 && http == 422 &&
        strstr(str_of(o, "detail"), "--job-timeout")) {
        svc_error_set(e, SVC_P_TIMEOUT, "%s", str_of(o, "detail"));
        return;
    }
    if (strcmp(code, "EIO") == 0 && http == 500) {
        svc_error_set(e, SVC_P_STORAGE, "%s", str_of(o, "detail"));
        return;
    }
    if (s == MCF_OK && strcmp(code, "OK") != 0) {
        svc_error_set(e, SVC_P_INTERNAL, "%s", str_of(o, "detail"));
        return;
    }
    error_from_mcf_json(e, s, http == 400 ? API_JOB_PARAMS
                              : http == 413 || http == 415 ? API_JOB_DECODE
                                                           : API_JOB_RUN, o);
}

static void error_from_json(svc_error *e, const cJSON *o)
{
    const char *kind = str_of(o, "kind");
    svc_problem p;
    int i;

    if (!*kind) {
        error_from_old_json(e, o);
        return;
    }
    for (i = 0; i < (int)SVC_EUNAVAILABLE && strcmp(kind, svc_code_name(i)); i++)
        ;
    if (svc__problem_find((svc_code)i, str_of(o, "code"), &p) == 0)
        svc_error_set(e, p, "%s", str_of(o, "detail"));
    else /* a row of a later version: its kind's failure of the stage */
        error_from_mcf_json(e, mcf_of_name(str_of(o, "mcf")),
                            (api_job_stage)(index_of(str_of(o, "stage"), stage_names, 4) > 0
                                            ? index_of(str_of(o, "stage"), stage_names, 4)
                                            : API_JOB_RUN), o);
    i = index_of(str_of(o, "cancel"), cancel_names, 6);
    e->cancel = i > 0 ? (svc_cancel_reason)i : SVC_CANCEL_NONE;
}

char *svc__state_json(const svc_state_rec *r)
{
    char *s;
    cJSON *o = cJSON_CreateObject();

    if (!o)
        return NULL;
    cJSON_AddStringToObject(o, "id", r->id);
    cJSON_AddStringToObject(o, "status", svc_job_status_name(r->status));
    cJSON_AddNumberToObject(o, "created", r->created);
    cJSON_AddNumberToObject(o, "started", r->started);
    cJSON_AddNumberToObject(o, "finished", r->finished);
    cJSON_AddStringToObject(o, "scheme", r->scheme);
    cJSON_AddNumberToObject(o, "steps_planned", r->steps_planned);
    cJSON_AddNumberToObject(o, "time_planned", r->time_planned);
    cJSON_AddNumberToObject(o, "step", r->step);
    add_num(o, "t", r->t);
    cJSON_AddStringToObject(o, "in_format", r->in_format);
    cJSON_AddStringToObject(o, "out_format", r->out_format);
    cJSON_AddStringToObject(o, "result", r->result_name);
    /* A cancel asked of a running job holds across a restart. */
    if (!svc_job_status_terminal(r->status) && r->cancel_requested)
        cJSON_AddStringToObject(o, "cancel_requested",
                                cancel_names[r->cancel_requested]);
    cJSON_AddNumberToObject(o, "result_bytes", (double)r->result_len);
    if (r->params_json)
        cJSON_AddStringToObject(o, "params", r->params_json);
    if (r->status == SVC_JOB_FAILED || r->status == SVC_JOB_CANCELED) {
        cJSON *e = cJSON_AddObjectToObject(o, "error");
        if (e)
            error_to_json(e, &r->err);
    }
    s = cJSON_PrintUnformatted(o);
    cJSON_Delete(o);
    return s;
}

int svc__state_parse(const cJSON *so, svc_state_rec *r, char **params_json)
{
    const cJSON *e;
    int i = index_of(str_of(so, "status"), (const char *const[]){
                         "queued", "running", "succeeded", "failed",
                         "canceled"}, 5);

    memset(r, 0, sizeof *r);
    *params_json = NULL;
    if (i < 0)
        return -1;
    r->status = (svc_job_status)i;
    snprintf(r->id, sizeof r->id, "%s", str_of(so, "id"));
    r->created = num_of(so, "created");
    r->started = num_of(so, "started");
    r->finished = num_of(so, "finished");
    snprintf(r->scheme, sizeof r->scheme, "%s", str_of(so, "scheme"));
    r->steps_planned = (int)num_of(so, "steps_planned");
    r->time_planned = num_of(so, "time_planned");
    r->step = (int)num_of(so, "step");
    r->t = num_of(so, "t");
    snprintf(r->in_format, sizeof r->in_format, "%s", str_of(so, "in_format"));
    snprintf(r->out_format, sizeof r->out_format, "%s", str_of(so, "out_format"));
    snprintf(r->result_name, sizeof r->result_name, "%s", str_of(so, "result"));
    r->result_len = (size_t)num_of(so, "result_bytes");
    i = index_of(str_of(so, "cancel_requested"), cancel_names, 5);
    r->cancel_requested = i > 0 ? (svc_cancel_reason)i : SVC_CANCEL_NONE;
    if (*str_of(so, "params") && !(*params_json = strdup(str_of(so, "params"))))
        return -1;
    if ((e = cJSON_GetObjectItemCaseSensitive(so, "error")) != NULL)
        error_from_json(&r->err, e);
    return 0;
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
    if (j->cpu_budget > 0) {
        cJSON_AddNumberToObject(o, "cpu_s", j->cpu_used);
        cJSON_AddNumberToObject(o, "cpu_threads_s", j->cpu_threads);
        cJSON_AddNumberToObject(o, "cpu_budget_s", j->cpu_budget);
    }
    if (j->recovered)
        cJSON_AddBoolToObject(o, "recovered", 1);
    if (j->status == SVC_JOB_FAILED || j->status == SVC_JOB_CANCELED) {
        cJSON_AddStringToObject(o, "kind", svc_code_name(svc_error_code(&j->err)));
        cJSON_AddStringToObject(o, "code", svc_problem_name(j->err.problem));
        cJSON_AddStringToObject(o, "detail", j->err.detail);
    }
    srv_log_json(j->status == SVC_JOB_FAILED &&
                         (svc_error_code(&j->err) == SVC_ESTORAGE ||
                          svc_error_code(&j->err) == SVC_EINTERNAL ||
                          svc_error_code(&j->err) == SVC_ENOMEM)
                     ? SRV_LOG_ERROR : SRV_LOG_INFO, o);
}
