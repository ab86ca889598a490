/* SPDX-License-Identifier: MIT */
/*
 * api_json.c - JSON views of the core's results: mesh information and
 * curvature summaries, flow statistics (with the per-step log when one
 * was kept, and phase timings), comparison metrics and the scheme table.
 *
 * Each builder returns a fresh cJSON tree or NULL when an allocation
 * failed (never a half-built tree). Non-finite numbers become null, and
 * counts that are "not meaningful" (genus -1) too, so every document is
 * valid JSON that says what is unknown rather than inventing a value.
 */
#include <math.h>
#include <stdlib.h>

#include "api_internal.h"

int api__json_put(cJSON *o, const char *key, cJSON *item)
{
    if (!item)
        return 0;
    if (!cJSON_AddItemToObject(o, key, item)) {
        cJSON_Delete(item);
        return 0;
    }
    return 1;
}

int api__json_num(cJSON *o, const char *key, double v)
{
    return api__json_put(o, key, isfinite(v) ? cJSON_CreateNumber(v) : cJSON_CreateNull());
}

static int boolean(cJSON *o, const char *key, int v)
{
    return api__json_put(o, key, cJSON_CreateBool(v != 0));
}

static int str(cJSON *o, const char *key, const char *s)
{
    return api__json_put(o, key, s ? cJSON_CreateString(s) : cJSON_CreateNull());
}

static cJSON *vec3(const double *v)
{
    cJSON *a = cJSON_CreateArray();
    int i;
    for (i = 0; a && i < 3; i++) {
        cJSON *n = isfinite(v[i]) ? cJSON_CreateNumber(v[i]) : cJSON_CreateNull();
        if (!n || !cJSON_AddItemToArray(a, n)) {
            cJSON_Delete(n);
            cJSON_Delete(a);
            return NULL;
        }
    }
    return a;
}

/* ok is the and of every add; on failure the tree is dropped. */
static cJSON *finish(cJSON *o, int ok)
{
    if (!ok) {
        cJSON_Delete(o);
        return NULL;
    }
    return o;
}

static cJSON *stats(const mcf_stats *s)
{
    cJSON *o = cJSON_CreateObject();
    int ok = o != NULL;
    if (!ok)
        return NULL;
    ok = ok && api__json_num(o, "min", s->min);
    ok = ok && api__json_num(o, "max", s->max);
    ok = ok && api__json_num(o, "mean", s->mean);
    ok = ok && api__json_num(o, "rms", s->rms);
    ok = ok && api__json_num(o, "p05", s->p05);
    ok = ok && api__json_num(o, "p50", s->p50);
    ok = ok && api__json_num(o, "p95", s->p95);
    return finish(o, ok);
}

cJSON *api_json_curvature(const mcf_curvature_summary *c)
{
    cJSON *o = cJSON_CreateObject();
    int ok = o != NULL;
    if (!ok)
        return NULL;
    ok = ok && api__json_put(o, "H", stats(&c->H));
    ok = ok && api__json_put(o, "K", stats(&c->K));
    ok = ok && api__json_put(o, "A2", stats(&c->A2));
    ok = ok && api__json_num(o, "total_K", c->total_K);
    ok = ok && api__json_num(o, "gauss_bonnet", c->gauss_bonnet);
    ok = ok && api__json_num(o, "euler", c->euler);
    return finish(o, ok);
}

cJSON *api_json_mesh_info(const mcf_mesh_info *i, const mcf_curvature_summary *curv)
{
    cJSON *o = cJSON_CreateObject(), *e, *bb;
    int ok = o != NULL;
    if (!ok)
        return NULL;
    ok = ok && api__json_num(o, "vertices", i->nv);
    ok = ok && api__json_num(o, "faces", i->nf);
    ok = ok && api__json_num(o, "edges", i->ne);
    ok = ok && api__json_num(o, "unreferenced_vertices", i->unreferenced);
    ok = ok && api__json_num(o, "degenerate_faces", i->degenerate_faces);
    ok = ok && api__json_num(o, "duplicate_faces", i->duplicate_faces);
    ok = ok && api__json_num(o, "boundary_edges", i->boundary_edges);
    ok = ok && api__json_num(o, "boundary_loops", i->boundary_loops);
    ok = ok && api__json_num(o, "nonmanifold_edges", i->nonmanifold_edges);
    ok = ok && api__json_num(o, "nonmanifold_vertices", i->nonmanifold_vertices);
    ok = ok && api__json_num(o, "components", i->components);
    ok = ok && api__json_num(o, "euler", i->euler);
    ok = ok && (i->genus >= 0 ? api__json_num(o, "genus", i->genus)
                              : api__json_put(o, "genus", cJSON_CreateNull()));
    ok = ok && boolean(o, "manifold", i->manifold);
    ok = ok && boolean(o, "closed", i->closed);
    ok = ok && api__json_num(o, "inconsistent_orientation", i->inconsistent_orientation);
    ok = ok && api__json_num(o, "area", i->area);
    ok = ok && api__json_num(o, "volume", i->volume);
    if (ok) {
        e = cJSON_CreateObject();
        ok = api__json_put(o, "edge_length", e);
        ok = ok && api__json_num(e, "mean", i->mean_edge);
        ok = ok && api__json_num(e, "min", i->min_edge);
        ok = ok && api__json_num(e, "max", i->max_edge);
    }
    if (ok) {
        bb = cJSON_CreateObject();
        ok = api__json_put(o, "bbox", bb);
        ok = ok && api__json_put(bb, "min", vec3(i->bbox_min));
        ok = ok && api__json_put(bb, "max", vec3(i->bbox_max));
    }
    if (ok && curv)
        ok = api__json_put(o, "curvature", api_json_curvature(curv));
    return finish(o, ok);
}

/* The step log: every step up to API_LOG_MAX, else API_LOG_MAX of them,
 * the first, the last and evenly spaced between (a 100,000-step run
 * wrote 15 MB); each entry says its step (1-based). */
static cJSON *step_log(const mcf_step_log *s, int n)
{
    cJSON *a = cJSON_CreateArray();
    int i, k, m = n <= API_LOG_MAX ? n : API_LOG_MAX, ok = a != NULL;
    for (i = 0; ok && i < m; i++) {
        cJSON *e = cJSON_CreateObject();
        k = m == n ? i : (int)((double)i * (n - 1) / (m - 1) + 0.5);
        if (!e || !cJSON_AddItemToArray(a, e)) {
            cJSON_Delete(e);
            ok = 0;
            break;
        }
        ok = ok && api__json_num(e, "step", k + 1);
        ok = ok && api__json_num(e, "t", s[k].t);
        ok = ok && api__json_num(e, "dt", s[k].dt);
        ok = ok && api__json_num(e, "area", s[k].area);
        ok = ok && api__json_num(e, "volume", s[k].volume);
        ok = ok && api__json_num(e, "max_disp", s[k].max_disp);
        ok = ok && api__json_num(e, "solve_s", s[k].solve_s);
        ok = ok && api__json_num(e, "rejected", s[k].rejected);
    }
    return finish(a, ok);
}

cJSON *api_json_flow_stats(const mcf_flow_stats *st)
{
    cJSON *o = cJSON_CreateObject(), *t;
    int ok = o != NULL;
    if (!ok)
        return NULL;
    ok = ok && api__json_num(o, "steps", st->steps);
    ok = ok && api__json_num(o, "rejected", st->rejected);
    ok = ok && api__json_num(o, "solves", st->solves);
    ok = ok && api__json_num(o, "factorizations", st->factorizations);
    ok = ok && api__json_num(o, "picard_iterations", st->picard_iterations);
    ok = ok && api__json_num(o, "t_final", st->t_final);
    ok = ok && api__json_num(o, "dt_first", st->dt_first);
    ok = ok && api__json_num(o, "dt_min", st->dt_min);
    ok = ok && api__json_num(o, "dt_max", st->dt_max);
    ok = ok && api__json_num(o, "lambda_max", st->lambda_max);
    /* adaptive runs: the sum of the accepted steps' local error
     * estimates, relative to the unit-area size (0 otherwise) */
    ok = ok && api__json_num(o, "error_estimate", st->error_estimate);
    ok = ok && api__json_num(o, "area0", st->area0);
    ok = ok && api__json_num(o, "area1", st->area1);
    ok = ok && api__json_num(o, "volume0", st->volume0);
    ok = ok && api__json_num(o, "volume1", st->volume1);
    ok = ok && api__json_num(o, "peak_bytes", (double)st->peak_bytes);
    /* the amount the run covered and the measures behind its warnings */
    ok = ok && api__json_num(o, "mean_edge", st->mean_edge);
    ok = ok && api__json_num(o, "t_target", st->t_target);
    ok = ok && api__json_num(o, "strength", st->strength);
    /* strength=auto and the fairing filters: the noise level the amount
     * assumed, in mean edges (else 0) */
    ok = ok && api__json_num(o, "noise", st->noise);
    /* fairing: the estimated mean squared error (squared mean edges) after
     * K = 0, 1, ... steps, whose minimum gave `steps`; null without */
    ok = ok && api__json_put(o, "sure", st->sure ? cJSON_CreateDoubleArray(st->sure, st->nsure)
                                                 : cJSON_CreateNull());
    ok = ok && api__json_num(o, "noise_tangential", st->noise_tangential);
    /* what the amount assumed of the noise: null (nothing read), given,
     * normal, isotropic (the tangent planes too), one_direction (one
     * viewpoint's: noise_direction the unit vector read) or correlated
     * (over a few edges, on a plated part); noise_share the
     * default request's direction statistic (null unless it read it) */
    static const char *const kinds[] = {NULL, "given", "normal", "isotropic", "one_direction",
                                               "correlated"};
    ok = ok && str(o, "noise_kind",
                   st->noise_kind > 0 && st->noise_kind < (int)(sizeof kinds / sizeof *kinds) ? kinds[st->noise_kind]
                                                                                            : NULL);
    ok = ok && api__json_put(o, "noise_share", st->noise_share > 0.0 ? cJSON_CreateNumber(st->noise_share)
                                                                      : cJSON_CreateNull());
    ok = ok && api__json_put(o, "noise_direction", st->noise_kind == MCF_NOISE_ONE_DIRECTION
                                                       ? vec3(st->noise_direction)
                                                       : cJSON_CreateNull());
    ok = ok && api__json_num(o, "tangential_steps", st->tangential_steps);
    /* fairing: the combination of iterates the result took along the
     * normals, {steps: [k...], weights: [c...]}; null: Y after `steps` */
    if (ok && st->ncomb > 0) {
        cJSON *cb = cJSON_CreateObject();
        ok = api__json_put(o, "combination", cb);
        ok = ok && api__json_put(cb, "steps", cJSON_CreateIntArray(st->comb_steps, st->ncomb));
        ok = ok && api__json_put(cb, "weights", cJSON_CreateDoubleArray(st->comb_weight, st->ncomb));
    } else {
        ok = ok && api__json_put(o, "combination", cJSON_CreateNull());
    }
    /* fairing: 1 when the result is the explicit lambda|mu passes', 0
     * the implicit steps' (or no fairing filter) */
    ok = ok && api__json_num(o, "filter_explicit", st->filter_explicit);
    /* the feature-aware stage (the default request and fairing_feature):
     * null when it did not run; else whether the result is its own, the
     * candidate of least SURE and the two SUREs compared (squared mean
     * edges per vertex) */
    if (ok && st->feature_ran) {
        cJSON *fe = cJSON_CreateObject();
        ok = api__json_put(o, "feature", fe);
        ok = ok && api__json_put(fe, "taken", cJSON_CreateBool(st->feature));
        ok = ok && api__json_num(fe, "sigma_r", st->feature_sigma_r);
        ok = ok && api__json_num(fe, "normal_iterations", st->feature_normal_iters);
        ok = ok && api__json_num(fe, "vertex_iterations", st->feature_vertex_iters);
        ok = ok && api__json_num(fe, "sure", st->feature_sure);
        ok = ok && api__json_num(fe, "sure_against", st->feature_sure_against);
        ok = ok && api__json_num(fe, "z", st->feature_z);
        ok = ok && api__json_num(fe, "noise", st->feature_noise);
    } else {
        ok = ok && api__json_put(o, "feature", cJSON_CreateNull());
    }
    ok = ok && api__json_num(o, "crease_vertices", st->crease_vertices);
    ok = ok && api__json_num(o, "guard_rounds", st->guard_rounds);
    ok = ok && api__json_num(o, "guard_vertices", st->guard_vertices);
    /* the default request: its robust stages ran (robust), the spikes
     * repaired before the filter; the filter whose result was taken */
    ok = ok && boolean(o, "robust", st->robust);
    ok = ok && api__json_num(o, "spikes_repaired", st->spikes_repaired);
    ok = ok && api__json_num(o, "flips_repaired", st->flips_repaired);
    ok = ok && api__json_num(o, "turned_repaired", st->turned_repaired);
    {
        const mcf_scheme_info *fi = mcf_scheme_get(st->filter);
        ok = ok && str(o, "filter", fi ? fi->name : NULL);
    }
    ok = ok && api__json_num(o, "folded_faces", st->folded_faces);
    ok = ok && api__json_num(o, "min_edge_ratio", st->min_edge_ratio);
    ok = ok && api__json_num(o, "area_ratio", st->area_ratio);
    if (ok) {
        t = cJSON_CreateObject();
        ok = api__json_put(o, "timings", t);
        ok = ok && api__json_num(t, "assemble_s", st->time_assemble);
        ok = ok && api__json_num(t, "analyze_s", st->time_analyze);
        ok = ok && api__json_num(t, "factorize_s", st->time_factorize);
        ok = ok && api__json_num(t, "solve_s", st->time_solve);
        ok = ok && api__json_num(t, "total_s", st->time_total);
        ok = ok && api__json_num(t, "threads_cpu_s", st->threads_cpu_s);
    }
    if (ok && st->log && st->nlog > 0)
        ok = api__json_put(o, "log", step_log(st->log, st->nlog));
    return finish(o, ok);
}

cJSON *api_json_compare(const mcf_compare_result *c)
{
    cJSON *o = cJSON_CreateObject();
    int ok = o != NULL;
    if (!ok)
        return NULL;
    ok = ok && api__json_num(o, "rms_m", c->rms_m);
    ok = ok && api__json_num(o, "rms_rel", c->rms_rel);
    ok = ok && api__json_num(o, "frobenius", c->frobenius);
    ok = ok && api__json_num(o, "max_err", c->max_err);
    ok = ok && api__json_num(o, "normal_angle_deg", c->normal_angle_deg);
    ok = ok && api__json_num(o, "inverted_faces", c->inverted_faces);
    return finish(o, ok);
}

cJSON *api_json_schemes(void)
{
    cJSON *o = cJSON_CreateObject(), *a;
    int s, ok = o != NULL;
    if (!ok)
        return NULL;
    a = cJSON_CreateArray();
    ok = api__json_put(o, "schemes", a);
    for (s = 0; ok && s < MCF_NSCHEMES; s++) {
        const mcf_scheme_info *si = mcf_scheme_get((mcf_scheme)s);
        cJSON *e, *cost;
        if (!si)
            continue;
        e = cJSON_CreateObject();
        if (!e || !cJSON_AddItemToArray(a, e)) {
            cJSON_Delete(e);
            ok = 0;
            break;
        }
        ok = ok && str(e, "name", si->name);
        ok = ok && str(e, "title", si->title);
        ok = ok && api__json_num(e, "order", si->order);
        ok = ok && boolean(e, "explicit", si->is_explicit);
        /* stability 0 means no step limit; say so rather than "0". */
        ok = ok && (si->stability > 0
                    ? api__json_num(e, "stability", si->stability)
                    : api__json_put(e, "stability", cJSON_CreateString("unconditional")));
        if (ok) {
            cost = cJSON_CreateObject();
            ok = api__json_put(e, "cost_per_step", cost);
            ok = ok && api__json_num(cost, "solves", si->solves_per_step);
            ok = ok && api__json_num(cost, "factorizations", si->factorizations_per_step);
        }
        ok = ok && boolean(e, "adaptive", si->has_estimate);
        ok = ok && str(e, "estimate", si->estimate && *si->estimate ? si->estimate : NULL);
        ok = ok && str(e, "best_use", si->best_use);
    }
    return finish(o, ok);
}

char *api_json_print(const cJSON *j, int pretty)
{
    if (!j)
        return NULL;
    return pretty ? cJSON_Print(j) : cJSON_PrintUnformatted(j);
}
