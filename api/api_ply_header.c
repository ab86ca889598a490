/* SPDX-License-Identifier: MIT */
/*
 * api_ply_header.c - the PLY header (api_ply_internal.h): the format line,
 * elements and their properties, each property given the role the reader
 * reads it for (x y z, the face's vertex_indices, the attributes), and
 * the smallest encoded size of an element, which bounds declared counts
 * by the body's size before anything is allocated (api_ply.c).
 */
#include <limits.h>
#include <stdlib.h>
#include <string.h>

#include "api_ply_internal.h"

static const struct {
    const char *name;
    ptype t;
} type_names[] = {
    {"char", T_I8},    {"int8", T_I8},     {"uchar", T_U8},   {"uint8", T_U8},
    {"short", T_I16},  {"int16", T_I16},   {"ushort", T_U16}, {"uint16", T_U16},
    {"int", T_I32},    {"int32", T_I32},   {"uint", T_U32},   {"uint32", T_U32},
    {"float", T_F32},  {"float32", T_F32}, {"double", T_F64}, {"float64", T_F64},
};

const size_t api__ply_type_size[T_F64 + 1] = {0, 1, 1, 2, 2, 4, 4, 4, 8};

/* Vertex property names of the attribute roles, ROLE_NX on. */
static const char *const vrole_names[NVROLES][3] = {
    {"nx", NULL, NULL}, {"ny", NULL, NULL}, {"nz", NULL, NULL},
    {"s", "u", "texture_u"}, {"t", "v", "texture_v"},
    {"red", "r", NULL}, {"green", "g", NULL}, {"blue", "b", NULL},
    {"alpha", "a", NULL},
};

void api__ply_header_free(header *h)
{
    int i;
    for (i = 0; i < h->nel; i++)
        free(h->el[i].props);
    free(h->el);
    h->el = NULL;
    h->nel = h->cap = 0;
}

const char *api__ply_type_name(ptype t)
{
    size_t i;
    for (i = 0; i < sizeof type_names / sizeof type_names[0]; i++)
        if (type_names[i].t == t)
            return type_names[i].name;
    return "double";
}

static ptype parse_type(const char *t, size_t n)
{
    size_t i;
    for (i = 0; i < sizeof type_names / sizeof type_names[0]; i++)
        if (api__tok_is(t, n, type_names[i].name))
            return type_names[i].t;
    return T_NONE;
}

/* An unsigned decimal integer token (no sign, no spaces), at most ULLONG_MAX. */
static int parse_count(const char *t, size_t n, unsigned long long *out)
{
    unsigned long long v = 0;
    size_t i;
    if (n == 0)
        return -1;
    for (i = 0; i < n; i++) {
        unsigned d;
        if (t[i] < '0' || t[i] > '9')
            return -1;
        d = (unsigned)(t[i] - '0');
        if (v > (ULLONG_MAX - d) / 10)
            return -1;
        v = v * 10 + d;
    }
    *out = v;
    return 0;
}

static mcf_status add_element(header *h, const char *name, size_t nlen,
                              unsigned long long count, mcf_error *err)
{
    element *e;
    if (h->nel == h->cap) {
        int ncap = h->cap ? 2 * h->cap : 4;
        element *p = realloc(h->el, (size_t)ncap * sizeof *p);
        if (!p)
            return api__fail(err, MCF_ENOMEM, "ply: out of memory in the header");
        h->el = p;
        h->cap = ncap;
    }
    e = &h->el[h->nel++];
    memset(e, 0, sizeof *e);
    e->name = name;
    e->nlen = nlen;
    e->count = count;
    e->is_vertex = api__tok_is(name, nlen, "vertex");
    e->is_face = api__tok_is(name, nlen, "face");
    return MCF_OK;
}

static mcf_status add_prop(element *e, const prop *p, mcf_error *err)
{
    if (e->nprops == e->cap) {
        int ncap = e->cap ? 2 * e->cap : 8;
        prop *q = realloc(e->props, (size_t)ncap * sizeof *q);
        if (!q)
            return api__fail(err, MCF_ENOMEM, "ply: out of memory in the header");
        e->props = q;
        e->cap = ncap;
    }
    e->props[e->nprops++] = *p;
    return MCF_OK;
}


/* The format line (after its keyword, at s): ascii or a binary byte
 * order, version 1.0, once and before any element. */
static mcf_status parse_format(const char *s, const char *le, long line, header *h,
                               int *have_format, mcf_error *err)
{
    const char *t;
    size_t n;
    char shown[API__SHOWN];

    if (*have_format)
        return api__fail(err, MCF_EDECODE,
                         "ply: line %ld: second format line", line);
    if (h->nel)
        return api__fail(err, MCF_EDECODE,
                         "ply: line %ld: format line after an element", line);
    n = api__token(&s, le, &t);
    if (api__tok_is(t, n, "ascii"))
        h->format = FMT_ASCII;
    else if (api__tok_is(t, n, "binary_little_endian"))
        h->format = FMT_LE;
    else if (api__tok_is(t, n, "binary_big_endian"))
        h->format = FMT_BE;
    else
        return api__fail(err, MCF_EDECODE,
                         "ply: line %ld: unknown format '%s' (ascii, "
                         "binary_little_endian, binary_big_endian)",
                         line, api__show(t, n, shown));
    n = api__token(&s, le, &t);
    if (!api__tok_is(t, n, "1.0") || api__token(&s, le, &t) != 0)
        return api__fail(err, MCF_EDECODE,
                         "ply: line %ld: format version must be 1.0", line);
    *have_format = 1;
    return MCF_OK;
}

/* An element line (after its keyword): its name, once, and its count. */
static mcf_status parse_element(const char *s, const char *le, long line, header *h,
                                mcf_error *err)
{
    const char *t, *name, *ct;
    size_t nn, cn;
    unsigned long long count;
    int i;
    char shown[API__SHOWN];

    nn = api__token(&s, le, &name);
    cn = api__token(&s, le, &ct);
    if (nn == 0 || cn == 0 || api__token(&s, le, &t) != 0)
        return api__fail(err, MCF_EDECODE,
                         "ply: line %ld: 'element <name> <count>' expected",
                         line);
    if (parse_count(ct, cn, &count) != 0)
        return api__fail(err, MCF_EDECODE,
                         "ply: line %ld: bad element count '%s'", line,
                         api__show(ct, cn, shown));
    for (i = 0; i < h->nel; i++)
        if (h->el[i].nlen == nn && memcmp(h->el[i].name, name, nn) == 0)
            return api__fail(err, MCF_EDECODE,
                             "ply: line %ld: element '%s' declared twice",
                             line, api__show(name, nn, shown));
    return add_element(h, name, nn, count, err);
}

/* The role of a vertex scalar property pr of e: x, y, z or an attribute
 * (the first of its names; a second name of a role taken stays unread). */
static int vertex_role(const element *e, const prop *pr)
{
    const char *name = pr->name;
    size_t nn = pr->nlen;
    int i, role = ROLE_NONE;
    if (api__tok_is(name, nn, "x"))
        role = ROLE_X;
    else if (api__tok_is(name, nn, "y"))
        role = ROLE_Y;
    else if (api__tok_is(name, nn, "z"))
        role = ROLE_Z;
    for (i = 0; role == ROLE_NONE && i < NVROLES; i++) {
        int j;
        for (j = 0; j < 3 && vrole_names[i][j]; j++)
            if (api__tok_is(name, nn, vrole_names[i][j]))
                role = ROLE_NX + i;
    }
    /* A second name of a role taken (u after s) stays unread. */
    for (i = 0; role >= ROLE_NX && i < e->nprops; i++)
        if (e->props[i].role == role)
            role = ROLE_NONE;
    return role;
}

/* The type part of a property line: [list <count type>] <type>, into pr;
 * *s moves past it. */
static mcf_status parse_prop_type(const char **s, const char *le, long line, prop *pr,
                                  mcf_error *err)
{
    const char *t;
    size_t n = api__token(s, le, &t);
    char shown[API__SHOWN];

    if (api__tok_is(t, n, "list")) {
        pr->is_list = 1;
        n = api__token(s, le, &t);
        pr->count_type = parse_type(t, n);
        if (pr->count_type == T_NONE)
            return api__fail(err, MCF_EDECODE,
                             "ply: line %ld: unknown list count type '%s'",
                             line, api__show(t, n, shown));
        if (!is_int_type(pr->count_type))
            return api__fail(err, MCF_EDECODE,
                             "ply: line %ld: list count type '%s' is not an "
                             "integer type",
                             line, api__show(t, n, shown));
        n = api__token(s, le, &t);
    }
    pr->type = parse_type(t, n);
    if (pr->type == T_NONE)
        return api__fail(err, MCF_EDECODE,
                         "ply: line %ld: unknown property type '%s'", line,
                         api__show(t, n, shown));
    return MCF_OK;
}

/* A property line (after its keyword), of the last element: its type,
 * its name (once per element) and the role it is read for. */
static mcf_status parse_property(const char *s, const char *le, long line, header *h,
                                 mcf_error *err)
{
    prop pr;
    element *e;
    const char *t, *name;
    size_t nn;
    int i;
    char shown[API__SHOWN];
    mcf_status rc;

    memset(&pr, 0, sizeof pr);
    if (h->nel == 0)
        return api__fail(err, MCF_EDECODE,
                         "ply: line %ld: property before any element", line);
    e = &h->el[h->nel - 1];
    if ((rc = parse_prop_type(&s, le, line, &pr, err)) != MCF_OK)
        return rc;
    nn = api__token(&s, le, &name);
    if (nn == 0 || api__token(&s, le, &t) != 0)
        return api__fail(err, MCF_EDECODE,
                         "ply: line %ld: 'property [list <count> <item>] "
                         "<type> <name>' expected",
                         line);
    for (i = 0; i < e->nprops; i++)
        if (e->props[i].nlen == nn && memcmp(e->props[i].name, name, nn) == 0)
            return api__fail(err, MCF_EDECODE,
                             "ply: line %ld: property '%s' declared twice",
                             line, api__show(name, nn, shown));
    pr.name = name;
    pr.nlen = nn;
    if (e->is_vertex && !pr.is_list) {
        pr.role = vertex_role(e, &pr);
        if (pr.role == ROLE_NONE) {
            pr.role = ROLE_EXTRA;
            pr.extra = e->nextra++;
        }
    }
    if (e->is_face && pr.is_list && api__tok_is(name, nn, "texcoord"))
        pr.role = ROLE_FTC;
    if (e->is_face
        && (api__tok_is(name, nn, "vertex_indices")
            || api__tok_is(name, nn, "vertex_index"))) {
        for (i = 0; i < e->nprops; i++)
            if (e->props[i].role == ROLE_INDICES)
                return api__fail(err, MCF_EDECODE,
                                 "ply: line %ld: both vertex_indices and "
                                 "vertex_index",
                                 line);
        if (!pr.is_list)
            return api__fail(err, MCF_EDECODE,
                             "ply: line %ld: face property '%s' must be a list",
                             line, api__show(name, nn, shown));
        if (!is_int_type(pr.type))
            return api__fail(err, MCF_EDECODE,
                             "ply: line %ld: face indices must have an "
                             "integer type",
                             line);
        pr.role = ROLE_INDICES;
    }
    return add_prop(e, &pr, err);
}

mcf_status api__ply_parse_header(const char *buf, size_t len, header *h,
                                 mcf_error *err)
{
    api__lines c = {buf, buf + len, 0};
    const char *s, *le;
    int have_format = 0;
    char shown[API__SHOWN];
    mcf_status rc;

    while (api__line_next(&c, &s, &le)) {
        const char *t;
        long line = c.line;
        size_t n = api__token(&s, le, &t);
        if (line == 1) {
            /* le == c.end: the line has no '\n' (le is one otherwise). */
            if (!api__tok_is(t, n, "ply") || api__token(&s, le, &t) != 0
                || le == c.end)
                return api__fail(err, MCF_EDECODE,
                                 "ply: line 1 must be 'ply' alone");
            continue;
        }
        if (n == 0)
            return api__fail(err, MCF_EDECODE, "ply: line %ld: empty header line",
                             line);
        if (api__tok_is(t, n, "comment") || api__tok_is(t, n, "obj_info"))
            continue;
        if (api__tok_is(t, n, "end_header")) {
            if (!have_format)
                return api__fail(err, MCF_EDECODE,
                                 "ply: line %ld: end_header before any format line",
                                 line);
            if (api__token(&s, le, &t) != 0)
                return api__fail(err, MCF_EDECODE,
                                 "ply: line %ld: text after end_header", line);
            h->body = (size_t)(c.p - buf);
            h->body_line = line + 1;
            return MCF_OK;
        }
        if (api__tok_is(t, n, "format"))
            rc = parse_format(s, le, line, h, &have_format, err);
        else if (api__tok_is(t, n, "element"))
            rc = parse_element(s, le, line, h, err);
        else if (api__tok_is(t, n, "property"))
            rc = parse_property(s, le, line, h, err);
        else
            return api__fail(err, MCF_EDECODE, "ply: line %ld: unknown header keyword '%s'",
                             line, api__show(t, n, shown));
        if (rc != MCF_OK)
            return rc;
    }
    return api__fail(err, MCF_EDECODE, "ply: no end_header line");
}

/* Smallest number of bytes one instance of e can take in the body. ASCII:
 * every value is at least one character plus a separator (the last one a
 * newline); the face list at least "3 a b c". Binary: the scalar sizes,
 * list counts, and three indices for the face list. */
unsigned long long api__ply_min_size(const element *e, int format)
{
    unsigned long long s = 0;
    int i;
    for (i = 0; i < e->nprops; i++) {
        const prop *p = &e->props[i];
        unsigned items = p->role == ROLE_INDICES ? 3 : 0;
        if (format == FMT_ASCII)
            s += 2 * (p->is_list ? 1 + items : 1);
        else
            s += p->is_list ? api__ply_type_size[p->count_type] + items * api__ply_type_size[p->type]
                            : api__ply_type_size[p->type];
    }
    return s;
}
