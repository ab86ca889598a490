/* SPDX-License-Identifier: MIT */
/*
 * upload.c - request bodies of the REST door: the checks of an upload's
 * head (415, 413, and 503 when busy or draining, answered before the body
 * when the client waits for it), the raw or multipart/form-data body
 * (fields mesh, target, params and plain parameter fields, each within
 * its limit), and the submission to the job service once the body is
 * complete.
 *
 * --max-upload bounds the body: a raw mesh, or a multipart body's mesh
 * and target together (plus the parameters and the framing): a
 * Content-Length over it is a 413 from the head, before any byte of the
 * body (and before 100 Continue). libmicrohttpd 0.9.75 cannot answer in
 * the middle of an upload, so an error found while reading (a body
 * without a declared length past the limit, a part over it, broken
 * multipart) is written on the socket at once, the rest discarded up to
 * the drain bound (rest_internal.h, SRV_DRAIN_MAX), and the connection closed.
 */
#include <ctype.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "rest_internal.h"

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

/* Content-Length above SRV_DRAIN_MAX: refused before it is read. A body
 * a busy daemon reads and discards so that its client, which is sending
 * it, hears the 503: an answer queued before the body makes MHD stop
 * reading, and the client's next bytes meet a reset. Above this, the
 * early answer (and the reset) is the lesser evil. */
static int big_body(struct MHD_Connection *c)
{
    const char *h = MHD_lookup_connection_value(c, MHD_HEADER_KIND,
                                                MHD_HTTP_HEADER_CONTENT_LENGTH);
    return h && strtoull(h, NULL, 10) > SRV_DRAIN_MAX;
}

static enum MHD_Result on_part(void *cls, enum MHD_ValueKind kind,
                               const char *key, const char *filename,
                               const char *content_type,
                               const char *transfer_encoding, const char *data,
                               uint64_t off, size_t size)
{
    rest_request *r = cls;
    const srv_config *cfg = r->door->cfg;
    api_buf *dst = NULL;
    const char *limit_name = "--max-upload";
    size_t limit = cfg->svc.lim.max_input_bytes;

    (void)kind;
    (void)content_type;
    (void)transfer_encoding;
    if (r->has_perr)
        return MHD_NO;
    if (!key || !*key) {
        /* MHD passes a part without Content-Disposition name as NULL:
         * no headers at all, only a filename or a Content-Type, or a mesh
         * whose bytes contain the boundary line. */
        svc_error_set(&r->perr, SVC_P_INPUT_INVALID, "a multipart part has no "
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
        limit = cfg->svc.lim.max_json_bytes;
        limit_name = "the JSON size limit";
    } else if (filename) {
        svc_error_set(&r->perr, SVC_P_INPUT_INVALID, "unknown multipart file field "
                        "'%s' (accepted: mesh, target, params, or a parameter "
                        "as a plain field)", key);
        r->has_perr = 1;
        return MHD_NO;
    } else {
        /* A parameter as a plain field: scheme=desbrun2. */
        cJSON *last = cJSON_GetArrayItem(r->fields, cJSON_GetArraySize(r->fields) - 1);
        r->fields_bytes += size + strlen(key);
        if (r->fields_bytes > cfg->svc.lim.max_json_bytes) {
            svc_error_set(&r->perr, SVC_P_INPUT_LIMIT, "multipart parameter fields "
                            "exceed %zu bytes", cfg->svc.lim.max_json_bytes);
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
        svc_error_set(&r->perr, SVC_P_INPUT_INVALID, "multipart field '%s' is "
                        "given twice: send exactly one '%s' part", key, key);
        r->has_perr = 1;
        return MHD_NO;
    }
    /* the mesh and the target share --max-upload */
    if (dst->len + size > limit ||
        (dst != &r->params && r->mesh.len + r->target.len + size > limit)) {
        if (dst != &r->params && r->mesh.len + r->target.len > dst->len)
            svc_error_set(&r->perr, SVC_P_INPUT_LIMIT, "multipart fields "
                            "'mesh' and 'target' together are larger than "
                            "%zu bytes (--max-upload: the whole upload)", limit);
        else
            svc_error_set(&r->perr, SVC_P_INPUT_LIMIT, "multipart field '%s' is "
                            "larger than %zu bytes (%s)", key, limit, limit_name);
        r->has_perr = 1;
        return MHD_NO;
    }
    if (api_buf_append(dst, data, size) != MCF_OK) {
        svc_error_set(&r->perr, SVC_P_NOMEM, "out of memory reading "
                        "multipart field '%s'", key);
        r->has_perr = 1;
        return MHD_NO;
    }
    return MHD_YES;
}

void rest_upload_consume(rest_request *r, const char *data, size_t size)
{
    const srv_config *cfg = r->door->cfg;

    r->bytes_in += size;
    if (r->has_perr)
        return; /* discard: the error is answered at the end */
    /* without a Content-Length, the memory is reserved as bytes come */
    if (svc_upload_reserve(r->door->svc, &r->mem_held, r->bytes_in, &r->perr) != 0) {
        r->has_perr = 1;
        return;
    }
    if (r->multipart && r->bytes_in > cfg->max_body) {
        svc_error_set(&r->perr, SVC_P_INPUT_LIMIT, "the multipart body exceeds "
                        "%zu bytes, the most it may hold with --max-upload %zu "
                        "(the mesh and a target together, and the "
                        "parameters)", cfg->max_body,
                        cfg->svc.lim.max_input_bytes);
        r->has_perr = 1;
        return;
    }
    if (!r->multipart && r->bytes_in > cfg->svc.lim.max_input_bytes) {
        svc_error_set(&r->perr, SVC_P_INPUT_LIMIT, "the request body exceeds "
                        "%zu bytes (--max-upload)", cfg->svc.lim.max_input_bytes);
        r->has_perr = 1;
        return;
    }
    if (r->multipart) {
        if (MHD_post_process(r->pp, data, size) != MHD_YES && !r->has_perr) {
            svc_error_set(&r->perr, SVC_P_INPUT_DECODE, "malformed "
                            "multipart/form-data body");
            r->has_perr = 1;
        }
    } else if (api_buf_append(&r->mesh, data, size) != MCF_OK) {
        svc_error_set(&r->perr, SVC_P_NOMEM, "out of memory reading "
                        "the body");
        r->has_perr = 1;
    }
}

/* The head of POST /smooth, /v1/smooth or /v1/jobs: decide everything
 * from the headers. */
enum MHD_Result rest_upload_begin(rest_request *r, struct MHD_Connection *c)
{
    const srv_config *cfg = r->door->cfg;
    svc_error p;
    const char *h;
    char stream[32];
    unsigned long long n = 0;

    h = rest_query_value(r, "phases", stream, sizeof stream);
    if (h && strcmp(h, "true") != 0 && strcmp(h, "false") != 0)
        return rest_send_problemf(r, c, SVC_P_PARAM_INVALID, "parameter 'phases' must be "
                                  "true or false, got \"%s\"", h);
    r->phases = h && strcmp(h, "true") == 0;
    h = rest_query_value(r, "stream", stream, sizeof stream);
    if (r->phases && !(h && r->rt == RT_SMOOTH))
        return rest_send_problemf(r, c, SVC_P_PARAM_INVALID, "parameter 'phases' is only "
                                  "for /smooth?stream=ndjson (GET /v1/jobs/ID/events always "
                                  "sends them, as 'work' events)");
    if (r->rt == RT_SMOOTH) {
        const char *acc = MHD_lookup_connection_value(c, MHD_HEADER_KIND,
                                                      MHD_HTTP_HEADER_ACCEPT);
        if (h && strcmp(h, "ndjson") != 0)
            return rest_send_problemf(r, c, SVC_P_PARAM_INVALID, "parameter 'stream' must be "
                                      "\"ndjson\", got \"%s\"", h);
        r->md = h ? MODE_NDJSON
                  : (acc && strstr(acc, "multipart/mixed")) ? MODE_MIXED
                                                            : MODE_SYNC;
    } else {
        if (h)
            return rest_send_problemf(r, c, SVC_P_PARAM_INVALID, "parameter 'stream' is only "
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
            return rest_send_problemf(r, c, SVC_P_INPUT_DECODE, "cannot parse the "
                                      "multipart/form-data header '%s' (boundary?)", h);
    } else if (h && !raw_mesh_type(h)) {
        return rest_send_problemf(r, c, SVC_P_INPUT_FORMAT, "Content-Type '%s' is not a mesh: "
                                  "send multipart/form-data with a 'mesh' field, or the "
                                  "mesh bytes as application/octet-stream or model/*", h);
    }
    h = MHD_lookup_connection_value(c, MHD_HEADER_KIND,
                                    MHD_HTTP_HEADER_CONTENT_LENGTH);
    if (h) {
        char *end;
        size_t lim = r->multipart ? cfg->max_body : cfg->svc.lim.max_input_bytes;
        errno = 0;
        n = strtoull(h, &end, 10);
        if (errno == 0 && end != h && n > lim) {
            if (r->multipart)
                svc_error_set(&p, SVC_P_INPUT_LIMIT, "Content-Length %llu "
                                "exceeds %zu bytes, the most a multipart body "
                                "may hold with --max-upload %zu (the mesh and "
                                "a target together, and the parameters)", n,
                                lim, cfg->svc.lim.max_input_bytes);
            else
                svc_error_set(&p, SVC_P_INPUT_LIMIT, "Content-Length %llu exceeds "
                                "the limit of %zu bytes (--max-upload)", n, lim);
            return rest_send_problem(r, c, &p, NULL);
        }
        if (errno != 0 || end == h)
            n = 0;
        r->declared = (size_t)n;
    }
    /* Busy or draining: say so before the body only when the client waits
     * for it (Expect: 100-continue) or the body is over SRV_DRAIN_MAX. A
     * client that is already sending would otherwise see its connection
     * reset by the close that follows an early answer, and lose the 503:
     * its body is read, discarded (never buffered) and answered. */
    h = MHD_lookup_connection_value(c, MHD_HEADER_KIND, MHD_HTTP_HEADER_EXPECT);
    if (svc_draining(r->door->svc))
        svc_error_set(&p, SVC_P_DRAINING, "the daemon is shutting down "
                        "and accepts no new jobs");
    else if (!svc_can_accept(r->door->svc))
        svc_error_set(&p, SVC_P_BUSY, "the job queue is full; retry "
                        "after the Retry-After delay");
    /* the memory the body will take, reserved by its declared size */
    else if (n > 0 && svc_upload_reserve(r->door->svc, &r->mem_held, (size_t)n, &p) != 0)
        ;
    else
        return MHD_YES;
    if ((h && strncasecmp(h, "100-continue", 12) == 0) || big_body(c))
        return rest_send_problem(r, c, &p, NULL);
    r->perr = p;
    r->has_perr = r->perr_head = 1;
    return MHD_YES;
}


/* The job's parameters, parsed once here: the params field (JSON), then
 * the plain form fields, then the query string (api_params_parse_request,
 * as the gRPC door reaches api_params_set_json: the door calls the
 * parser, not the service), and the daemon's `fields` and `measures`
 * keys. 0, or -1 and
 * *e. */
static int request_params(rest_request *r, svc_request *rq, svc_error *e)
{
    const char *q = rest_query_of(r);
    mcf_error err = {MCF_OK, ""};
    mcf_status st;

    st = api_params_parse_request(&rq->params,
                                  r->has_params ? (r->params.data ? r->params.data : "") : NULL,
                                  r->fields, q, svc_query_keys, svc_limits(r->door->svc), &err);
    if (st != MCF_OK) {
        svc_error_from_mcf(e, st, API_JOB_PARAMS, NULL, &err);
        return -1;
    }
    if (svc_query_flag(q, "fields", &rq->fields, e) != 0 ||
        svc_query_flag(q, "measures", &rq->measures, e) != 0)
        return -1;
    /* the metrics sent with the result (multipart/mixed, the stream's
     * last line and its steps' volumes) are asked for */
    rq->measures |= r->md == MODE_MIXED || r->md == MODE_NDJSON;
    return 0;
}

/* The body is complete: hand the job over. */
enum MHD_Result rest_upload_submit(rest_request *r, struct MHD_Connection *c)
{
    svc_request rq;
    svc_error e;
    svc_job *j = NULL;
    char loc[96];
    int rc;

    if (r->pp) {
        if (MHD_destroy_post_processor(r->pp) != MHD_YES && !r->has_perr) {
            svc_error_set(&r->perr, SVC_P_INPUT_DECODE, "malformed or truncated "
                            "multipart/form-data body");
            r->has_perr = 1;
        }
        r->pp = NULL;
    }
    if (r->has_perr)
        return rest_send_problem(r, c, &r->perr, NULL);
    if (r->multipart && !r->has_mesh)
        return rest_send_problemf(r, c, SVC_P_INPUT_INVALID, "multipart field 'mesh' "
                                  "is missing: send the mesh as -F mesh=@file");
    if (r->mesh.len == 0)
        return rest_send_problemf(r, c, SVC_P_INPUT_INVALID, "the mesh is empty: send "
                                  "it as the body or as multipart field 'mesh'");
    srv_metrics_upload(r->mesh.len);

    svc_request_init(&rq);
    if (request_params(r, &rq, &e) != 0) {
        svc_request_free(&rq);
        return rest_send_problem(r, c, &e, NULL);
    }
    snprintf(rq.filename, sizeof rq.filename, "%s",
             r->filename[0] ? r->filename : "mesh");
    rq.input = api_buf_detach(&r->mesh, &rq.input_len);
    if (r->has_target)
        rq.target = api_buf_detach(&r->target, &rq.target_len);
    rq.keep_result = r->md == MODE_SYNC || r->md == MODE_MIXED;
    rc = svc_submit(r->door->svc, &rq, &j, &e);
    svc_upload_release(r->door->svc, &r->mem_held);  /* the bytes are in the store, or gone */
    if (rc != 0)
        return rest_send_problem(r, c, &e, NULL);
    r->job = j;
    snprintf(r->id, sizeof r->id, "%s", svc_job_id(j));
    if (r->md == MODE_ASYNC) {
        struct MHD_Response *resp;
        if (!(resp = rest_json_response(rest_job_json(j, NULL),
                                        "application/json", 0)))
            return MHD_NO;
        snprintf(loc, sizeof loc, "/v1/jobs/%s", r->id);
        MHD_add_response_header(resp, MHD_HTTP_HEADER_LOCATION, loc);
        MHD_add_response_header(resp, "X-Job-Id", r->id);
        return rest_respond(r, c, 202, resp);
    }
    r->sync_owner = r->md != MODE_NDJSON;
    /* Nobody else knows this job's ID yet: when this client goes, so does
     * the reason to run it. */
    if (rest_waiter_start(&r->w, r->door, j, c, 0, 1) != 0)
        return rest_send_problemf(r, c, SVC_P_NOMEM, "out of memory waiting "
                                  "for job %s", r->id);
    r->waiting = 1;
    return rest_wait_or_answer(r, c);
}
