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
 * Attributes (api_ply_decode_attrs): vertex nx ny nz, s t (or u v,
 * texture_u texture_v), red green blue [alpha] (integer types scaled to
 * [0, 1]) and the face `texcoord` list draco_decoder writes; one with a
 * missing component or a non-finite value is dropped, never an error;
 * and each face's corner count, so polygons can be written back.
 *
 * Writer: ascii or binary_little_endian (independent of the host's byte
 * order), x y z as float when the attributes say the input was single
 * precision, else double; with attributes, nx ny nz recomputed from the
 * surface (per vertex), texcoords as vertex s t (or, at UV seams, the face
 * `texcoord` list), uchar red green blue [alpha]; optional float
 * `mean_curvature` and `gaussian_curvature` vertex properties (given, or
 * computed with ply_curvature); `property list uchar int vertex_indices`
 * triangles, or the input's polygons when the attributes hold them (of at
 * most 127 corners, so a face texcoord list's count fits its uchar). ASCII uses %.17g for doubles, %.9g for floats (exact round
 * trips).
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

enum {
    ROLE_NONE = 0, ROLE_X, ROLE_Y, ROLE_Z, ROLE_INDICES,
    /* vertex attributes (read only for api_ply_decode_attrs) */
    ROLE_NX, ROLE_NY, ROLE_NZ, ROLE_S, ROLE_T, ROLE_R, ROLE_G, ROLE_B, ROLE_A,
    ROLE_FTC,       /* the face's `texcoord` list (u v per corner) */
    ROLE_COUNT
};
#define NVROLES (ROLE_A - ROLE_NX + 1)

/* Vertex property names of the attribute roles, ROLE_NX on. */
static const char *const vrole_names[NVROLES][3] = {
    {"nx", NULL, NULL}, {"ny", NULL, NULL}, {"nz", NULL, NULL},
    {"s", "u", "texture_u"}, {"t", "v", "texture_v"},
    {"red", "r", NULL}, {"green", "g", NULL}, {"blue", "b", NULL},
    {"alpha", "a", NULL},
};
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
                for (i = 0; pr.role == ROLE_NONE && i < NVROLES; i++) {
                    int j;
                    for (j = 0; j < 3 && vrole_names[i][j]; j++)
                        if (api__tok_is(name, nn, vrole_names[i][j]))
                            pr.role = ROLE_NX + i;
                }
                /* A second name of a role taken (u after s) stays unread. */
                for (i = 0; pr.role >= ROLE_NX && i < e->nprops; i++)
                    if (e->props[i].role == pr.role)
                        pr.role = ROLE_NONE;
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
    /* Attributes, when wanted: per-vertex arrays by role (NULL: absent),
     * the face texcoords as 6 doubles per triangle (ftc, growing with T),
     * the current face's list (tmp) and its vertex count. */
    int want;
    double *va[NVROLES];
    double vscale[NVROLES];        /* 1 / type maximum for integer colours */
    double *ftc;
    long long ftc_cap;
    int ftc_bad;                   /* some face lacks a usable list */
    double *tmp;
    long long tmp_n, tmp_cap, poly_n, tri0;
    int32_t *psize;                /* each face row's corner count */
    long long np, np_cap;
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

/* An attribute value v of vertex r for property p (attributes wanted). */
static void put_vattr(body *b, const prop *p, unsigned long long r, double v)
{
    int k = p->role - ROLE_NX;
    if (b->va[k])
        b->va[k][r] = v * b->vscale[k];
}

/* Value k of the face's texcoord list (kept in tmp until the row ends). */
static mcf_status put_ftc(body *b, long long k, double v, mcf_error *err)
{
    if (k == 0)
        b->tmp_n = 0;
    if (b->tmp_n == b->tmp_cap) {
        long long nc = b->tmp_cap ? 2 * b->tmp_cap : 64;
        double *q = realloc(b->tmp, sizeof *q * (size_t)nc);
        if (!q)
            return api__fail(err, MCF_ENOMEM, "ply: out of memory for texcoords");
        b->tmp = q;
        b->tmp_cap = nc;
    }
    b->tmp[b->tmp_n++] = v;
    return MCF_OK;
}

/* The end of face row r: hands its texcoord list (2 values per polygon
 * corner) to the triangles the fan made of it, corner by corner. */
static mcf_status end_face(body *b, mcf_error *err)
{
    long long t, ntri = b->T.n - b->tri0;
    if (!b->want)
        return MCF_OK;
    if (b->np == b->np_cap) {
        long long nc = b->np_cap ? 2 * b->np_cap : 1024;
        int32_t *q = realloc(b->psize, sizeof *q * (size_t)nc);
        if (!q)
            return api__fail(err, MCF_ENOMEM, "ply: out of memory for the faces");
        b->psize = q;
        b->np_cap = nc;
    }
    b->psize[b->np++] = (int32_t)b->poly_n;
    if (b->ftc_bad)
        return MCF_OK;
    /* A list of another length drops the attribute; non-finite values
     * are caught once all are in (make_attrs). */
    if (b->tmp_n != 2 * b->poly_n) {
        b->ftc_bad = 1;
        return MCF_OK;
    }
    if (b->T.n > b->ftc_cap) {
        long long nc = b->T.cap;
        double *q = realloc(b->ftc, 6 * sizeof *q * (size_t)nc);
        if (!q)
            return api__fail(err, MCF_ENOMEM, "ply: out of memory for texcoords");
        b->ftc = q;
        b->ftc_cap = nc;
    }
    for (t = 0; t < ntri; t++) {
        double *o = b->ftc + 6 * (b->tri0 + t);
        /* The fan's triangle t: polygon corners 0, t + 1, t + 2. */
        o[0] = b->tmp[0];
        o[1] = b->tmp[1];
        o[2] = b->tmp[2 * (t + 1)];
        o[3] = b->tmp[2 * (t + 1) + 1];
        o[4] = b->tmp[2 * (t + 2)];
        o[5] = b->tmp[2 * (t + 2) + 1];
    }
    return MCF_OK;
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
            b->tri0 = b->T.n;
            b->tmp_n = b->poly_n = 0;
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
                    } else if (p->role >= ROLE_NX && p->role <= ROLE_A && b->want) {
                        put_vattr(b, p, r, get_scalar(u + b->pos, p->type, swap));
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
                        b->poly_n = count;
                        for (k = 0; k < count; k++) {
                            double v = get_scalar(u + b->pos + (size_t)k * is,
                                                  p->type, swap);
                            if ((rc = fan_add(b, &f, k, v, r, err)) != MCF_OK)
                                return rc;
                        }
                    } else if (p->role == ROLE_FTC && b->want) {
                        b->tmp_n = 0;
                        for (k = 0; k < count; k++)
                            if ((rc = put_ftc(b, k,
                                              get_scalar(u + b->pos + (size_t)k * is,
                                                         p->type, swap),
                                              err)) != MCF_OK)
                                return rc;
                    }
                    b->pos += (size_t)count * is;
                }
            }
            if (e->is_face && (rc = end_face(b, err)) != MCF_OK)
                return rc;
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
            b->tri0 = b->T.n;
            b->tmp_n = b->poly_n = 0;
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
                    } else if (p->role >= ROLE_NX && p->role <= ROLE_A && b->want) {
                        put_vattr(b, p, r, v);
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
                    if (p->role == ROLE_INDICES)
                        b->poly_n = count;
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
                            if (p->role == ROLE_FTC && b->want
                                && (rc = put_ftc(b, k, v, err)) != MCF_OK)
                                return rc;
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
            if (e->is_face && (rc = end_face(b, err)) != MCF_OK)
                return rc;
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
    return api_ply_decode_attrs(buf, len, lim, out, NULL, err);
}

/* All n values finite? */
static int all_finite(const double *v, size_t n)
{
    size_t i;
    for (i = 0; i < n; i++)
        if (!isfinite(v[i]))
            return 0;
    return 1;
}

/* The attributes read into b, for mesh m, as a new handle in *attrs.
 * Vertex attributes need all their components (nx ny nz, s t, red green
 * blue); one with a non-finite value is dropped, as is a face texcoord
 * list some face lacks. float32: x, y and z were all `float`. */
static mcf_status make_attrs(body *b, const mcf_mesh *m, int float32,
                             api_attrs **attrs, mcf_error *err)
{
    int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m), k, c;
    size_t nc = 3 * (size_t)nf;
    api_attrs *a = api_attrs_new(nv, nf);
    mcf_status rc = MCF_OK;
    static const struct {
        api_attr_kind kind;
        int first, ncomp;
    } groups[] = {{API_ATTR_NORMAL, ROLE_NX, 3},
                  {API_ATTR_TEXCOORD, ROLE_S, 2},
                  {API_ATTR_COLOR, ROLE_R, 3}};

    if (!a)
        return api__fail(err, MCF_ENOMEM, "ply: out of memory for the attributes");
    a->float32 = float32;
    for (k = 0; k < 3 && rc == MCF_OK; k++) {
        int first = groups[k].first - ROLE_NX, ncomp = groups[k].ncomp, i;
        double *v;
        int32_t *cr;
        if (groups[k].kind == API_ATTR_COLOR && b->va[ROLE_A - ROLE_NX])
            ncomp = 4;
        for (c = 0; c < ncomp; c++)
            if (!b->va[first + c])
                break;
        if (c < ncomp)
            continue;
        v = malloc(sizeof *v * (size_t)ncomp * (size_t)nv + 1);
        cr = malloc(sizeof *cr * nc + 1);
        if (!v || !cr) {
            free(v);
            free(cr);
            rc = api__fail(err, MCF_ENOMEM, "ply: out of memory for the attributes");
            break;
        }
        for (i = 0; i < nv; i++)
            for (c = 0; c < ncomp; c++)
                v[(size_t)i * ncomp + c] = b->va[first + c][i];
        if (!all_finite(v, (size_t)ncomp * (size_t)nv)) {
            free(v);
            free(cr);
            continue;
        }
        memcpy(cr, mcf_mesh_faces(m), sizeof *cr * nc);
        rc = api__attrs_take(a, groups[k].kind, ncomp, nv, v, cr, err);
    }
    if (rc == MCF_OK && !a->a[API_ATTR_TEXCOORD].corners && b->ftc && !b->ftc_bad
        && b->T.n == nf && all_finite(b->ftc, 6 * (size_t)nf)) {
        /* One value per corner, then equal values shared. */
        int32_t *cr = malloc(sizeof *cr * nc + 1);
        if (!cr) {
            rc = api__fail(err, MCF_ENOMEM, "ply: out of memory for texcoords");
        } else {
            size_t i;
            for (i = 0; i < nc; i++)
                cr[i] = (int32_t)i;
            rc = api__attrs_take(a, API_ATTR_TEXCOORD, 2, (int)nc, b->ftc, cr, err);
            b->ftc = NULL;
            if (rc == MCF_OK)
                rc = api__attr_dedupe(&a->a[API_ATTR_TEXCOORD], nc, err);
        }
    }
    if (rc == MCF_OK)
        rc = api__attrs_polys(a, b->psize, (int)b->np, err);
    if (rc != MCF_OK) {
        api_attrs_free(a);
        return rc;
    }
    *attrs = a;
    return MCF_OK;
}

mcf_status api_ply_decode_attrs(const void *buf, size_t len,
                                const api_limits *lim, mcf_mesh **out,
                                api_attrs **attrs, mcf_error *err)
{
    api_limits def;
    header h;
    body b;
    const element *ve = NULL, *fe = NULL;
    unsigned long long need = 0;
    size_t blen;
    int i, roles[ROLE_COUNT] = {0}, float32 = 1;
    char shown[API__SHOWN];
    mcf_mesh *m = NULL;
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
    if (attrs) {
        b.want = 1;
        for (i = 0; i < ve->nprops; i++) {
            const prop *p = &ve->props[i];
            if (p->role >= ROLE_X && p->role <= ROLE_Z && p->type != T_F32)
                float32 = 0;
            if (p->role >= ROLE_NX && p->role <= ROLE_A) {
                int k = p->role - ROLE_NX;
                /* Integer colours (uchar, ushort) scale to [0, 1]. */
                b.vscale[k] = 1.0;
                if (p->role >= ROLE_R && is_int_type(p->type))
                    b.vscale[k] = 1.0 / (p->type == T_U8 ? 255.0
                                         : p->type == T_U16 ? 65535.0
                                         : p->type == T_I8 ? 127.0
                                         : p->type == T_I16 ? 32767.0
                                                            : 4294967295.0);
                b.va[k] = malloc(sizeof *b.va[k] * (size_t)b.nv);
                if (!b.va[k]) {
                    rc = api__fail(err, MCF_ENOMEM,
                                   "ply: no memory for the attributes of %d vertices",
                                   b.nv);
                    goto done;
                }
            }
        }
    }
    rc = h.format == FMT_ASCII ? read_ascii(&b, &h, err) : read_binary(&b, &h, err);
    if (rc != MCF_OK)
        goto done;
    if ((rc = api__mesh_new(b.nv, b.X, (int)b.T.n, b.T.F, &m, err)) != MCF_OK)
        goto done;
    if (attrs && (rc = make_attrs(&b, m, float32, attrs, err)) != MCF_OK) {
        mcf_mesh_free(m);
        goto done;
    }
    *out = m;
done:
    free(b.X);
    free(b.T.F);
    for (i = 0; i < NVROLES; i++)
        free(b.va[i]);
    free(b.ftc);
    free(b.tmp);
    free(b.psize);
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

/* What a PLY output carries besides x y z and the faces. */
typedef struct {
    int f32;                /* positions (and attributes) as float */
    double *N;              /* 3*nv normals, or NULL */
    double *T;              /* 2*nv vertex texcoords, or NULL */
    const api__attr *ftc;   /* else texcoords per corner, or NULL */
    double *C;              /* ccomp*nv colours in [0, 1], or NULL */
    int ccomp;
    const double *H, *K;    /* curvatures, or NULL */
    double *Hown, *Kown;    /* computed here (ply_curvature) */
} plyextra;

static void extra_free(plyextra *x)
{
    free(x->N);
    free(x->T);
    free(x->C);
    free(x->Hown);
    free(x->Kown);
}

static mcf_status extra_init(plyextra *x, const mcf_mesh *m,
                             const api_encode_opts *o, mcf_error *err)
{
    const api_attrs *a = o ? o->attrs : NULL;
    size_t nv = (size_t)mcf_mesh_nvertices(m);
    mcf_status rc;

    memset(x, 0, sizeof *x);
    if ((rc = api__attrs_check(a, m, "ply", err)) != MCF_OK)
        return rc;
    x->H = o ? o->ply_mean_curvature : NULL;
    x->K = o ? o->ply_gaussian_curvature : NULL;
    if (o && o->ply_curvature && !x->H && !x->K) {
        x->Hown = malloc(sizeof *x->Hown * (nv + 1));
        x->Kown = malloc(sizeof *x->Kown * (nv + 1));
        if (!x->Hown || !x->Kown) {
            extra_free(x);
            return api__fail(err, MCF_ENOMEM, "ply: out of memory for curvatures");
        }
        if ((rc = mcf_curvature(m, NULL, x->Hown, x->Kown, NULL, err)) != MCF_OK) {
            extra_free(x);
            return rc;
        }
        x->H = x->Hown;
        x->K = x->Kown;
    }
    if (!a)
        return MCF_OK;
    x->f32 = a->float32;
    if (a->a[API_ATTR_NORMAL].corners) {
        /* PLY normals are per vertex: creases cannot be kept here. */
        x->N = malloc(3 * sizeof *x->N * (nv + 1));
        if (!x->N)
            goto nomem;
        api__vertex_normals(m, x->N);
    }
    if (a->a[API_ATTR_TEXCOORD].corners) {
        x->T = malloc(2 * sizeof *x->T * (nv + 1));
        if (!x->T)
            goto nomem;
        if (!api__attr_per_vertex(&a->a[API_ATTR_TEXCOORD], m, x->T)) {
            free(x->T); /* seams: the face `texcoord` list, as Draco writes */
            x->T = NULL;
            x->ftc = &a->a[API_ATTR_TEXCOORD];
        }
    }
    if (a->a[API_ATTR_COLOR].corners) {
        x->ccomp = a->a[API_ATTR_COLOR].ncomp;
        x->C = malloc(sizeof *x->C * (size_t)x->ccomp * (nv + 1));
        if (!x->C)
            goto nomem;
        if (!api__attr_per_vertex(&a->a[API_ATTR_COLOR], m, x->C)) {
            free(x->C); /* colours differ at a vertex: not in PLY */
            x->C = NULL;
        }
    }
    return MCF_OK;
nomem:
    extra_free(x);
    return api__fail(err, MCF_ENOMEM, "ply: out of memory for the attributes");
}

/* A colour component in [0, 1] as a byte (exact for 8-bit sources). */
static unsigned char color_byte(double c)
{
    double v = floor(c * 255.0 + 0.5);
    return (unsigned char)(v < 0 ? 0 : v > 255 ? 255 : v);
}

/* Appends value v as a float or a double (binary or ASCII). */
static void put_real(unsigned char *p, size_t *n, double v, int f32)
{
    if (f32) {
        api__put_f32(p + *n, (float)v);
        *n += 4;
    } else {
        put_double(p + *n, v);
        *n += 8;
    }
}

/* ASCII: " v" with %.9g for a float (exact for floats), %.17g for a
 * double. */
static mcf_status print_real(api_buf *out, double v, int f32)
{
    return f32 ? api_buf_printf(out, " %.9g", (double)(float)v)
               : api_buf_printf(out, " %.17g", v);
}

mcf_status api_ply_encode(const mcf_mesh *m, const api_encode_opts *o,
                          api_buf *out, mcf_error *err)
{
    int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m), i, k;
    const double *X = mcf_mesh_positions(m);
    const int32_t *F = mcf_mesh_faces(m);
    int binary = o ? o->ply_binary != 0 : 1, pn;
    size_t len0 = out->len, *cs;
    unsigned char *fb;
    const api_attrs *pa;
    api__poly_it it = {0, 0};
    plyextra x;
    const char *real;
    mcf_status rc;

    if ((rc = extra_init(&x, m, o, err)) != MCF_OK)
        return rc;
    /* The input's polygons, when their counts fit the uchar list count
     * (and a texcoord list of 2 per corner fits too); else triangles. */
    pa = o && o->attrs && api__attrs_maxpoly(o->attrs) <= 127 ? o->attrs : NULL;
    cs = malloc(sizeof *cs * (size_t)api__attrs_maxpoly(pa));
    fb = malloc((size_t)api__attrs_maxpoly(pa) * (4 + 2 * 8) + 2);
    if (!cs || !fb) {
        free(cs);
        free(fb);
        extra_free(&x);
        return api__fail(err, MCF_ENOMEM, "ply: out of memory");
    }
    real = x.f32 ? "float" : "double";
    rc = api_buf_printf(out,
                        "ply\nformat %s 1.0\ncomment mcfd\nelement vertex %d\n"
                        "property %s x\nproperty %s y\nproperty %s z\n",
                        binary ? "binary_little_endian" : "ascii", nv, real, real,
                        real);
    if (rc == MCF_OK && x.N)
        rc = api_buf_printf(out, "property %s nx\nproperty %s ny\nproperty %s nz\n",
                            real, real, real);
    if (rc == MCF_OK && x.T)
        rc = api_buf_printf(out, "property %s s\nproperty %s t\n", real, real);
    if (rc == MCF_OK && x.C)
        rc = api_buf_printf(out, "property uchar red\nproperty uchar green\n"
                                 "property uchar blue\n%s",
                            x.ccomp == 4 ? "property uchar alpha\n" : "");
    if (rc == MCF_OK && x.H)
        rc = api_buf_printf(out, "property float mean_curvature\n");
    if (rc == MCF_OK && x.K)
        rc = api_buf_printf(out, "property float gaussian_curvature\n");
    if (rc == MCF_OK)
        rc = api_buf_printf(out, "element face %d\nproperty list uchar int "
                                 "vertex_indices\n%s",
                            pa && pa->poly ? pa->npoly : nf, x.ftc ? "" : "end_header\n");
    if (rc == MCF_OK && x.ftc)
        rc = api_buf_printf(out, "property list uchar %s texcoord\nend_header\n",
                            real);
    for (i = 0; i < nv && rc == MCF_OK; i++) {
        if (binary) {
            unsigned char v[128];
            size_t n = 0;
            for (k = 0; k < 3; k++)
                put_real(v, &n, X[3 * i + k], x.f32);
            for (k = 0; x.N && k < 3; k++)
                put_real(v, &n, x.N[3 * i + k], x.f32);
            for (k = 0; x.T && k < 2; k++)
                put_real(v, &n, x.T[2 * i + k], x.f32);
            for (k = 0; x.C && k < x.ccomp; k++)
                v[n++] = color_byte(x.C[x.ccomp * i + k]);
            if (x.H) {
                api__put_f32(v + n, (float)x.H[i]);
                n += 4;
            }
            if (x.K) {
                api__put_f32(v + n, (float)x.K[i]);
                n += 4;
            }
            rc = api_buf_append(out, v, n);
        } else {
            rc = api_buf_printf(out, x.f32 ? "%.9g %.9g %.9g" : "%.17g %.17g %.17g",
                                x.f32 ? (double)(float)X[3 * i] : X[3 * i],
                                x.f32 ? (double)(float)X[3 * i + 1] : X[3 * i + 1],
                                x.f32 ? (double)(float)X[3 * i + 2] : X[3 * i + 2]);
            for (k = 0; x.N && k < 3 && rc == MCF_OK; k++)
                rc = print_real(out, x.N[3 * i + k], x.f32);
            for (k = 0; x.T && k < 2 && rc == MCF_OK; k++)
                rc = print_real(out, x.T[2 * i + k], x.f32);
            for (k = 0; x.C && k < x.ccomp && rc == MCF_OK; k++)
                rc = api_buf_printf(out, " %u", (unsigned)color_byte(x.C[x.ccomp * i + k]));
            if (rc == MCF_OK && x.H)
                rc = api_buf_printf(out, " %.9g", (double)(float)x.H[i]);
            if (rc == MCF_OK && x.K)
                rc = api_buf_printf(out, " %.9g", (double)(float)x.K[i]);
            if (rc == MCF_OK)
                rc = api_buf_append(out, "\n", 1);
        }
    }
    while (rc == MCF_OK && api__poly_next(pa, nf, &it, cs, &pn)) {
        if (binary) {
            size_t b = 1;
            fb[0] = (unsigned char)pn;
            for (k = 0; k < pn; k++, b += 4)
                api__put_le32(fb + b, (uint32_t)F[cs[k]]);
            if (x.ftc) {
                fb[b++] = (unsigned char)(2 * pn);
                for (k = 0; k < 2 * pn; k++)
                    put_real(fb, &b,
                             x.ftc->values[2 * (size_t)x.ftc->corners[cs[k / 2]] + (size_t)(k % 2)],
                             x.f32);
            }
            rc = api_buf_append(out, fb, b);
        } else {
            rc = api_buf_printf(out, "%d", pn);
            for (k = 0; k < pn && rc == MCF_OK; k++)
                rc = api_buf_printf(out, " %ld", (long)F[cs[k]]);
            if (rc == MCF_OK && x.ftc) {
                rc = api_buf_printf(out, " %d", 2 * pn);
                for (k = 0; k < 2 * pn && rc == MCF_OK; k++) {
                    double t = x.ftc->values[2 * (size_t)x.ftc->corners[cs[k / 2]]
                                             + (size_t)(k % 2)];
                    rc = print_real(out, t, x.f32);
                }
            }
            if (rc == MCF_OK)
                rc = api_buf_append(out, "\n", 1);
        }
    }
    free(cs);
    free(fb);
    extra_free(&x);
    return api__encode_end(out, len0, rc, "ply", nv, "vertices", err);
}
