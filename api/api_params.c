/* SPDX-License-Identifier: MIT */
/*
 * api_params.c - the job parameters' one table: per key its type, its
 * range and the setter that stores the value, what each key means for
 * people (api_params_describe, which the contract test holds against
 * openapi.yaml and mcfd.proto), and the parameters as JSON.
 *
 * Every source of a value ends in api_params_set(key, text)
 * (api_params_parse.c): JSON numbers and booleans are turned into text
 * first, so "dt": "abc" in a JSON body and dt=abc in a query string fail
 * with the very same message. The "accepted" list of the unknown-key
 * error and the range text of every other error are generated from the
 * table, so they cannot drift. The rules that need the mesh are in
 * api_params_finish.c.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "api_params_internal.h"

static const char *const boundary_names[] = {"fixed", "free", NULL};
static const char *const rescale_names[] = {"none", "volume", "area", NULL};
static const char *const laplacian_names[] = {"cotan", "uniform", NULL};
static const char *const mass_names[] = {"barycentric", "voronoi", NULL};

static void set_scheme(api_params *p, value v)
{
    p->flow.scheme = (mcf_scheme)v.e;
    p->scheme_set = 1;
}
static void set_dt(api_params *p, value v)
{
    p->dt_set = 1;
    p->flow_keys_set = 1;
    /* NaN stands for "auto" (see parse_value). */
    if (isnan(v.d)) {
        p->flow.dt_auto = 1;
    } else {
        p->flow.dt_auto = 0;
        p->flow.dt = v.d;
    }
}
static void set_iterations(api_params *p, value v)
{
    p->flow.iterations = (int)v.i;
    p->iterations_set = 1;
}
static void set_time(api_params *p, value v)
{
    p->flow_keys_set = 1;
    p->flow.time = v.d;
    p->time_set = 1;
}
static void set_boundary(api_params *p, value v) { p->flow.boundary = (mcf_boundary)v.e; }
static void set_rescale(api_params *p, value v)
{
    p->flow.rescale = (mcf_rescale)v.e;
    p->flow_keys_set = 1;
}
static void set_normalize(api_params *p, value v) { p->flow.normalize = v.e; }
static void set_laplacian(api_params *p, value v)
{
    p->flow.laplacian = (mcf_laplacian)v.e;
    p->flow_keys_set = 1;
}
static void set_mass(api_params *p, value v)
{
    p->flow.mass = (mcf_mass)v.e;
    p->flow_keys_set = 1;
}
static void set_adaptive(api_params *p, value v)
{
    p->flow.adaptive = v.e;
    p->flow_keys_set = 1;
}
static void set_tol(api_params *p, value v)
{
    p->flow.tol = v.d;
    p->tol_set = 1;
}
static void set_strength(api_params *p, value v)
{
    /* NaN stands for "auto" (see parse_value). */
    p->flow.strength_auto = isnan(v.d);
    if (!isnan(v.d))
        p->flow.strength = v.d;
    p->strength_set = 1;
}
static void set_max_steps(api_params *p, value v) { p->flow.max_steps = (int)v.i; }
static void set_format(api_params *p, value v) { p->encode.format = (api_format)v.e; }
static void set_qbits(api_params *p, value v) { p->encode.quantization_bits = (int)v.i; }
static void set_clevel(api_params *p, value v) { p->encode.compression_level = (int)v.i; }
static void set_order(api_params *p, value v) { p->encode.preserve_order = v.e; }
static void set_ply_binary(api_params *p, value v) { p->encode.ply_binary = v.e; }
static void set_ply_curvature(api_params *p, value v) { p->encode.ply_curvature = v.e; }

/* The one table. fixed_vertices has no apply: lists are stored by
 * set_list, which owns the array. */
const keydef api__param_keys[] = {
    {"scheme", K_SCHEME, 0, 0, 0, NULL, set_scheme},
    {"dt", K_NUM, 0, 1e3, AUTO, NULL, set_dt},
    {"iterations", K_INT, 1, 0, HI_ITER, NULL, set_iterations},
    {"time", K_NUM, 0, HUGE_VAL, 0, NULL, set_time},
    {"strength", K_NUM, 0, 100, AUTO, NULL, set_strength},
    {"boundary", K_ENUM, 0, 0, 0, boundary_names, set_boundary},
    {"fixed_vertices", K_LIST, 0, 0, 0, NULL, NULL},
    {"rescale", K_ENUM, 0, 0, 0, rescale_names, set_rescale},
    {"normalize", K_BOOL, 0, 0, 0, NULL, set_normalize},
    {"laplacian", K_ENUM, 0, 0, 0, laplacian_names, set_laplacian},
    {"mass", K_ENUM, 0, 0, 0, mass_names, set_mass},
    {"adaptive", K_BOOL, 0, 0, 0, NULL, set_adaptive},
    {"tol", K_NUM, 1e-12, 1, LO_INCL, NULL, set_tol},
    {"max_steps", K_INT, 1, 0, HI_ITER, NULL, set_max_steps},
    {"format", K_FORMAT, 0, 0, 0, NULL, set_format},
    /* at most 24: Draco's encoder memory doubles per bit (26: 200 MB,
     * 30: about 3 GB, whatever the mesh) */
    {"quantization_bits", K_INT, 0, 24, AUTO, NULL, set_qbits},
    {"compression_level", K_INT, 0, 10, 0, NULL, set_clevel},
    {"preserve_order", K_BOOL, 0, 0, 0, NULL, set_order},
    {"ply_curvature", K_BOOL, 0, 0, 0, NULL, set_ply_curvature},
    {"ply_binary", K_BOOL, 0, 0, 0, NULL, set_ply_binary},
};
#define NKEYS (sizeof api__param_keys / sizeof api__param_keys[0])
const size_t api__param_nkeys = NKEYS;

/* given is a bit per key of the table */
typedef char given_fits[NKEYS <= 32 ? 1 : -1];

const char *const api__format_names[] = {"obj", "draco", "ply", "stl", "off", "glb", "gltf", NULL};

/* What each key means, for people: the unit and one line of help, the
 * default in words where it is derived rather than a value, and whether it
 * is an output (encoder) option, which `mcf convert` takes too. Every key
 * of the table above needs its line here: without one, api_params_describe
 * gives it a null help, and tests/test_contract.py fails naming it. */
typedef struct {
    const char *name, *unit, *help, *derived;
    int output;
} keydoc;

static const keydoc docs[] = {
    {"scheme", NULL, "the integrator or filter (`mcf schemes` describes each); unset: "
     "fairing, fairing_explicit above 150,000 vertices, desbrun2 when time, dt, adaptive, "
     "laplacian, mass or rescale is set", "fairing", 0},
    {"dt", "flow time", "the step (unit-area time when normalize is on); auto: from "
     "lambda_max, explicit schemes only", "time / iterations", 0},
    {"iterations", "steps", "number of steps over the time (taubin, fairing_explicit: passes; "
     "fairing: its steps, automatic when unset)", NULL, 0},
    {"time", "flow time", "total flow time (unit-area time when normalize is on); "
     "replaces strength", "strength^2 h^2", 0},
    {"strength", "mean edges", "the amount: diffuse over about this many mean edges "
     "(time strength^2 h^2); auto (the default when no amount is named): from the "
     "mesh's own noise; the fairing filters: the noise level to remove (auto: "
     "estimated)", NULL, 0},
    {"boundary", NULL, "fixed: boundary vertices stay; free: they move", NULL, 0},
    {"fixed_vertices", "vertex indices", "0-based vertices held in place", NULL, 0},
    {"rescale", NULL, "after the flow, restore the input's volume or area", NULL, 0},
    {"normalize", NULL, "centre and scale to unit area before the flow, undone after",
     NULL, 0},
    {"laplacian", NULL, "the discrete Laplacian", NULL, 0},
    {"mass", NULL, "the mass matrix", NULL, 0},
    {"adaptive", NULL, "adaptive steps to the time, by the scheme's error estimate "
     "(desbrun2, ros2, richardson, desbrun)", NULL, 0},
    {"tol", "error relative to sqrt(area)", "tolerance of adaptive steps (needs adaptive): "
     "the result's M-weighted RMS error against the converged flow, relative to "
     "sqrt(area) (desbrun2, ros2: at the end of the flow, measured 0.01-0.4 tol; "
     "richardson, desbrun: each step's); the largest vertex's within about 20 tol "
     "(desbrun2; docs/numerics.md)", NULL, 0},
    {"max_steps", "steps", "cap on the steps of a run, rejected adaptive attempts "
     "included", NULL, 0},
    {"format", NULL, "output format: obj, draco (or drc), ply, stl, off, glb or gltf",
     "the input's", 1},
    {"quantization_bits", "bits", "Draco output: position bits; auto keeps a Draco "
     "input's, 16 from other formats; 0 lossless", NULL, 1},
    {"compression_level", NULL, "Draco output: 0 fastest to 10 smallest", NULL, 1},
    {"preserve_order", NULL, "Draco output: keep the vertex order", NULL, 1},
    {"ply_curvature", NULL, "PLY output: mean and Gaussian curvature per vertex", NULL, 1},
    {"ply_binary", NULL, "PLY output: binary (false: ASCII)", NULL, 1},
};
#define NDOCS (sizeof docs / sizeof docs[0])

/* --------------------------------------------------------------- helpers */

const keydef *api__param_find(const char *name)
{
    size_t i;
    for (i = 0; i < NKEYS; i++)
        if (strcmp(api__param_keys[i].name, name) == 0)
            return &api__param_keys[i];
    return NULL;
}

static void join_names(char *out, size_t size, const char *const *names)
{
    size_t used = 0;
    int i;
    out[0] = '\0';
    for (i = 0; names[i]; i++) {
        int n = snprintf(out + used, size - used, "%s%s", i ? ", " : "",
                         names[i]);
        if (n < 0 || (size_t)n >= size - used)
            break;
        used += (size_t)n;
    }
}

/* What a key accepts, in words ("a number > 0 and <= 1000 or \"auto\""). */
void api__param_accepts(const keydef *k, const api_limits *lim, char *out,
                        size_t size)
{
    char list[160];
    switch (k->kind) {
    case K_NUM:
        if (k->flags & AUTO)
            snprintf(out, size, "a number > %g and <= %g or \"auto\"", k->lo, k->hi);
        else if (isinf(k->hi))
            snprintf(out, size, "a finite number %s %g",
                     (k->flags & LO_INCL) ? ">=" : ">", k->lo);
        else if (k->flags & LO_INCL)
            snprintf(out, size, "a number from %g to %g", k->lo, k->hi);
        else
            snprintf(out, size, "a number > %g and <= %g", k->lo, k->hi);
        break;
    case K_INT:
        snprintf(out, size, "an integer from %.0f to %d%s", k->lo,
                 (k->flags & HI_ITER) ? lim->max_iterations : (int)k->hi,
                 (k->flags & AUTO) ? " or \"auto\"" : "");
        break;
    case K_BOOL:
        snprintf(out, size, "true or false (or 1/0, yes/no)");
        break;
    case K_ENUM:
    case K_FORMAT:
        join_names(list, sizeof list, k->kind == K_ENUM ? k->names : api__format_names);
        snprintf(out, size, "one of %s", list);
        break;
    case K_SCHEME: {
        size_t used = 0;
        int s;
        list[0] = '\0';
        for (s = 0; s < MCF_NSCHEMES; s++) {
            const mcf_scheme_info *si = mcf_scheme_get((mcf_scheme)s);
            int n;
            if (!si)
                continue;
            n = snprintf(list + used, sizeof list - used, "%s%s", used ? ", " : "",
                         si->name);
            if (n < 0 || (size_t)n >= sizeof list - used)
                break;
            used += (size_t)n;
        }
        snprintf(out, size, "one of %s", list);
        break;
    }
    case K_LIST:
        snprintf(out, size, "a list of at most %d vertex indices (integers >= 0)",
                 lim->max_fixed);
        break;
    }
}

/* ------------------------------------------------------------------ API */

void api_params_init(api_params *p)
{
    memset(p, 0, sizeof *p);
    mcf_flow_params_init(&p->flow);
    /* the request's default: the fairing filter (api_default_scheme picks
     * the variant once the mesh is known, in api_params_finish) */
    p->flow.scheme = MCF_FAIRING;
    api_encode_opts_init(&p->encode);
    p->fixed_owned = NULL;
    p->time_set = 0;
    p->iterations_set = 0;
    p->dt_set = 0;
    p->tol_set = 0;
    p->scheme_set = 0;
    p->strength_set = 0;
    p->flow_keys_set = 0;
    p->scheme_chosen = 0;
}

void api_params_free(api_params *p)
{
    if (!p)
        return;
    free(p->fixed_owned);
    p->fixed_owned = NULL;
    p->flow.fixed = NULL;
    p->flow.nfixed = 0;
}

mcf_status api_params_copy(api_params *dst, const api_params *src)
{
    int32_t *a = NULL;

    if (src->fixed_owned && src->flow.nfixed > 0) {
        a = malloc((size_t)src->flow.nfixed * sizeof *a);
        if (!a)
            return MCF_ENOMEM;
        memcpy(a, src->fixed_owned, (size_t)src->flow.nfixed * sizeof *a);
    }
    *dst = *src;
    dst->fixed_owned = a;
    if (a)
        dst->flow.fixed = a;
    return MCF_OK;
}

static const char *enum_name(const char *const *names, int i)
{
    int k;
    for (k = 0; names[k]; k++)
        if (k == i)
            return names[k];
    return "unknown";
}

cJSON *api_params_to_json(const api_params *p)
{
    cJSON *j = cJSON_CreateObject(), *fx;
    const mcf_scheme_info *si = mcf_scheme_get(p->flow.scheme);
    int ok = j != NULL, i;

    if (!ok)
        return NULL;
    /* an unnamed scheme is the default, which depends on the mesh: named
     * once api_params_finish has chosen it */
    if (p->scheme_set || p->scheme_chosen)
        ok &= cJSON_AddStringToObject(j, "scheme", si ? si->name : "unknown") != NULL;
    /* What was given, so the object parses back to the same job: an
     * unset dt, time or iterations is derived from strength by the core,
     * and with none of them nor strength the amount is automatic */
    if (p->flow.dt_auto)
        ok &= cJSON_AddStringToObject(j, "dt", "auto") != NULL;
    else if (p->flow.dt > 0.0)
        ok &= cJSON_AddNumberToObject(j, "dt", p->flow.dt) != NULL;
    if (p->time_set)
        ok &= cJSON_AddNumberToObject(j, "time", p->flow.time) != NULL;
    if (p->iterations_set)
        ok &= cJSON_AddNumberToObject(j, "iterations", p->flow.iterations) != NULL;
    /* a fairing filter's strength is the noise level, automatic unless
     * given: the default MCF strength is no value for it */
    if (p->flow.strength_auto)
        ok &= cJSON_AddStringToObject(j, "strength", "auto") != NULL;
    else if (p->strength_set ||
             ((p->scheme_set || p->scheme_chosen) && !api__is_fairing(p->flow.scheme) && !api_params_auto_amount(p)))
        ok &= cJSON_AddNumberToObject(j, "strength", p->flow.strength) != NULL;
    else
        ok &= cJSON_AddStringToObject(j, "strength", "auto") != NULL;
    ok &= cJSON_AddStringToObject(j, "boundary",
                                  enum_name(boundary_names, (int)p->flow.boundary)) != NULL;
    fx = cJSON_AddArrayToObject(j, "fixed_vertices");
    ok &= fx != NULL;
    for (i = 0; ok && i < p->flow.nfixed; i++) {
        cJSON *n = cJSON_CreateNumber(p->flow.fixed[i]);
        ok &= n != NULL && cJSON_AddItemToArray(fx, n);
    }
    ok &= cJSON_AddStringToObject(j, "rescale",
                                  enum_name(rescale_names, (int)p->flow.rescale)) != NULL;
    ok &= cJSON_AddBoolToObject(j, "normalize", p->flow.normalize) != NULL;
    ok &= cJSON_AddStringToObject(j, "laplacian",
                                  enum_name(laplacian_names, (int)p->flow.laplacian)) != NULL;
    ok &= cJSON_AddStringToObject(j, "mass", enum_name(mass_names, (int)p->flow.mass)) != NULL;
    ok &= cJSON_AddBoolToObject(j, "adaptive", p->flow.adaptive) != NULL;
    if (p->tol_set)
        ok &= cJSON_AddNumberToObject(j, "tol", p->flow.tol) != NULL;
    ok &= cJSON_AddNumberToObject(j, "max_steps", p->flow.max_steps) != NULL;
    if (p->encode.format != API_FMT_UNKNOWN)
        ok &= cJSON_AddStringToObject(j, "format", api_format_name(p->encode.format)) != NULL;
    if (p->encode.quantization_bits < 0)
        ok &= cJSON_AddStringToObject(j, "quantization_bits", "auto") != NULL;
    else
        ok &= cJSON_AddNumberToObject(j, "quantization_bits", p->encode.quantization_bits) != NULL;
    ok &= cJSON_AddNumberToObject(j, "compression_level", p->encode.compression_level) != NULL;
    ok &= cJSON_AddBoolToObject(j, "preserve_order", p->encode.preserve_order) != NULL;
    ok &= cJSON_AddBoolToObject(j, "ply_binary", p->encode.ply_binary) != NULL;
    ok &= cJSON_AddBoolToObject(j, "ply_curvature", p->encode.ply_curvature) != NULL;
    if (!ok) {
        cJSON_Delete(j);
        return NULL;
    }
    return j;
}

cJSON *api_params_given_json(const api_params *p)
{
    cJSON *all = api_params_to_json(p), *c, *next;
    const keydef *k;

    if (!all)
        return NULL;
    for (c = all->child; c; c = next) {
        next = c->next;
        k = api__param_find(c->string);
        if (!k || !(p->given & (1u << (k - api__param_keys))))
            cJSON_Delete(cJSON_DetachItemViaPointer(all, c));
    }
    return all;
}

/* --------------------------------------------------------- description */

static const keydoc *find_doc(const char *name)
{
    size_t i;
    for (i = 0; i < NDOCS; i++)
        if (strcmp(docs[i].name, name) == 0)
            return &docs[i];
    return NULL;
}

static cJSON *string_array(const char *const *names)
{
    cJSON *a = cJSON_CreateArray();
    int i;
    for (i = 0; a && names[i]; i++)
        if (!cJSON_AddItemToArray(a, cJSON_CreateString(names[i]))) {
            cJSON_Delete(a);
            return NULL;
        }
    return a;
}

static cJSON *scheme_names(void)
{
    const char *names[MCF_NSCHEMES + 1];
    int s, n = 0;
    for (s = 0; s < MCF_NSCHEMES; s++) {
        const mcf_scheme_info *si = mcf_scheme_get((mcf_scheme)s);
        if (si)
            names[n++] = si->name;
    }
    names[n] = NULL;
    return string_array(names);
}

/* The default of key k as JSON: the value of a fresh api_params, or NULL
 * when it is derived (dt, time, format: keydoc.derived says how). */
static cJSON *default_json(const keydef *k, const api_params *fresh, const cJSON *dj)
{
    if (strcmp(k->name, "iterations") == 0)
        return cJSON_CreateNumber(MCF_DEFAULT_STEPS);
    if (strcmp(k->name, "tol") == 0)
        return cJSON_CreateNumber(fresh->flow.tol);
    if (strcmp(k->name, "strength") == 0) /* no amount named: automatic */
        return cJSON_CreateString("auto");
    return cJSON_Duplicate(cJSON_GetObjectItemCaseSensitive(dj, k->name), 1);
}

cJSON *api_params_describe(const api_limits *lim)
{
    api_limits def;
    api_params fresh;
    cJSON *out = cJSON_CreateArray(), *dj;
    size_t i;
    int ok = out != NULL;

    if (!lim) {
        api_limits_default(&def);
        lim = &def;
    }
    api_params_init(&fresh);
    dj = api_params_to_json(&fresh);
    ok &= dj != NULL;
    for (i = 0; ok && i < NKEYS; i++) {
        const keydef *k = &api__param_keys[i];
        const keydoc *d = find_doc(k->name);
        cJSON *o = cJSON_CreateObject(), *dv;
        char what[200];
        const char *type = "string";

        ok &= o != NULL && cJSON_AddItemToArray(out, o);
        if (!ok)
            break;
        switch (k->kind) {
        case K_NUM: type = "number"; break;
        case K_INT: type = "integer"; break;
        case K_BOOL: type = "boolean"; break;
        case K_LIST: type = "array"; break;
        default: break;
        }
        api__param_accepts(k, lim, what, sizeof what);
        ok &= cJSON_AddStringToObject(o, "name", k->name) != NULL;
        ok &= cJSON_AddStringToObject(o, "type", type) != NULL;
        ok &= cJSON_AddBoolToObject(o, "auto", (k->flags & AUTO) != 0) != NULL;
        if (k->kind == K_NUM || k->kind == K_INT) {
            ok &= cJSON_AddNumberToObject(o, (k->kind == K_NUM && !(k->flags & LO_INCL))
                                          ? "exclusiveMinimum" : "minimum", k->lo) != NULL;
            if (k->flags & HI_ITER)
                ok &= cJSON_AddStringToObject(o, "maximum_limit", "max_iterations") != NULL;
            else if (!isinf(k->hi))
                ok &= cJSON_AddNumberToObject(o, "maximum", k->hi) != NULL;
        }
        if (k->kind == K_ENUM)
            ok &= cJSON_AddItemToObject(o, "enum", string_array(k->names));
        else if (k->kind == K_FORMAT)
            ok &= cJSON_AddItemToObject(o, "enum", string_array(api__format_names));
        else if (k->kind == K_SCHEME)
            ok &= cJSON_AddItemToObject(o, "enum", scheme_names());
        dv = default_json(k, &fresh, dj);
        if (dv)
            ok &= cJSON_AddItemToObject(o, "default", dv);
        else
            ok &= cJSON_AddStringToObject(o, "default_text", d && d->derived ? d->derived
                                          : "") != NULL;
        ok &= cJSON_AddStringToObject(o, "accepts", what) != NULL;
        if (!d) {   /* a key without its line in docs[] */
            ok &= cJSON_AddNullToObject(o, "help") != NULL;
            continue;
        }
        ok &= cJSON_AddStringToObject(o, "help", d->help) != NULL;
        if (d->unit)
            ok &= cJSON_AddStringToObject(o, "unit", d->unit) != NULL;
        ok &= cJSON_AddBoolToObject(o, "output", d->output) != NULL;
    }
    cJSON_Delete(dj);
    api_params_free(&fresh);
    if (!ok) {
        cJSON_Delete(out);
        return NULL;
    }
    return out;
}
