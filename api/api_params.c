/* SPDX-License-Identifier: MIT */
/*
 * api_params.c - job parameters from JSON, URL query strings and CLI
 * flags, through one table and one validation path.
 *
 * Every source ends in api_params_set(key, text): JSON numbers and
 * booleans are turned into text first, so "dt": "abc" in a JSON body and
 * dt=abc in a query string fail with the very same message. The table
 * below holds, per key, its type, its range and the setter that stores
 * the value; the "accepted" list of the unknown-key error and the range
 * text of every other error are generated from it, so they cannot drift.
 * A failing set leaves the parameters unchanged.
 */
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "api_internal.h"

typedef enum {
    K_NUM,      /* finite double, lo < x <= hi (or lo <= x with LO_INCL) */
    K_INT,      /* integer lo..hi (hi from the limits with HI_ITER) */
    K_BOOL,     /* true/false/1/0/yes/no */
    K_ENUM,     /* one of names[] (value = index) */
    K_SCHEME,   /* a scheme name (mcf_scheme_from_name) */
    K_FORMAT,   /* obj|draco|ply|stl|off */
    K_LIST      /* vertex indices: JSON array or comma/space separated */
} kind;

enum { LO_INCL = 1, AUTO = 2, HI_ITER = 4 };

typedef union {
    double d;
    long long i;
    int e;              /* bool, enum index, scheme, format */
} value;

typedef struct {
    const char *name;
    kind kind;
    double lo, hi;
    int flags;
    const char *const *names;
    void (*apply)(api_params *p, value v);
} keydef;

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
static const keydef keys[] = {
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
#define NKEYS (sizeof keys / sizeof keys[0])

/* given is a bit per key of the table */
typedef char given_fits[NKEYS <= 32 ? 1 : -1];

static const char *const format_names[] = {"obj", "draco", "ply", "stl", "off", "glb", "gltf", NULL};

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
    {"tol", "error per step", "tolerance of adaptive steps (needs adaptive)", NULL, 0},
    {"max_steps", "steps", "cap on the steps of a run, rejected adaptive attempts "
     "included", NULL, 0},
    {"format", NULL, "output format: obj, draco, ply, stl, off, glb or gltf", "the input's", 1},
    {"quantization_bits", "bits", "Draco output: position bits; auto keeps a Draco "
     "input's, 16 from other formats; 0 lossless", NULL, 1},
    {"compression_level", NULL, "Draco output: 0 fastest to 10 smallest", NULL, 1},
    {"preserve_order", NULL, "Draco output: keep the vertex order", NULL, 1},
    {"ply_curvature", NULL, "PLY output: mean and Gaussian curvature per vertex", NULL, 1},
    {"ply_binary", NULL, "PLY output: binary (false: ASCII)", NULL, 1},
};
#define NDOCS (sizeof docs / sizeof docs[0])

/* --------------------------------------------------------------- helpers */

static const keydef *find_key(const char *name)
{
    size_t i;
    for (i = 0; i < NKEYS; i++)
        if (strcmp(keys[i].name, name) == 0)
            return &keys[i];
    return NULL;
}

/* s shortened to fit an error message, control bytes as '?'. */
static const char *shorten(const char *s, size_t max, char *out)
{
    size_t i, n = strlen(s), k = n > max ? max : n;
    for (i = 0; i < k; i++) {
        unsigned char c = (unsigned char)s[i];
        out[i] = (c < 0x20 || c == 0x7f) ? '?' : (char)c;
    }
    if (n > k) {
        memcpy(out + k, "...", 3);
        k += 3;
    }
    out[k] = '\0';
    return out;
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
static void describe(const keydef *k, const api_limits *lim, char *out,
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
        join_names(list, sizeof list, k->kind == K_ENUM ? k->names : format_names);
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

/* The EINVAL of a bad value. shown: how to print the value (NULL: the
 * text in quotes). */
static mcf_status bad_value(const keydef *k, const char *text,
                            const char *shown, const api_limits *lim,
                            mcf_error *err)
{
    char what[200], s[48];
    describe(k, lim, what, sizeof what);
    if (shown)
        return api__fail(err, MCF_EINVAL, "parameter '%s' must be %s, got %s",
                         k->name, what, shown);
    return api__fail(err, MCF_EINVAL, "parameter '%s' must be %s, got \"%s\"",
                     k->name, what, shorten(text, 40, s));
}

static int parse_ll(const char *t, long long *out)
{
    char *end;
    long long v;
    if (!*t || !(t[0] == '-' || (t[0] >= '0' && t[0] <= '9')))
        return -1;
    errno = 0;
    v = strtoll(t, &end, 10);
    if (*end || errno == ERANGE)
        return -1;
    *out = v;
    return 0;
}

static int parse_bool(const char *t, int *out)
{
    if (!strcasecmp(t, "true") || !strcmp(t, "1") || !strcasecmp(t, "yes"))
        *out = 1;
    else if (!strcasecmp(t, "false") || !strcmp(t, "0") || !strcasecmp(t, "no"))
        *out = 0;
    else
        return -1;
    return 0;
}

/* Parses text for a scalar key: 0 and *v, or -1 (wrong type or range). */
static int parse_value(const keydef *k, const char *t, const api_limits *lim,
                       value *v)
{
    int i;
    switch (k->kind) {
    case K_NUM:
        if ((k->flags & AUTO) && strcmp(t, "auto") == 0) {
            v->d = NAN;
            return 0;
        }
        if (api__parse_double(t, strlen(t), &v->d) != 0 || !isfinite(v->d))
            return -1;
        if (v->d > k->hi || ((k->flags & LO_INCL) ? v->d < k->lo : v->d <= k->lo))
            return -1;
        return 0;
    case K_INT: {
        long long hi = (k->flags & HI_ITER) ? lim->max_iterations : (long long)k->hi;
        if ((k->flags & AUTO) && strcmp(t, "auto") == 0) {
            v->i = -1; /* an integer key's "auto" (quantization_bits) */
            return 0;
        }
        if (parse_ll(t, &v->i) != 0 || v->i < (long long)k->lo || v->i > hi)
            return -1;
        return 0;
    }
    case K_BOOL:
        return parse_bool(t, &v->e);
    case K_ENUM:
        for (i = 0; k->names[i]; i++)
            if (strcmp(t, k->names[i]) == 0) {
                v->e = i;
                return 0;
            }
        return -1;
    case K_SCHEME: {
        mcf_scheme s;
        if (mcf_scheme_from_name(t, &s) != MCF_OK)
            return -1;
        v->e = (int)s;
        return 0;
    }
    case K_FORMAT:
        for (i = 0; format_names[i]; i++)
            if (strcmp(t, format_names[i]) == 0) {
                v->e = (int)api_format_from_name(t);
                return 0;
            }
        return -1;
    case K_LIST:
        break;
    }
    return -1;
}

static int is_sep(char c)
{
    return c == ',' || c == ' ' || c == '\t' || c == '\n' || c == '\r';
}

/* A list of vertex indices separated by commas and/or white space. */
static mcf_status set_list(api_params *p, const keydef *k, const char *t,
                           const api_limits *lim, mcf_error *err)
{
    const char *s;
    size_t n = 0, i = 0, item = 0;
    int32_t *a;

    for (s = t; *s;) {
        while (*s && is_sep(*s))
            s++;
        if (!*s)
            break;
        if (n >= (size_t)lim->max_fixed)
            return api__fail(err, MCF_ELIMIT,
                             "parameter '%s' has more than max_fixed (%d) indices",
                             k->name, lim->max_fixed);
        n++;
        while (*s && !is_sep(*s))
            s++;
    }
    a = malloc((n ? n : 1) * sizeof *a);
    if (!a)
        return api__fail(err, MCF_ENOMEM, "parameter '%s': no memory for %zu indices",
                         k->name, n);
    for (s = t; *s;) {
        char tok[32], sh[48];
        size_t len = 0;
        long long v;
        while (*s && is_sep(*s))
            s++;
        if (!*s)
            break;
        item++;
        while (s[len] && !is_sep(s[len]))
            len++;
        if (len < sizeof tok) {
            memcpy(tok, s, len);
            tok[len] = '\0';
        }
        if (len >= sizeof tok || parse_ll(tok, &v) != 0 || v < 0 || v > INT32_MAX) {
            char what[200], raw[40];
            size_t rl = len < 33 ? len : 33;  /* shorten() marks the cut */
            memcpy(raw, s, rl);
            raw[rl] = '\0';
            free(a);
            describe(k, lim, what, sizeof what);
            return api__fail(err, MCF_EINVAL,
                             "parameter '%s' must be %s, got \"%s\" (item %zu)",
                             k->name, what, shorten(raw, 32, sh), item);
        }
        a[i++] = (int32_t)v;
        s += len;
    }
    free(p->fixed_owned);
    p->fixed_owned = a;
    p->flow.fixed = a;
    p->flow.nfixed = (int)n;
    return MCF_OK;
}

/* set with an optional display form of the value (JSON non-strings). */
static mcf_status set_shown(api_params *p, const char *key, const char *text,
                            const char *shown, const api_limits *lim,
                            mcf_error *err)
{
    const keydef *k;
    value v;

    if (!key || !text)
        return api__fail(err, MCF_EINVAL, "parameter: NULL key or value");
    k = find_key(key);
    if (!k) {
        char list[256], s[48];
        size_t used = 0, i, room;
        list[0] = '\0';
        for (i = 0; i < NKEYS; i++) {
            int n = snprintf(list + used, sizeof list - used, "%s%s",
                             i ? "," : "", keys[i].name);
            if (n < 0 || (size_t)n >= sizeof list - used)
                break;
            used += (size_t)n;
        }
        /* The whole list fits in the message; the unknown name gets the
         * room left (8 to 32 characters, then "..."). */
        room = MCF_ERRMSG_SIZE - 1 - strlen("unknown parameter '...' (accepted: )");
        room = room > used + 8 ? room - used : 8;
        return api__fail(err, MCF_EINVAL, "unknown parameter '%s' (accepted: %s)",
                         shorten(key, room < 32 ? room : 32, s), list);
    }
    if (!shown && text[0] == '\0')
        return api__fail(err, MCF_EINVAL, "parameter '%s' has an empty value",
                         k->name);
    if (k->kind == K_LIST) {
        mcf_status rc;
        /* From JSON only an array ("[]" shown) or a string is a list. */
        if (shown && strcmp(shown, "[]") != 0)
            return bad_value(k, text, shown, lim, err);
        if ((rc = set_list(p, k, text, lim, err)) == MCF_OK)
            p->given |= 1u << (k - keys);
        return rc;
    }
    if (parse_value(k, text, lim, &v) != 0)
        return bad_value(k, text, shown, lim, err);
    k->apply(p, v);
    p->given |= 1u << (k - keys);
    return MCF_OK;
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

mcf_scheme api_default_scheme(long long nv)
{
    return nv > API_FAIRING_IMPLICIT_MAX ? MCF_FAIRING_EXPLICIT : MCF_FAIRING;
}

mcf_scheme api_params_scheme(const api_params *p, long long nv)
{
    if (!p)
        return api_default_scheme(nv);
    if (p->scheme_set || p->scheme_chosen)
        return p->flow.scheme;
    /* a request that sets a flow's parameters (time, dt, adaptive,
     * laplacian, mass, rescale) and no scheme is a flow request, as
     * before the fairing filter became the default: desbrun2 */
    return p->flow_keys_set ? MCF_DESBRUN2 : api_default_scheme(nv);
}

static int is_fairing(mcf_scheme s)
{
    return s == MCF_FAIRING || s == MCF_FAIRING_EXPLICIT;
}

int api_params_auto_amount(const api_params *p)
{
    return p->flow.strength_auto ||
           !(p->time_set || p->iterations_set || p->dt_set || p->strength_set);
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

mcf_status api_params_set(api_params *p, const char *key, const char *value_text,
                          const api_limits *lim, mcf_error *err)
{
    api_limits def;
    if (!lim) {
        api_limits_default(&def);
        lim = &def;
    }
    return set_shown(p, key, value_text, NULL, lim, err);
}

/* Depth of a parsed tree: a scalar is 0, {} or [] is 1. */
static int json_depth(const cJSON *j)
{
    int best = 0;
    const cJSON *c;
    if (!cJSON_IsObject(j) && !cJSON_IsArray(j))
        return 0;
    for (c = j->child; c; c = c->next) {
        int d = json_depth(c);
        if (d > best)
            best = d;
    }
    return best + 1;
}

/* Bracket depth of raw text (strings skipped), for a document cJSON
 * refused: nested past cJSON's own limit it is still an ELIMIT. */
static int text_depth(const char *s, size_t n)
{
    int d = 0, best = 0, in_str = 0;
    size_t i;
    for (i = 0; i < n; i++) {
        char c = s[i];
        if (in_str) {
            if (c == '\\')
                i++;
            else if (c == '"')
                in_str = 0;
        } else if (c == '"') {
            in_str = 1;
        } else if (c == '{' || c == '[') {
            if (++d > best)
                best = d;
        } else if (c == '}' || c == ']') {
            d--;
        }
    }
    return best;
}

/* JSON number as the text the query string would carry. */
static void number_text(double d, char *out, size_t size)
{
    if (d == floor(d) && fabs(d) < 1e15)
        snprintf(out, size, "%.0f", d);
    else
        snprintf(out, size, "%.17g", d);
}

static mcf_status set_json_list(api_params *p, const char *key, const cJSON *arr,
                                 const api_limits *lim, mcf_error *err)
{
    api_buf b;
    const cJSON *c;
    size_t item = 0;
    mcf_status rc = MCF_OK;

    api_buf_init(&b, 0);
    for (c = arr->child; c; c = c->next) {
        char num[40];
        item++;
        if (!cJSON_IsNumber(c)) {
            const keydef *k = find_key(key);
            char what[200];
            describe(k, lim, what, sizeof what);
            rc = api__fail(err, MCF_EINVAL,
                           "parameter '%s' must be %s, got %s (item %zu)", key, what,
                           cJSON_IsString(c) ? "a string" : cJSON_IsBool(c) ? "a boolean"
                           : cJSON_IsNull(c) ? "null" : "a nested value", item);
            goto done;
        }
        number_text(c->valuedouble, num, sizeof num);
        if (api_buf_printf(&b, "%s%s", item > 1 ? "," : "", num) != MCF_OK) {
            rc = api__fail(err, MCF_ENOMEM, "parameter '%s': no memory", key);
            goto done;
        }
    }
    /* An empty array is an empty list: nothing extra is fixed. */
    rc = set_shown(p, key, b.data ? b.data : "", "[]", lim, err);
done:
    api_buf_free(&b);
    return rc;
}

mcf_status api_params_set_json(api_params *p, const cJSON *obj,
                               const api_limits *lim, mcf_error *err)
{
    api_limits def;
    const cJSON *c;
    mcf_status rc = MCF_OK;

    if (!lim) {
        api_limits_default(&def);
        lim = &def;
    }
    if (!cJSON_IsObject(obj))
        return api__fail(err, MCF_EINVAL, "parameters: the top level must be a JSON object");
    for (c = obj->child; c && rc == MCF_OK; c = c->next) {
        char num[40];
        const char *key = c->string ? c->string : "";
        if (cJSON_IsString(c))
            rc = set_shown(p, key, c->valuestring, NULL, lim, err);
        else if (cJSON_IsNumber(c)) {
            number_text(c->valuedouble, num, sizeof num);
            rc = set_shown(p, key, num, NULL, lim, err);
        } else if (cJSON_IsBool(c))
            rc = set_shown(p, key, cJSON_IsTrue(c) ? "true" : "false",
                           cJSON_IsTrue(c) ? "true" : "false", lim, err);
        else if (cJSON_IsArray(c) && strcmp(key, "fixed_vertices") == 0)
            rc = set_json_list(p, key, c, lim, err);
        else
            rc = set_shown(p, key, "", cJSON_IsNull(c) ? "null"
                           : cJSON_IsArray(c) ? "an array" : "an object", lim, err);
    }
    return rc;
}

mcf_status api_params_parse_json(api_params *p, const char *buf, size_t len,
                                 const api_limits *lim, mcf_error *err)
{
    api_limits def;
    char *copy = NULL;
    const char *end = NULL;
    cJSON *root = NULL;
    mcf_status rc = MCF_OK;

    if (!lim) {
        api_limits_default(&def);
        lim = &def;
    }
    if (len > lim->max_json_bytes)
        return api__fail(err, MCF_ELIMIT,
                         "parameters: %zu bytes of JSON exceed max_json_bytes (%zu)",
                         len, lim->max_json_bytes);
    /* cJSON wants the terminating NUL inside the length it is given. */
    copy = malloc(len + 1);
    if (!copy)
        return api__fail(err, MCF_ENOMEM, "parameters: no memory");
    if (len)
        memcpy(copy, buf, len);
    copy[len] = '\0';
    root = cJSON_ParseWithLengthOpts(copy, len + 1, &end, 1);
    if (!root) {
        if (text_depth(copy, len) > lim->max_json_depth)
            rc = api__fail(err, MCF_ELIMIT,
                           "parameters: JSON nested deeper than max_json_depth (%d)",
                           lim->max_json_depth);
        else
            rc = api__fail(err, MCF_EINVAL, "parameters: invalid JSON near byte %zu",
                           end ? (size_t)(end - copy) : (size_t)0);
        goto done;
    }
    if (end != copy + len) {
        rc = api__fail(err, MCF_EINVAL, "parameters: NUL byte inside JSON at byte %zu",
                       (size_t)(end - copy));
        goto done;
    }
    if (json_depth(root) > lim->max_json_depth) {
        rc = api__fail(err, MCF_ELIMIT,
                       "parameters: JSON nested deeper than max_json_depth (%d)",
                       lim->max_json_depth);
        goto done;
    }
    rc = api_params_set_json(p, root, lim, err);
done:
    cJSON_Delete(root);
    free(copy);
    return rc;
}

static int hexval(char c)
{
    if (c >= '0' && c <= '9')
        return c - '0';
    if (c >= 'a' && c <= 'f')
        return c - 'a' + 10;
    if (c >= 'A' && c <= 'F')
        return c - 'A' + 10;
    return -1;
}

/* Percent-decodes n bytes of s into out (n + 1 bytes); '+' is a space. */
static int url_decode(const char *s, size_t n, char *out)
{
    size_t i, k = 0;
    for (i = 0; i < n; i++) {
        if (s[i] == '%') {
            int hi, lo;
            if (i + 2 >= n)
                return -1;
            hi = hexval(s[i + 1]);
            lo = hexval(s[i + 2]);
            if (hi < 0 || lo < 0 || (hi == 0 && lo == 0))
                return -1;
            out[k++] = (char)(hi * 16 + lo);
            i += 2;
        } else if (s[i] == '+') {
            out[k++] = ' ';
        } else {
            out[k++] = s[i];
        }
    }
    out[k] = '\0';
    return 0;
}

mcf_status api_params_parse_query(api_params *p, const char *qs,
                                  const char *const *ignore,
                                  const api_limits *lim, mcf_error *err)
{
    api_limits def;
    const char *s = qs;
    char *key = NULL, *val = NULL;
    mcf_status rc = MCF_OK;

    if (!lim) {
        api_limits_default(&def);
        lim = &def;
    }
    if (!qs)
        return MCF_OK;
    while (*s && rc == MCF_OK) {
        const char *amp = strchr(s, '&');
        size_t seg = amp ? (size_t)(amp - s) : strlen(s);
        const char *eq = memchr(s, '=', seg);
        size_t klen = eq ? (size_t)(eq - s) : seg;
        size_t vlen = eq ? seg - klen - 1 : 0;
        int skip = 0, i;
        char sh[48];

        if (seg == 0) {     /* "a=1&&b=2", trailing '&' */
            s += amp ? 1 : 0;
            continue;
        }
        key = malloc(klen + 1);
        val = malloc(vlen + 1);
        if (!key || !val) {
            rc = api__fail(err, MCF_ENOMEM, "query: no memory");
            break;
        }
        if (url_decode(s, klen, key) != 0 || (eq && url_decode(eq + 1, vlen, val) != 0)) {
            char raw[48];
            size_t rl = seg < 40 ? seg : 40;
            memcpy(raw, s, rl);
            raw[rl] = '\0';
            rc = api__fail(err, MCF_EINVAL, "query: bad percent-encoding in '%s'",
                           shorten(raw, 40, sh));
            break;
        }
        if (!eq)
            val[0] = '\0';
        if (key[0] == '\0') {
            rc = api__fail(err, MCF_EINVAL, "query: a parameter without a name");
            break;
        }
        for (i = 0; ignore && ignore[i]; i++)
            if (strcmp(key, ignore[i]) == 0)
                skip = 1;
        if (!skip)
            rc = set_shown(p, key, val, NULL, lim, err);
        free(key);
        free(val);
        key = val = NULL;
        s += seg + (amp ? 1 : 0);
    }
    free(key);
    free(val);
    return rc;
}

double api_params_steps(const api_params *p, const api_limits *lim,
                        int *by_mesh)
{
    const mcf_flow_params *f = &p->flow;
    /* unnamed and not chosen yet (before the mesh): desbrun2 for a flow
     * request, else a fairing filter, which the mesh's size picks */
    mcf_scheme s = api_params_scheme(p, 0);
    int known = p->scheme_set || p->scheme_chosen || p->flow_keys_set,
        mesh = 0;
    /* Taubin's automatic pass count (api_params_auto_amount) */
    int auto_passes = s == MCF_TAUBIN && f->iterations <= 0 &&
                      api_params_auto_amount(p);
    double n;

    if (is_fairing(s) && f->iterations <= 0) {
        /* the fairing filters' automatic amount stops at its cap (the
         * larger one while the filter is not known), or at max_steps
         * (which the work limit may lower) */
        double cap = known && s == MCF_FAIRING ? MCF_FAIRING_MAX_STEPS
                                               : MCF_FAIRING_MAX_PASSES;
        mesh = 1;
        n = f->max_steps > 0 && f->max_steps < cap ? f->max_steps : cap;
    } else if (!auto_passes && (s == MCF_TAUBIN || is_fairing(s) ||
                                (!f->adaptive && !f->dt_auto && !(f->dt > 0.0))))
        n = f->iterations > 0 ? f->iterations : MCF_DEFAULT_STEPS;
    else if (!auto_passes && !f->adaptive && !f->dt_auto && f->time > 0.0)
        n = ceil(f->time / f->dt - 1e-9);
    else if (!auto_passes && !f->adaptive && f->iterations > 0 && f->time <= 0.0)
        n = f->iterations;
    else {
        mesh = 1;
        n = f->max_steps > 0 && f->max_steps < lim->max_iterations
                ? f->max_steps : lim->max_iterations;
    }
    if (by_mesh)
        *by_mesh = mesh;
    return n;
}

/* time, dt and iterations say the same thing twice (mcf.h: "The amount
 * of smoothing"): with time and dt given, the steps are ceil(time / dt)
 * and iterations would be dropped without a word, and a dt over the time
 * would be cut to it. Refused, naming both, unless they agree. */
static mcf_status amounts_agree(const api_params *p, mcf_error *err)
{
    const mcf_flow_params *f = &p->flow;
    double steps;

    if (!p->time_set || !(f->time > 0.0))
        return MCF_OK;
    if (f->dt_auto && p->iterations_set)
        return api__fail(err, MCF_EINVAL,
                         "parameters 'time' and 'iterations' contradict 'dt' = auto, which "
                         "sets the steps itself: give dt=auto with time, or time with "
                         "iterations");
    if (!(f->dt > 0.0))
        return MCF_OK;
    if (f->dt > f->time * (1.0 + 1e-12))
        return api__fail(err, MCF_EINVAL,
                         "parameter 'dt' (%g) is larger than 'time' (%g): the run would be "
                         "one step of the time; give a dt at most the time, or drop one",
                         f->dt, f->time);
    /* the core's own count (api_params_steps, the work bound's too) */
    steps = ceil(f->time / f->dt - 1e-9);
    if (p->iterations_set && steps != (double)f->iterations)
        return api__fail(err, MCF_EINVAL,
                         "parameters 'time' (%g) and 'dt' (%g) make %.0f steps, but "
                         "'iterations' says %d: give two of the three",
                         f->time, f->dt, steps, f->iterations);
    return MCF_OK;
}

mcf_status api_params_finish(api_params *p, int nv, const api_limits *lim,
                             mcf_error *err)
{
    api_limits def;
    double steps;
    mcf_status rc;
    int i, by_mesh;

    if (!lim) {
        api_limits_default(&def);
        lim = &def;
    }
    if (p->tol_set && !p->flow.adaptive)
        return api__fail(err, MCF_EINVAL,
                         "parameter 'tol' applies to adaptive runs only: add adaptive=true or drop tol");
    if (!p->scheme_set) {
        p->scheme_chosen = 0;
        p->flow.scheme = api_params_scheme(p, nv);
        p->scheme_chosen = 1;
    }
    /* the fairing filters' strength: the noise level (mean edges) whose
     * removal their amount optimizes; unset or auto: estimated */
    if (is_fairing(p->flow.scheme))
        p->flow.noise_sigma = p->strength_set && !p->flow.strength_auto ? p->flow.strength : 0.0;
    for (i = 0; i < p->flow.nfixed; i++)
        if (p->flow.fixed[i] < 0 || p->flow.fixed[i] >= nv)
            return api__fail(err, MCF_EINVAL,
                             "parameter 'fixed_vertices': index %ld out of range (0..%d)",
                             (long)p->flow.fixed[i], nv - 1);
    /* the MCF schemes' and Taubin's automatic amount (the fairing filters
     * choose their own: noise_sigma above) */
    if (!is_fairing(p->flow.scheme))
        p->flow.strength_auto = api_params_auto_amount(p);
    if ((rc = mcf_flow_params_check(&p->flow, nv, err)) != MCF_OK)
        return rc;
    if ((rc = amounts_agree(p, err)) != MCF_OK)
        return rc;
    if (nv < 1)
        return api__fail(err, MCF_EINVAL, "mesh has no vertices");

    /* Work bound: steps x vertices. When the parameters alone give the
     * step count, it is checked here; when it depends on the mesh (its
     * edge lengths, lambda_max, a fairing filter's estimated noise, or
     * Taubin's automatic pass count), the core's hard cap max_steps is
     * lowered to what the limits allow instead. */
    steps = api_params_steps(p, lim, &by_mesh);
    if (!by_mesh && steps > lim->max_iterations) {
        /* iterations are bounded when parsed: time / dt */
        return api__fail(err, MCF_EINVAL,
                         "parameters 'time'/'dt' = %.3g steps exceeds max_iterations (%d)",
                         steps, lim->max_iterations);
    } else if (by_mesh && is_fairing(p->flow.scheme)) {
        /* the automatic amount stops at its cap, max_steps or the work
         * limit, whichever comes first */
        double cap = p->flow.scheme == MCF_FAIRING ? MCF_FAIRING_MAX_STEPS : MCF_FAIRING_MAX_PASSES;
        double room = floor(lim->max_work / nv);
        if (room < cap && room < p->flow.max_steps)
            p->flow.max_steps = room < 1 ? 1 : (int)room;
        steps = fmin(cap, p->flow.max_steps);
    } else if (by_mesh) {
        double cap = floor(lim->max_work / nv);
        if (cap < p->flow.max_steps)
            p->flow.max_steps = cap < 1 ? 1 : (int)cap;
        if (p->flow.max_steps > lim->max_iterations)
            p->flow.max_steps = lim->max_iterations;
        steps = p->flow.max_steps;
    }
    if (steps * (double)nv > lim->max_work)
        return api__fail(err, MCF_ELIMIT,
                         "work of %.0f steps x %d vertices = %.3g exceeds max_work (%.3g)",
                         steps, nv, steps * (double)nv, lim->max_work);
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
             ((p->scheme_set || p->scheme_chosen) && !is_fairing(p->flow.scheme) && !api_params_auto_amount(p)))
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
        k = find_key(c->string);
        if (!k || !(p->given & (1u << (k - keys))))
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
        const keydef *k = &keys[i];
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
        describe(k, lim, what, sizeof what);
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
            ok &= cJSON_AddItemToObject(o, "enum", string_array(format_names));
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
