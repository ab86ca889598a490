/*
 * api_ply.c - Stanford PLY reader and writer on memory buffers.
 *
 * Reader: ascii, binary_little_endian and binary_big_endian bodies. The
 * header is parsed into elements and their properties; any element other
 * than `vertex` and `face` is skipped, as is every property other than
 * the vertex's x, y, z (any scalar type) and the face's `vertex_indices`
 * (or `vertex_index`) list (any integer count and item types). Polygons are
 * fan-triangulated (v0, vi, vi+1). Before anything is allocated, every
 * declared count is checked against the size of the body (each element
 * has a minimum encoded size: a tiny body cannot announce a billion faces)
 * and then against the api_limits. ASCII bodies are read one element per
 * line (the PLY convention), so an error names its line; binary errors name
 * the element, its index and the byte offset. The buffer is never read past
 * len and need not be NUL-terminated.
 *
 * Writer: ascii or binary_little_endian (independent of the host's byte
 * order), double x y z, optional float `mean_curvature` and
 * `gaussian_curvature` vertex properties, `property list uchar int
 * vertex_indices` triangles. ASCII doubles use %.17g (exact round trip).
 */
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "api_internal.h"

typedef enum { T_NONE = 0, T_I8, T_U8, T_I16, T_U16, T_I32, T_U32, T_F32, T_F64 } ptype;

static const struct {
    const char *name;
    ptype t;
} type_names[] = {
    {"char", T_I8},    {"int8", T_I8},     {"uchar", T_U8},   {"uint8", T_U8},
    {"short", T_I16},  {"int16", T_I16},   {"ushort", T_U16}, {"uint16", T_U16},
    {"int", T_I32},    {"int32", T_I32},   {"uint", T_U32},   {"uint32", T_U32},
    {"float", T_F32},  {"float32", T_F32}, {"double", T_F64}, {"float64", T_F64},
};

static const size_t type_size[] = {0, 1, 1, 2, 2, 4, 4, 4, 8};

enum { ROLE_NONE = 0, ROLE_X, ROLE_Y, ROLE_Z, ROLE_INDICES };
enum { FMT_ASCII = 0, FMT_LE, FMT_BE };

typedef struct {
    const char *name;       /* into the input buffer */
    size_t nlen;
    int is_list;
    ptype type;             /* scalar type, or the list's item type */
    ptype count_type;       /* list only */
    int role;
} prop;

typedef struct {
    const char *name;
    size_t nlen;
    unsigned long long count;
    prop *props;
    int nprops, cap;
    int is_vertex, is_face;
} element;

typedef struct {
    int format;
    element *el;
    int nel, cap;
    size_t body;            /* offset of the first body byte */
    long body_line;         /* ASCII: number of the first body line */
} header;

static void header_free(header *h)
{
    int i;
    for (i = 0; i < h->nel; i++)
        free(h->el[i].props);
    free(h->el);
    h->el = NULL;
    h->nel = h->cap = 0;
}

static ptype parse_type(const char *t, size_t n)
{
    size_t i;
    for (i = 0; i < sizeof type_names / sizeof type_names[0]; i++)
        if (api__tok_is(t, n, type_names[i].name))
            return type_names[i].t;
    return T_NONE;
}

static int is_int_type(ptype t)
{
    return t != T_NONE && t != T_F32 && t != T_F64;
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

/* Parses the header up to and including the end_header line. */
static mcf_status parse_header(const char *buf, size_t len, header *h,
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
        if (api__tok_is(t, n, "format")) {
            if (have_format)
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
            have_format = 1;
            continue;
        }
        if (api__tok_is(t, n, "element")) {
            const char *name, *ct;
            size_t nn, cn;
            unsigned long long count;
            int i;
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
            if ((rc = add_element(h, name, nn, count, err)) != MCF_OK)
                return rc;
            continue;
        }
        if (api__tok_is(t, n, "property")) {
            prop pr;
            element *e;
            const char *name;
            size_t nn;
            int i;
            memset(&pr, 0, sizeof pr);
            if (h->nel == 0)
                return api__fail(err, MCF_EDECODE,
                                 "ply: line %ld: property before any element", line);
            e = &h->el[h->nel - 1];
            n = api__token(&s, le, &t);
            if (api__tok_is(t, n, "list")) {
                pr.is_list = 1;
                n = api__token(&s, le, &t);
                pr.count_type = parse_type(t, n);
                if (pr.count_type == T_NONE)
                    return api__fail(err, MCF_EDECODE,
                                     "ply: line %ld: unknown list count type '%s'",
                                     line, api__show(t, n, shown));
                if (!is_int_type(pr.count_type))
                    return api__fail(err, MCF_EDECODE,
                                     "ply: line %ld: list count type '%s' is not an "
                                     "integer type",
                                     line, api__show(t, n, shown));
                n = api__token(&s, le, &t);
            }
            pr.type = parse_type(t, n);
            if (pr.type == T_NONE)
                return api__fail(err, MCF_EDECODE,
                                 "ply: line %ld: unknown property type '%s'", line,
                                 api__show(t, n, shown));
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
                if (api__tok_is(name, nn, "x"))
                    pr.role = ROLE_X;
                else if (api__tok_is(name, nn, "y"))
                    pr.role = ROLE_Y;
                else if (api__tok_is(name, nn, "z"))
                    pr.role = ROLE_Z;
            }
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
            if ((rc = add_prop(e, &pr, err)) != MCF_OK)
                return rc;
            continue;
        }
        return api__fail(err, MCF_EDECODE, "ply: line %ld: unknown header keyword '%s'",
                         line, api__show(t, n, shown));
    }
    return api__fail(err, MCF_EDECODE, "ply: no end_header line");
}

/* Smallest number of bytes one instance of e can take in the body. ASCII:
 * every value is at least one character plus a separator (the last one a
 * newline); the face list at least "3 a b c". Binary: the scalar sizes,
 * list counts, and three indices for the face list. */
static unsigned long long min_size(const element *e, int format)
{
    unsigned long long s = 0;
    int i;
    for (i = 0; i < e->nprops; i++) {
        const prop *p = &e->props[i];
        unsigned items = p->role == ROLE_INDICES ? 3 : 0;
        if (format == FMT_ASCII)
            s += 2 * (p->is_list ? 1 + items : 1);
        else
            s += p->is_list ? type_size[p->count_type] + items * type_size[p->type]
                            : type_size[p->type];
    }
    return s;
}

/* ---------------------------------------------------------------- body */

typedef struct {
    const char *buf;
    size_t len, pos;        /* binary cursor */
    int format;
    api__lines txt;         /* ASCII cursor; txt.line: the current line */
    int nv;
    double *X;
    api__tris T;            /* the triangles so far */
    const api_limits *lim;
} body;

/* The value of type t stored at b; swap: the file's byte order differs
 * from the host's. */
static double get_scalar(const unsigned char *b, ptype t, int swap)
{
    unsigned char u[8];
    size_t n = type_size[t], i;
    for (i = 0; i < n; i++)
        u[i] = swap ? b[n - 1 - i] : b[i];
    switch (t) {
    case T_I8: return (double)(int8_t)u[0];
    case T_U8: return (double)u[0];
    case T_I16: { int16_t v; memcpy(&v, u, 2); return v; }
    case T_U16: { uint16_t v; memcpy(&v, u, 2); return v; }
    case T_I32: { int32_t v; memcpy(&v, u, 4); return v; }
    case T_U32: { uint32_t v; memcpy(&v, u, 4); return v; }
    case T_F32: { float v; memcpy(&v, u, 4); return v; }
    case T_F64: { double v; memcpy(&v, u, 8); return v; }
    case T_NONE: break;
    }
    return 0.0;
}

static int host_big(void)
{
    const uint16_t one = 1;
    unsigned char c;
    memcpy(&c, &one, 1);
    return c == 0;
}

static mcf_status add_triangle(body *b, int32_t a, int32_t c, int32_t d,
                               const char *where, unsigned long long idx,
                               mcf_error *err)
{
    long long want = 0;
    mcf_status rc = api__tris_add(&b->T, a, c, d, b->lim->max_faces, 1024, &want);
    if (rc == MCF_ELIMIT)
        return api__fail(err, rc, "ply: %s %llu: more than max_faces (%d) triangles",
                         where, idx, b->lim->max_faces);
    if (rc != MCF_OK)
        return api__fail(err, rc, "ply: out of memory for %lld triangles", want);
    return MCF_OK;
}

/* One face's index list, value by value: fan-triangulates and checks
 * indices. k is the position in the list, count its length. */
typedef struct {
    int32_t first, prev;
} fan;

static mcf_status fan_add(body *b, fan *f, long long k, double v,
                          unsigned long long idx, mcf_error *err)
{
    int32_t i;
    if (!(v >= 0 && v < b->nv) || v != floor(v)) {
        if (b->format == FMT_ASCII)
            return api__fail(err, MCF_EDECODE,
                             "ply: line %ld: face %llu: index %.0f out of range (0..%d)",
                             b->txt.line, idx, v, b->nv - 1);
        return api__fail(err, MCF_EDECODE,
                         "ply: face %llu: index %.0f out of range (0..%d)", idx, v,
                         b->nv - 1);
    }
    i = (int32_t)v;
    if (k == 0)
        f->first = i;
    else if (k >= 2) {
        mcf_status rc = add_triangle(b, f->first, f->prev, i, "face", idx, err);
        if (rc != MCF_OK)
            return rc;
    }
    f->prev = i;
    return MCF_OK;
}

static mcf_status bad_count(const body *b, long long count, unsigned long long idx,
                            mcf_error *err)
{
    if (b->format == FMT_ASCII)
        return api__fail(err, MCF_EDECODE,
                         "ply: line %ld: face %llu has %lld vertices, at least 3 needed",
                         b->txt.line, idx, count);
    return api__fail(err, MCF_EDECODE,
                     "ply: face %llu has %lld vertices, at least 3 needed", idx,
                     count);
}

static mcf_status read_binary(body *b, const header *h, mcf_error *err)
{
    const unsigned char *u = (const unsigned char *)b->buf;
    int swap = (h->format == FMT_BE) != host_big();
    char shown[API__SHOWN];
    int ei, pi;
    mcf_status rc;

    for (ei = 0; ei < h->nel; ei++) {
        const element *e = &h->el[ei];
        unsigned long long r;
        if (e->nprops == 0) /* takes no bytes, whatever its count */
            continue;
        for (r = 0; r < e->count; r++) {
            for (pi = 0; pi < e->nprops; pi++) {
                const prop *p = &e->props[pi];
                size_t left = b->len - b->pos;
                if (!p->is_list) {
                    size_t sz = type_size[p->type];
                    if (left < sz)
                        goto truncated;
                    if (p->role >= ROLE_X && p->role <= ROLE_Z) {
                        double v = get_scalar(u + b->pos, p->type, swap);
                        if (!isfinite(v))
                            return api__fail(err, MCF_EDECODE,
                                             "ply: vertex %llu: coordinate %s is "
                                             "not finite",
                                             r, api__show(p->name, p->nlen, shown));
                        b->X[3 * r + (unsigned)(p->role - ROLE_X)] = v;
                    }
                    b->pos += sz;
                } else {
                    size_t cs = type_size[p->count_type], is = type_size[p->type];
                    double cv;
                    long long count, k;
                    if (left < cs)
                        goto truncated;
                    cv = get_scalar(u + b->pos, p->count_type, swap);
                    b->pos += cs;
                    left -= cs;
                    if (cv < 0)
                        return api__fail(err, MCF_EDECODE,
                                         "ply: %s %llu: negative list length %.0f",
                                         api__show(e->name, e->nlen, shown), r, cv);
                    count = (long long)cv;
                    if ((unsigned long long)count > left / is)
                        goto truncated;
                    if (p->role == ROLE_INDICES) {
                        fan f = {0, 0};
                        if (count < 3)
                            return bad_count(b, count, r, err);
                        for (k = 0; k < count; k++) {
                            double v = get_scalar(u + b->pos + (size_t)k * is,
                                                  p->type, swap);
                            if ((rc = fan_add(b, &f, k, v, r, err)) != MCF_OK)
                                return rc;
                        }
                    }
                    b->pos += (size_t)count * is;
                }
            }
        }
        continue;
    truncated:
        return api__fail(err, MCF_EDECODE,
                         "ply: body ends inside %s %llu of %llu (byte %zu)",
                         api__show(e->name, e->nlen, shown), r, e->count, b->pos);
    }
    if (b->pos != b->len)
        return api__fail(err, MCF_EDECODE,
                         "ply: %zu bytes after the last element (byte %zu)",
                         b->len - b->pos, b->pos);
    return MCF_OK;
}

/* ASCII: one element per line; blank lines are skipped. */
static int next_line(body *b, const char **s, const char **e)
{
    while (api__line_next(&b->txt, s, e)) {
        const char *q = *s, *t;
        if (api__token(&q, *e, &t) != 0)
            return 1;
    }
    return 0;
}

static mcf_status read_ascii(body *b, const header *h, mcf_error *err)
{
    char shown[API__SHOWN], shown2[API__SHOWN];
    int ei, pi;
    mcf_status rc;

    for (ei = 0; ei < h->nel; ei++) {
        const element *e = &h->el[ei];
        unsigned long long r;
        if (e->nprops == 0) /* empty lines, which are skipped anyway */
            continue;
        for (r = 0; r < e->count; r++) {
            const char *s, *le, *t;
            size_t n;
            if (!next_line(b, &s, &le))
                return api__fail(err, MCF_EDECODE,
                                 "ply: line %ld: input ends before %s %llu of %llu",
                                 b->txt.line, api__show(e->name, e->nlen, shown), r,
                                 e->count);
            for (pi = 0; pi < e->nprops; pi++) {
                const prop *p = &e->props[pi];
                n = api__token(&s, le, &t);
                if (n == 0)
                    return api__fail(err, MCF_EDECODE,
                                     "ply: line %ld: %s %llu: value for '%s' missing",
                                     b->txt.line, api__show(e->name, e->nlen, shown), r,
                                     api__show(p->name, p->nlen, shown2));
                if (!p->is_list) {
                    double v;
                    if (api__parse_double(t, n, &v) != 0)
                        return api__fail(err, MCF_EDECODE,
                                         "ply: line %ld: bad number '%s'", b->txt.line,
                                         api__show(t, n, shown));
                    if (p->role >= ROLE_X && p->role <= ROLE_Z) {
                        if (!isfinite(v))
                            return api__fail(err, MCF_EDECODE,
                                             "ply: line %ld: coordinate '%s' is not "
                                             "finite",
                                             b->txt.line, api__show(t, n, shown));
                        b->X[3 * r + (unsigned)(p->role - ROLE_X)] = v;
                    }
                } else {
                    long long count, k;
                    fan f = {0, 0};
                    if (api__parse_int(t, n, &count) != 0 || count < 0)
                        return api__fail(err, MCF_EDECODE,
                                         "ply: line %ld: bad list length '%s'",
                                         b->txt.line, api__show(t, n, shown));
                    if (p->role == ROLE_INDICES && count < 3)
                        return bad_count(b, count, r, err);
                    for (k = 0; k < count; k++) {
                        n = api__token(&s, le, &t);
                        if (n == 0)
                            return api__fail(err, MCF_EDECODE,
                                             "ply: line %ld: %s %llu: list '%s' has "
                                             "%lld of %lld values",
                                             b->txt.line, api__show(e->name, e->nlen, shown),
                                             r, api__show(p->name, p->nlen, shown2), k,
                                             count);
                        if (p->role == ROLE_INDICES) {
                            long long v;
                            if (api__parse_int(t, n, &v) != 0)
                                return api__fail(err, MCF_EDECODE,
                                                 "ply: line %ld: bad index '%s'",
                                                 b->txt.line, api__show(t, n, shown));
                            if (v < 0 || v >= b->nv)
                                return api__fail(err, MCF_EDECODE,
                                                 "ply: line %ld: face %llu: index "
                                                 "%lld out of range (0..%d)",
                                                 b->txt.line, r, v, b->nv - 1);
                            if ((rc = fan_add(b, &f, k, (double)v, r, err)) != MCF_OK)
                                return rc;
                        } else {
                            double v;
                            if (api__parse_double(t, n, &v) != 0)
                                return api__fail(err, MCF_EDECODE,
                                                 "ply: line %ld: bad number '%s'",
                                                 b->txt.line, api__show(t, n, shown));
                        }
                    }
                }
            }
            if (api__token(&s, le, &t) != 0)
                return api__fail(err, MCF_EDECODE,
                                 "ply: line %ld: %s %llu has more values than its "
                                 "%d properties",
                                 b->txt.line, api__show(e->name, e->nlen, shown), r,
                                 e->nprops);
        }
    }
    {
        const char *s, *le;
        if (next_line(b, &s, &le))
            return api__fail(err, MCF_EDECODE,
                             "ply: line %ld: data after the last element", b->txt.line);
    }
    return MCF_OK;
}

mcf_status api_ply_decode(const void *buf, size_t len, const api_limits *lim,
                          mcf_mesh **out, mcf_error *err)
{
    api_limits def;
    header h;
    body b;
    const element *ve = NULL, *fe = NULL;
    unsigned long long need = 0;
    size_t blen;
    int i, roles[5] = {0, 0, 0, 0, 0};
    char shown[API__SHOWN];
    mcf_status rc;

    memset(&h, 0, sizeof h);
    memset(&b, 0, sizeof b);
    if ((rc = api__decode_begin("ply", buf, len, &lim, &def, err)) != MCF_OK)
        return rc;
    if ((rc = parse_header(buf, len, &h, err)) != MCF_OK)
        goto done;

    for (i = 0; i < h.nel; i++) {
        if (h.el[i].is_vertex)
            ve = &h.el[i];
        if (h.el[i].is_face)
            fe = &h.el[i];
    }
    rc = MCF_EDECODE;
    if (!ve) {
        api__fail(err, rc, "ply: no 'vertex' element");
        goto done;
    }
    for (i = 0; i < ve->nprops; i++)
        roles[ve->props[i].role]++;
    if (!roles[ROLE_X] || !roles[ROLE_Y] || !roles[ROLE_Z]) {
        api__fail(err, rc, "ply: element 'vertex' lacks property '%s'",
                  !roles[ROLE_X] ? "x" : !roles[ROLE_Y] ? "y" : "z");
        goto done;
    }
    if (!fe) {
        api__fail(err, rc, "ply: no 'face' element (a point cloud is not a mesh)");
        goto done;
    }
    for (i = 0; i < fe->nprops; i++)
        roles[fe->props[i].role]++;
    if (!roles[ROLE_INDICES]) {
        api__fail(err, rc, "ply: element 'face' has no 'vertex_indices' list");
        goto done;
    }

    /* Declared counts against the body, then against the limits. */
    blen = len - h.body;
    for (i = 0; i < h.nel; i++) {
        unsigned long long ms = min_size(&h.el[i], h.format), c = h.el[i].count;
        if (ms && c > (ULLONG_MAX - need) / ms) {
            need = ULLONG_MAX;
        } else {
            need += c * ms;
        }
        /* ASCII: the last line may lack its newline. */
        if (c && need > (unsigned long long)blen + (h.format == FMT_ASCII)) {
            api__fail(err, MCF_EDECODE,
                      "ply: header declares %llu '%s' elements, more than the "
                      "%zu-byte body can hold",
                      c, api__show(h.el[i].name, h.el[i].nlen, shown), blen);
            goto done;
        }
    }
    if (ve->count > (unsigned long long)lim->max_vertices) {
        rc = api__fail(err, MCF_ELIMIT,
                       "ply: %llu vertices exceed max_vertices (%d)", ve->count,
                       lim->max_vertices);
        goto done;
    }
    if (fe->count > (unsigned long long)lim->max_faces) {
        rc = api__fail(err, MCF_ELIMIT, "ply: %llu faces exceed max_faces (%d)",
                       fe->count, lim->max_faces);
        goto done;
    }
    if (ve->count == 0) {
        api__fail(err, rc, "ply: no vertices");
        goto done;
    }
    if (fe->count == 0) {
        api__fail(err, rc, "ply: no faces: %llu vertices only", ve->count);
        goto done;
    }

    b.buf = (const char *)buf + h.body;
    b.len = blen;
    b.format = h.format;
    b.txt.p = b.buf;
    b.txt.end = b.buf + b.len;
    b.txt.line = h.body_line - 1; /* the line before the first body line */
    b.nv = (int)ve->count;
    b.lim = lim;
    b.X = malloc(3 * sizeof *b.X * (size_t)b.nv);
    if (!b.X) {
        rc = api__fail(err, MCF_ENOMEM, "ply: no memory for %d vertices", b.nv);
        goto done;
    }
    rc = h.format == FMT_ASCII ? read_ascii(&b, &h, err) : read_binary(&b, &h, err);
    if (rc != MCF_OK)
        goto done;
    rc = api__mesh_new(b.nv, b.X, (int)b.T.n, b.T.F, out, err);
done:
    free(b.X);
    free(b.T.F);
    header_free(&h);
    return rc;
}

/* -------------------------------------------------------------- writer */

static void put_le64(unsigned char *p, uint64_t v)
{
    api__put_le32(p, (uint32_t)v);
    api__put_le32(p + 4, (uint32_t)(v >> 32));
}

static void put_double(unsigned char *p, double d)
{
    uint64_t v;
    memcpy(&v, &d, 8);
    put_le64(p, v);
}

mcf_status api_ply_encode(const mcf_mesh *m, const api_encode_opts *o,
                          api_buf *out, mcf_error *err)
{
    int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m), i;
    const double *X = mcf_mesh_positions(m);
    const int32_t *F = mcf_mesh_faces(m);
    const double *H = o ? o->ply_mean_curvature : NULL;
    const double *K = o ? o->ply_gaussian_curvature : NULL;
    int binary = o ? o->ply_binary != 0 : 1;
    size_t len0 = out->len;
    mcf_status rc;

    rc = api_buf_printf(out,
                        "ply\nformat %s 1.0\ncomment mcfd\nelement vertex %d\n"
                        "property double x\nproperty double y\nproperty double z\n",
                        binary ? "binary_little_endian" : "ascii", nv);
    if (rc == MCF_OK && H)
        rc = api_buf_printf(out, "property float mean_curvature\n");
    if (rc == MCF_OK && K)
        rc = api_buf_printf(out, "property float gaussian_curvature\n");
    if (rc == MCF_OK)
        rc = api_buf_printf(out, "element face %d\nproperty list uchar int "
                                 "vertex_indices\nend_header\n",
                            nf);
    for (i = 0; i < nv && rc == MCF_OK; i++) {
        if (binary) {
            unsigned char v[32];
            size_t n = 24;
            put_double(v, X[3 * i]);
            put_double(v + 8, X[3 * i + 1]);
            put_double(v + 16, X[3 * i + 2]);
            if (H) {
                api__put_f32(v + n, (float)H[i]);
                n += 4;
            }
            if (K) {
                api__put_f32(v + n, (float)K[i]);
                n += 4;
            }
            rc = api_buf_append(out, v, n);
        } else {
            rc = api_buf_printf(out, "%.17g %.17g %.17g", X[3 * i], X[3 * i + 1],
                                X[3 * i + 2]);
            if (rc == MCF_OK && H)
                rc = api_buf_printf(out, " %.9g", (double)(float)H[i]);
            if (rc == MCF_OK && K)
                rc = api_buf_printf(out, " %.9g", (double)(float)K[i]);
            if (rc == MCF_OK)
                rc = api_buf_append(out, "\n", 1);
        }
    }
    for (i = 0; i < nf && rc == MCF_OK; i++) {
        if (binary) {
            unsigned char f[13];
            f[0] = 3;
            api__put_le32(f + 1, (uint32_t)F[3 * i]);
            api__put_le32(f + 5, (uint32_t)F[3 * i + 1]);
            api__put_le32(f + 9, (uint32_t)F[3 * i + 2]);
            rc = api_buf_append(out, f, sizeof f);
        } else {
            rc = api_buf_printf(out, "3 %ld %ld %ld\n", (long)F[3 * i],
                                (long)F[3 * i + 1], (long)F[3 * i + 2]);
        }
    }
    return api__encode_end(out, len0, rc, "ply", nv, "vertices", err);
}
