/* SPDX-License-Identifier: MIT */
/*
 * api_metrics.c - the one metrics document of a smoothing run, for every
 * door: `mcf smooth --metrics FILE` and the daemon's job metrics
 * (GET /v1/jobs/{id}/metrics, the multipart/mixed part, the last ndjson
 * line) are this builder's output, so the same request yields the same
 * keys, and the same numbers up to the door's own facts (paths, job id,
 * timings).
 *
 * The measurements happen in two calls around the flow, because the flow
 * changes the mesh in place: api_metrics_before on the mesh as the flow
 * receives it, api_metrics_after on the result.
 * Each is one mcf_mesh_inspect, one mcf_curvature_summarize and, with a
 * target, one mcf_compare: linear in the mesh (radix sorts), a small
 * fraction of a flow step (about 0.06 s per call on the 35k-vertex bunny).
 * A door may skip both (api_job_request.light): the light document keeps
 * every key, the measured ones null (measured false), for a request that
 * did not ask for them; on a 7M-vertex scan the two cost 92.5 s of a
 * job's 876 s wall (lab/bench/README.md).
 * What only a door knows (names, byte counts, phase timings) comes in an
 * api_metrics_run; a number a door does not have is NaN and prints as null,
 * so a key never disappears because of the door that answered.
 *
 * Volumes: every volume in the document (input/output info and volume,
 * flow.volume0/volume1, each flow.log entry) and in the daemon's step
 * stream is one quantity, mcf_mesh_volume: the signed volume enclosed by
 * the surface and the input's coordinate origin (divergence theorem), in
 * input units. It is the enclosed volume of a closed mesh wherever the
 * origin lies; on an open mesh it depends on the origin.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "api_internal.h"

static int str(cJSON *o, const char *key, const char *s)
{
    return api__json_put(o, key, s ? cJSON_CreateString(s) : cJSON_CreateNull());
}

/* A new object attached under key, or NULL (then the tree is incomplete
 * and the caller drops it). */
static cJSON *obj(cJSON *o, const char *key)
{
    cJSON *c = cJSON_CreateObject();
    return api__json_put(o, key, c) ? c : NULL;
}

void api_metrics_init(api_metrics *mt)
{
    memset(mt, 0, sizeof *mt);
}

static mcf_status measure(api_metrics *mt, int k, const mcf_mesh *m,
                          const mcf_mesh *target, mcf_error *err)
{
    mcf_mesh_info info;
    mcf_curvature_summary cs;
    mcf_compare_result cmp;
    mcf_status rc;

    if (!mt || !m)
        return api__fail(err, MCF_EINVAL, "metrics: NULL argument");
    if ((rc = mcf_mesh_inspect(m, &info, err)) != MCF_OK ||
        (rc = mcf_curvature_summarize(m, &cs, err)) != MCF_OK ||
        (target && (rc = mcf_compare(m, target, &cmp, err)) != MCF_OK))
        return rc;
    mt->info[k] = info;
    mt->curv[k] = cs;
    if (target)
        mt->cmp[k] = cmp;
    mt->measured |= 1 << k;
    mt->target |= (target != NULL) << k;
    return MCF_OK;
}

mcf_status api_metrics_before(api_metrics *mt, const mcf_mesh *m,
                              const mcf_mesh *target, mcf_error *err)
{
    return measure(mt, 0, m, target, err);
}

mcf_status api_metrics_after(api_metrics *mt, const mcf_mesh *m,
                             const mcf_mesh *target, mcf_error *err)
{
    return measure(mt, 1, m, target, err);
}

void api_metrics_run_init(api_metrics_run *r)
{
    memset(r, 0, sizeof *r);
    r->input_format = r->output_format = API_FMT_UNKNOWN;
    r->quantization_max_error = NAN;
    r->queue_s = r->read_s = r->decode_s = NAN;
    r->flow_s = r->encode_s = r->write_s = r->total_s = r->metrics_s = NAN;
    r->peak_rss_bytes = NAN;
}

static const char *format_name(api_format f)
{
    return f == API_FMT_UNKNOWN ? NULL : api_format_name(f);
}

/* The core's warnings about the result (mcf_flow_stats.warnings: folded
 * faces, collapsed edges, lost area, a negligible amount of smoothing),
 * one string each, the warning's name ("folds", "edge_collapse", ...,
 * from the core's MCF_WARNINGS table), in bit order; [] when there is
 * none. The numbers behind them are in flow (folded_faces,
 * min_edge_ratio, area_ratio, strength). */
static cJSON *warnings_json(const mcf_flow_stats *st)
{
    cJSON *a = cJSON_CreateArray();
    unsigned bit;

    for (bit = 1; a && bit; bit <<= 1) {
        const char *name = mcf_warning_name(bit);
        cJSON *s;
        if (!(st->warnings & bit) || !name)
            continue;
        s = cJSON_CreateString(name);
        if (!s || !cJSON_AddItemToArray(a, s)) {
            cJSON_Delete(s);
            cJSON_Delete(a);
            return NULL;
        }
    }
    return a;
}

/* A mesh's info (k 0: before the flow, 1: after), null when not
 * measured (the light document). */
static cJSON *info_json(const api_metrics *mt, int k)
{
    return (mt->measured >> k) & 1 ? api_json_mesh_info(&mt->info[k], NULL)
                                   : cJSON_CreateNull();
}

/* The timings object: the door's phases, null where the door has none. */
static int timings(cJSON *t, const api_metrics_run *r)
{
    int ok = 1;
    ok = ok && api__json_num(t, "queue_s", r->queue_s);
    ok = ok && api__json_num(t, "read_s", r->read_s);
    ok = ok && api__json_num(t, "decode_s", r->decode_s);
    ok = ok && api__json_num(t, "flow_s", r->flow_s);
    ok = ok && api__json_num(t, "encode_s", r->encode_s);
    ok = ok && api__json_num(t, "write_s", r->write_s);
    ok = ok && api__json_num(t, "metrics_s", r->metrics_s);
    ok = ok && api__json_num(t, "total_s", r->total_s);
    return ok;
}

/* The comparison with the target: before and after the flow, and the
 * after's members once more at the top (the daemon's first layout). */
static cJSON *compare_json(const api_metrics *mt, const api_metrics_run *r)
{
    cJSON *c = api_json_compare(&mt->cmp[1]);
    int ok = c != NULL;
    if (!ok)
        return NULL;
    ok = ok && str(c, "target", r->target_name);
    ok = ok && ((mt->target & 1) ? api__json_put(c, "before", api_json_compare(&mt->cmp[0]))
                                 : api__json_put(c, "before", cJSON_CreateNull()));
    ok = ok && api__json_put(c, "after", api_json_compare(&mt->cmp[1]));
    if (!ok) {
        cJSON_Delete(c);
        return NULL;
    }
    return c;
}

cJSON *api_metrics_json(const api_metrics *mt, const api_params *p,
                        const mcf_flow_stats *st, const api_metrics_run *r)
{
    const mcf_scheme_info *si;
    cJSON *o, *x = NULL, *c = NULL;
    int ok;

    int measured = mt ? (mt->measured & 3) == 3 : 0;

    if (!mt || !p || !st || !r || (!measured && (mt->measured & 3)))
        return NULL;
    si = mcf_scheme_get(p->flow.scheme);
    o = cJSON_CreateObject();
    ok = o != NULL;
    ok = ok && str(o, "command", "smooth");
    ok = ok && str(o, "job", r->job);
    ok = ok && str(o, "scheme", si ? si->name : NULL);
    ok = ok && api__json_put(o, "params", api_params_to_json(p));
    ok = ok && api__json_put(o, "warnings", warnings_json(st));

    ok = ok && (x = obj(o, "input")) != NULL;
    ok = ok && str(x, "path", r->input_name);
    ok = ok && str(x, "format", format_name(r->input_format));
    ok = ok && api__json_num(x, "bytes", (double)r->input_bytes);
    ok = ok && api__json_put(x, "info", info_json(mt, 0));
    /* "mesh": the daemon's first name for "info", kept for its clients */
    ok = ok && api__json_put(x, "mesh", info_json(mt, 0));

    ok = ok && (x = obj(o, "output")) != NULL;
    ok = ok && str(x, "path", r->output_name);
    ok = ok && str(x, "format", format_name(r->output_format));
    ok = ok && api__json_num(x, "bytes", (double)r->output_bytes);
    ok = ok && api__json_num(x, "vertices", measured ? mt->info[1].nv : r->nv);
    ok = ok && api__json_num(x, "faces", measured ? mt->info[1].nf : r->nf);
    ok = ok && api__json_num(x, "area", measured ? mt->info[1].area : st->area1);
    ok = ok && api__json_num(x, "volume", measured ? mt->info[1].volume : st->volume1);
    ok = ok && api__json_num(x, "quantization_max_error", r->quantization_max_error);
    ok = ok && str(x, "not_kept", r->not_kept);
    ok = ok && api__json_put(x, "info", info_json(mt, 1));

    ok = ok && (c = obj(o, "curvature")) != NULL;
    ok = ok && api__json_put(c, "before", measured ? api_json_curvature(&mt->curv[0])
                                                   : cJSON_CreateNull());
    ok = ok && api__json_put(c, "after", measured ? api_json_curvature(&mt->curv[1])
                                                  : cJSON_CreateNull());

    ok = ok && api__json_put(o, "flow", api_json_flow_stats(st));
    if (ok && (mt->target & 2))
        ok = api__json_put(o, "compare", compare_json(mt, r));

    ok = ok && (x = obj(o, "timings")) != NULL && timings(x, r);
    /* "timing": the daemon's first name for "timings", kept for its
     * clients */
    ok = ok && (x = obj(o, "timing")) != NULL && timings(x, r);
    ok = ok && api__json_num(o, "peak_rss_bytes", r->peak_rss_bytes);
    ok = ok && api__json_put(o, "measured", cJSON_CreateBool(measured));
    if (!ok) {
        cJSON_Delete(o);
        return NULL;
    }
    return o;
}
