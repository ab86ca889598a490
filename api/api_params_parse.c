/* SPDX-License-Identifier: MIT */
/*
 * api_params_parse.c - job parameter values from text, JSON bodies and URL
 * query strings, through the table of api_params.c and one validation
 * path (set_shown). A failing set leaves the parameters unchanged.
 */
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "api_params_internal.h"

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

/* The choice of a named key nearest to text (api_nearest_name), or NULL. */
static const char *nearest_choice(const keydef *k, const char *text)
{
    const char *names[MCF_NSCHEMES + 1];
    size_t n = 0;

    if (k->kind == K_SCHEME) {
        for (n = 0; n < (size_t)MCF_NSCHEMES; n++)
            names[n] = mcf_scheme_get((mcf_scheme)n)->name;
        return api_nearest_name(text, names, n);
    }
    if (k->kind != K_ENUM && k->kind != K_FORMAT)
        return NULL;
    for (const char *const *c = k->kind == K_ENUM ? k->names : api__format_names; *c; c++)
        n++;
    return api_nearest_name(text, k->kind == K_ENUM ? k->names : api__format_names, n);
}

/* The EINVAL of a bad value. shown: how to print the value (NULL: the
 * text in quotes); a choice near the text is offered. */
static mcf_status bad_value(const keydef *k, const char *text,
                            const char *shown, const api_limits *lim,
                            mcf_error *err)
{
    char what[200], s[48], hint[48] = "";
    const char *near = shown ? NULL : nearest_choice(k, text);
    api__param_accepts(k, lim, what, sizeof what);
    if (near)
        snprintf(hint, sizeof hint, " (did you mean %s?)", near);
    if (shown)
        return api__fail(err, MCF_EINVAL, "parameter '%s' must be %s, got %s",
                         k->name, what, shown);
    return api__fail(err, MCF_EINVAL, "parameter '%s' must be %s, got \"%s\"%s",
                     k->name, what, shorten(text, 40, s), hint);
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
        if (strcmp(t, "drc") == 0)     /* Draco's extension, as OUT's names it */
            t = "draco";
        for (i = 0; api__format_names[i]; i++)
            if (strcmp(t, api__format_names[i]) == 0) {
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
            api__param_accepts(k, lim, what, sizeof what);
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
    k = api__param_find(key);
    if (!k) {
        char list[256], s[48];
        const char *names[64], *near;
        size_t used = 0, i, room;
        /* A name near it is the whole answer (the list leaves it no room). */
        for (i = 0; i < api__param_nkeys && i < 64; i++)
            names[i] = api__param_keys[i].name;
        if ((near = api_nearest_name(key, names, i)) != NULL)
            return api__fail(err, MCF_EINVAL, "unknown parameter '%s' (did you mean '%s'?)",
                             shorten(key, 40, s), near);
        list[0] = '\0';
        for (i = 0; i < api__param_nkeys; i++) {
            int n = snprintf(list + used, sizeof list - used, "%s%s",
                             i ? "," : "", api__param_keys[i].name);
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
            p->given |= 1u << (k - api__param_keys);
        return rc;
    }
    if (parse_value(k, text, lim, &v) != 0)
        return bad_value(k, text, shown, lim, err);
    k->apply(p, v);
    p->given |= 1u << (k - api__param_keys);
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
    int d = 0, best = 0, c;
    size_t i = 0;
    while ((c = api__json_next(s, n, &i)) >= 0) {
        if (c == '{' || c == '[') {
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
            const keydef *k = api__param_find(key);
            char what[200];
            api__param_accepts(k, lim, what, sizeof what);
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

mcf_status api_params_parse_request(api_params *p, const char *params_json,
                                    const cJSON *fields, const char *query,
                                    const char *const *ignore,
                                    const api_limits *lim, mcf_error *err)
{
    mcf_status rc = MCF_OK;
    const cJSON *f;

    if (params_json &&
        (rc = api_params_parse_json(p, params_json, strlen(params_json), lim,
                                    err)) != MCF_OK)
        return rc;
    cJSON_ArrayForEach(f, fields) {
        const char *k = cJSON_GetStringValue(cJSON_GetArrayItem(f, 0));
        const char *v = cJSON_GetStringValue(cJSON_GetArrayItem(f, 1));
        if (k && v && (rc = api_params_set(p, k, v, lim, err)) != MCF_OK)
            return rc;
    }
    if (query && query[0])
        rc = api_params_parse_query(p, query, ignore, lim, err);
    return rc;
}
