/* SPDX-License-Identifier: MIT */
/*
 * api_ply.c - Stanford PLY reader on memory buffers (the header:
 * api_ply_header.c; the writer: api_ply_write.c).
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
 * every other vertex scalar (quality, confidence, ...) as it came, to be
 * written back (the first API__SCALARS_MAX; what is not read is named:
 * api_attrs_not_kept); and each face's corner count, so polygons can be
 * written back.
 */
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "api_ply_internal.h"

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
    double *xa[API__SCALARS_MAX];  /* the ROLE_EXTRA properties, by rank */
    double *ftc;
    long long ftc_cap;
    int ftc_bad;                   /* some face lacks a usable list */
    double *tmp;
    long long tmp_n, tmp_cap, poly_n, tri0;
    int32_t *psize;                /* each face row's corner count */
    long long np, np_cap;
    long long fan_max;             /* triangles the declared counts allow */
} body;

/* The value of type t stored at b; swap: the file's byte order differs
 * from the host's. */
static double get_scalar(const unsigned char *b, ptype t, int swap)
{
    unsigned char u[8];
    size_t n = api__ply_type_size[t], i;
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

/* A polygon of count corners fans into count - 2 triangles: refused
 * before it is built when the triangles would pass b->fan_max (set in
 * api_ply_decode_attrs). */
static mcf_status fan_budget(const body *b, long long count, unsigned long long idx,
                             mcf_error *err)
{
    if (count - 2 <= b->fan_max - b->T.n)
        return MCF_OK;
    return api__fail(err, MCF_ELIMIT,
                     "ply: face %llu has %lld corners: the polygons would fan into "
                     "more than %lld triangles, more than %d vertices and the faces "
                     "declared make (a closed surface of V vertices has about 2V)",
                     idx, count, b->fan_max, b->nv);
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
    if (p->role == ROLE_EXTRA) {
        if (p->extra < API__SCALARS_MAX && b->xa[p->extra])
            b->xa[p->extra][r] = v;
    } else if (b->va[p->role - ROLE_NX]) {
        b->va[p->role - ROLE_NX][r] = v * b->vscale[p->role - ROLE_NX];
    }
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
                    size_t sz = api__ply_type_size[p->type];
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
                    } else if (((p->role >= ROLE_NX && p->role <= ROLE_A) || p->role == ROLE_EXTRA) && b->want) {
                        put_vattr(b, p, r, get_scalar(u + b->pos, p->type, swap));
                    }
                    b->pos += sz;
                } else {
                    size_t cs = api__ply_type_size[p->count_type], is = api__ply_type_size[p->type];
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
                        if ((rc = fan_budget(b, count, r, err)) != MCF_OK)
                            return rc;
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

/* Scalar property p of row r: the number t (n bytes). */
static mcf_status ascii_scalar(body *b, const prop *p, unsigned long long r, const char *t,
                               size_t n, mcf_error *err)
{
    char shown[API__SHOWN];
    double v;

    if (api__parse_double(t, n, &v) != 0)
        return api__fail(err, MCF_EDECODE, "ply: line %ld: bad number '%s'", b->txt.line,
                         api__show(t, n, shown));
    if (p->role >= ROLE_X && p->role <= ROLE_Z) {
        if (!isfinite(v))
            return api__fail(err, MCF_EDECODE,
                             "ply: line %ld: coordinate '%s' is not "
                             "finite",
                             b->txt.line, api__show(t, n, shown));
        b->X[3 * r + (unsigned)(p->role - ROLE_X)] = v;
    } else if (((p->role >= ROLE_NX && p->role <= ROLE_A) || p->role == ROLE_EXTRA) && b->want) {
        put_vattr(b, p, r, v);
    }
    return MCF_OK;
}

/* Value k of list property p (row r): t (n bytes), a face's vertex index
 * (checked against the vertices, then into the fan f) or a number. */
static mcf_status ascii_list_value(body *b, const prop *p, unsigned long long r, fan *f,
                                   long long k, const char *t, size_t n, mcf_error *err)
{
    char shown[API__SHOWN];

    if (p->role == ROLE_INDICES) {
        long long v;
        if (api__parse_int(t, n, &v) != 0)
            return api__fail(err, MCF_EDECODE, "ply: line %ld: bad index '%s'", b->txt.line,
                             api__show(t, n, shown));
        if (v < 0 || v >= b->nv)
            return api__fail(err, MCF_EDECODE,
                             "ply: line %ld: face %llu: index "
                             "%lld out of range (0..%d)",
                             b->txt.line, r, v, b->nv - 1);
        return fan_add(b, f, k, (double)v, r, err);
    } else {
        double v;
        if (api__parse_double(t, n, &v) != 0)
            return api__fail(err, MCF_EDECODE, "ply: line %ld: bad number '%s'", b->txt.line,
                             api__show(t, n, shown));
        if (p->role == ROLE_FTC && b->want)
            return put_ftc(b, k, v, err);
    }
    return MCF_OK;
}

/* List property p of row r of e: its length t (n bytes), then as many
 * values from *s on (up to le). */
static mcf_status ascii_list(body *b, const element *e, const prop *p, unsigned long long r,
                             const char **s, const char *le, const char *t, size_t n,
                             mcf_error *err)
{
    char shown[API__SHOWN], shown2[API__SHOWN];
    long long count, k;
    fan f = {0, 0};
    mcf_status rc;

    if (api__parse_int(t, n, &count) != 0 || count < 0)
        return api__fail(err, MCF_EDECODE, "ply: line %ld: bad list length '%s'", b->txt.line,
                         api__show(t, n, shown));
    if (p->role == ROLE_INDICES && count < 3)
        return bad_count(b, count, r, err);
    if (p->role == ROLE_INDICES && (rc = fan_budget(b, count, r, err)) != MCF_OK)
        return rc;
    if (p->role == ROLE_INDICES)
        b->poly_n = count;
    for (k = 0; k < count; k++) {
        n = api__token(s, le, &t);
        if (n == 0)
            return api__fail(err, MCF_EDECODE,
                             "ply: line %ld: %s %llu: list '%s' has "
                             "%lld of %lld values",
                             b->txt.line, api__show(e->name, e->nlen, shown), r,
                             api__show(p->name, p->nlen, shown2), k, count);
        if ((rc = ascii_list_value(b, p, r, &f, k, t, n, err)) != MCF_OK)
            return rc;
    }
    return MCF_OK;
}

/* Row r of element e: one line, a value (or a list) per property and
 * nothing after them; a face's texcoords then go to its triangles. */
static mcf_status ascii_row(body *b, const element *e, unsigned long long r, mcf_error *err)
{
    char shown[API__SHOWN], shown2[API__SHOWN];
    const char *s, *le, *t;
    size_t n;
    int pi;
    mcf_status rc;

    b->tri0 = b->T.n;
    b->tmp_n = b->poly_n = 0;
    if (!next_line(b, &s, &le))
        return api__fail(err, MCF_EDECODE, "ply: line %ld: input ends before %s %llu of %llu",
                         b->txt.line, api__show(e->name, e->nlen, shown), r, e->count);
    for (pi = 0; pi < e->nprops; pi++) {
        const prop *p = &e->props[pi];
        n = api__token(&s, le, &t);
        if (n == 0)
            return api__fail(err, MCF_EDECODE, "ply: line %ld: %s %llu: value for '%s' missing",
                             b->txt.line, api__show(e->name, e->nlen, shown), r,
                             api__show(p->name, p->nlen, shown2));
        rc = p->is_list ? ascii_list(b, e, p, r, &s, le, t, n, err)
                        : ascii_scalar(b, p, r, t, n, err);
        if (rc != MCF_OK)
            return rc;
    }
    if (api__token(&s, le, &t) != 0)
        return api__fail(err, MCF_EDECODE,
                         "ply: line %ld: %s %llu has more values than its "
                         "%d properties",
                         b->txt.line, api__show(e->name, e->nlen, shown), r, e->nprops);
    return e->is_face ? end_face(b, err) : MCF_OK;
}

/* ASCII: the elements' rows in the header's order, then only blank lines. */
static mcf_status read_ascii(body *b, const header *h, mcf_error *err)
{
    const char *s, *le;
    mcf_status rc;

    for (int ei = 0; ei < h->nel; ei++) {
        const element *e = &h->el[ei];
        if (e->nprops == 0) /* empty lines, which are skipped anyway */
            continue;
        for (unsigned long long r = 0; r < e->count; r++)
            if ((rc = ascii_row(b, e, r, err)) != MCF_OK)
                return rc;
    }
    if (next_line(b, &s, &le))
        return api__fail(err, MCF_EDECODE, "ply: line %ld: data after the last element",
                         b->txt.line);
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

/* What of h no output keeps, named in a: the vertex and face
 * properties not read (lists of the vertex, scalars of the face, vertex
 * scalars past API__SCALARS_MAX) and the other elements. */
static mcf_status name_not_kept(api_attrs *a, const header *h, mcf_error *err)
{
    char what[96], shown[API__SHOWN], shown2[API__SHOWN];
    mcf_status rc = MCF_OK;
    int i, j;
    for (i = 0; i < h->nel && rc == MCF_OK; i++) {
        const element *e = &h->el[i];
        if (!e->is_vertex && !e->is_face) {
            snprintf(what, sizeof what, "element %s", api__show(e->name, e->nlen, shown));
            rc = api__attrs_drop(a, what, strlen(what), err);
            continue;
        }
        for (j = 0; j < e->nprops && rc == MCF_OK; j++) {
            const prop *p = &e->props[j];
            if (p->role == ROLE_INDICES || p->role == ROLE_FTC
                || (p->role >= ROLE_X && p->role <= ROLE_A)
                || (p->role == ROLE_EXTRA && p->extra < API__SCALARS_MAX))
                continue;
            snprintf(what, sizeof what, "%s %s%s", api__show(e->name, e->nlen, shown),
                     api__show(p->name, p->nlen, shown2), p->is_list ? " (a list)" : "");
            rc = api__attrs_drop(a, what, strlen(what), err);
        }
    }
    return rc;
}

/* The attributes read into b, for mesh m, as a new handle in *attrs.
 * Vertex attributes need all their components (nx ny nz, s t, red green
 * blue); one with a non-finite value is dropped, as is a face texcoord
 * list some face lacks; the other vertex scalars pass through as they
 * came. float32: x, y and z were all `float`. */
static mcf_status make_attrs(body *b, const header *h, const element *ve,
                             const mcf_mesh *m, int float32, api_attrs **attrs,
                             mcf_error *err)
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
    for (k = 0; k < ve->nprops && rc == MCF_OK; k++) {
        const prop *p = &ve->props[k];
        if (p->role == ROLE_EXTRA && p->extra < API__SCALARS_MAX) {
            rc = api__attrs_scalar(a, p->name, p->nlen, (int)p->type, b->xa[p->extra], err);
            b->xa[p->extra] = NULL;
        }
    }
    if (rc == MCF_OK)
        rc = name_not_kept(a, h, err);
    if (rc == MCF_OK)
        rc = api__attrs_polys(a, b->psize, (int)b->np, err);
    if (rc != MCF_OK) {
        api_attrs_free(a);
        return rc;
    }
    *attrs = a;
    return MCF_OK;
}

/* The vertex and face elements of h (*ve, *fe), with the properties the
 * mesh needs, and every declared count checked against the body (its
 * elements' smallest sizes) and then against the limits. */
static mcf_status check_elements(const header *h, size_t len, const api_limits *lim,
                                 const element **ve_out, mcf_error *err)
{
    const element *ve = NULL, *fe = NULL;
    unsigned long long need = 0;
    size_t blen;
    int i, roles[ROLE_COUNT] = {0};
    char shown[API__SHOWN];

    for (i = 0; i < h->nel; i++) {
        if (h->el[i].is_vertex)
            ve = &h->el[i];
        if (h->el[i].is_face)
            fe = &h->el[i];
    }
    if (!ve)
        return api__fail(err, MCF_EDECODE, "ply: no 'vertex' element");
    for (i = 0; i < ve->nprops; i++)
        roles[ve->props[i].role]++;
    if (!roles[ROLE_X] || !roles[ROLE_Y] || !roles[ROLE_Z])
        return api__fail(err, MCF_EDECODE, "ply: element 'vertex' lacks property '%s'",
                         !roles[ROLE_X] ? "x" : !roles[ROLE_Y] ? "y" : "z");
    if (!fe)
        return api__fail(err, MCF_EDECODE,
                         "ply: no 'face' element (a point cloud is not a mesh)");
    for (i = 0; i < fe->nprops; i++)
        roles[fe->props[i].role]++;
    if (!roles[ROLE_INDICES])
        return api__fail(err, MCF_EDECODE, "ply: element 'face' has no 'vertex_indices' list");

    /* Declared counts against the body, then against the limits. */
    blen = len - h->body;
    for (i = 0; i < h->nel; i++) {
        unsigned long long ms = api__ply_min_size(&h->el[i], h->format), c = h->el[i].count;
        if (ms && c > (ULLONG_MAX - need) / ms) {
            need = ULLONG_MAX;
        } else {
            need += c * ms;
        }
        /* ASCII: the last line may lack its newline. */
        if (c && need > (unsigned long long)blen + (h->format == FMT_ASCII))
            return api__fail(err, MCF_EDECODE,
                             "ply: header declares %llu '%s' elements, more than the "
                             "%zu-byte body can hold",
                             c, api__show(h->el[i].name, h->el[i].nlen, shown), blen);
    }
    if (ve->count > (unsigned long long)lim->max_vertices)
        return api__fail(err, MCF_ELIMIT, "ply: %llu vertices exceed max_vertices (%d)",
                         ve->count, lim->max_vertices);
    if (fe->count > (unsigned long long)lim->max_faces)
        return api__fail(err, MCF_ELIMIT, "ply: %llu faces exceed max_faces (%d)",
                         fe->count, lim->max_faces);
    if (ve->count == 0)
        return api__fail(err, MCF_EDECODE, "ply: no vertices");
    if (fe->count == 0)
        return api__fail(err, MCF_EDECODE, "ply: no faces: %llu vertices only", ve->count);
    *ve_out = ve;
    return MCF_OK;
}

/* The vertex attributes to read (api_ply_decode_attrs): an array per
 * attribute role of ve, integer colours scaled to [0, 1]; *float32: the
 * positions are all float. */
static mcf_status want_attrs(body *b, const element *ve, int *float32, mcf_error *err)
{
    int i;

    b->want = 1;
    for (i = 0; i < ve->nprops; i++) {
        const prop *p = &ve->props[i];
        if (p->role >= ROLE_X && p->role <= ROLE_Z && p->type != T_F32)
            *float32 = 0;
        if (p->role >= ROLE_NX && p->role <= ROLE_A) {
            int k = p->role - ROLE_NX;
            /* Integer colours (uchar, ushort) scale to [0, 1]. */
            b->vscale[k] = 1.0;
            if (p->role >= ROLE_R && is_int_type(p->type))
                b->vscale[k] = 1.0 / (p->type == T_U8 ? 255.0
                                     : p->type == T_U16 ? 65535.0
                                     : p->type == T_I8 ? 127.0
                                     : p->type == T_I16 ? 32767.0
                                                        : 4294967295.0);
            b->va[k] = malloc(sizeof *b->va[k] * (size_t)b->nv);
            if (!b->va[k])
                return api__fail(err, MCF_ENOMEM,
                               "ply: no memory for the attributes of %d vertices",
                               b->nv);
        }
        if (p->role == ROLE_EXTRA && p->extra < API__SCALARS_MAX
            && !(b->xa[p->extra] = malloc(sizeof *b->xa[0] * (size_t)b->nv)))
            return api__fail(err, MCF_ENOMEM,
                             "ply: no memory for the properties of %d vertices", b->nv);
    }
    return MCF_OK;
}

mcf_status api_ply_decode_attrs(const void *buf, size_t len,
                                const api_limits *lim, mcf_mesh **out,
                                api_attrs **attrs, mcf_error *err)
{
    api_limits def;
    header h;
    body b;
    const element *ve = NULL;
    size_t blen;
    int i, float32 = 1;
    mcf_mesh *m = NULL;
    mcf_status rc;

    memset(&h, 0, sizeof h);
    memset(&b, 0, sizeof b);
    if ((rc = api__decode_begin("ply", buf, len, &lim, &def, err)) != MCF_OK)
        return rc;
    if ((rc = api__ply_parse_header(buf, len, &h, err)) != MCF_OK)
        goto done;

    if ((rc = check_elements(&h, len, lim, &ve, err)) != MCF_OK)
        goto done;
    blen = len - h.body;

    b.buf = (const char *)buf + h.body;
    b.len = blen;
    b.format = h.format;
    b.txt.p = b.buf;
    b.txt.end = b.buf + b.len;
    b.txt.line = h.body_line - 1; /* the line before the first body line */
    b.nv = (int)ve->count;
    b.lim = lim;
    /* the triangles the declared counts pay for (api__fan_max) */
    for (i = 0; i < h.nel; i++)
        if (h.el[i].is_face)
            b.fan_max = api__fan_max(b.nv, (long long)h.el[i].count);
    b.X = malloc(3 * sizeof *b.X * (size_t)b.nv);
    if (!b.X) {
        rc = api__fail(err, MCF_ENOMEM, "ply: no memory for %d vertices", b.nv);
        goto done;
    }
    if (attrs && (rc = want_attrs(&b, ve, &float32, err)) != MCF_OK)
        goto done;
    rc = h.format == FMT_ASCII ? read_ascii(&b, &h, err) : read_binary(&b, &h, err);
    if (rc != MCF_OK)
        goto done;
    if ((rc = api__mesh_new(b.nv, b.X, (int)b.T.n, b.T.F, &m, err)) != MCF_OK)
        goto done;
    if (attrs && (rc = make_attrs(&b, &h, ve, m, float32, attrs, err)) != MCF_OK) {
        mcf_mesh_free(m);
        goto done;
    }
    *out = m;
done:
    free(b.X);
    free(b.T.F);
    for (i = 0; i < NVROLES; i++)
        free(b.va[i]);
    for (i = 0; i < API__SCALARS_MAX; i++)
        free(b.xa[i]);
    free(b.ftc);
    free(b.tmp);
    free(b.psize);
    api__ply_header_free(&h);
    return rc;
}

