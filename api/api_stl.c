/* SPDX-License-Identifier: MIT */
/*
 * api_stl.c - STL (stereolithography) reader and writer on memory buffers.
 *
 * STL stores a soup of triangles, each with its own three positions. The
 * reader welds corners with exactly equal positions into one vertex (a hash
 * on the bit pattern of x, y, z, with -0 taken as +0), which gives back the
 * connectivity of a mesh that was written from shared vertices. Faces that
 * become degenerate after welding are kept: core's inspection reports
 * them. Vertex order is the order of first appearance.
 *
 * Binary or ASCII: a file of exactly 84 + 50 n bytes, n being the count at
 * byte 80, is binary even when its free-form header starts with "solid"
 * (many exporters do that). Otherwise text starting with "solid" is ASCII;
 * anything else is a binary file whose size does not match its count, and
 * the error says so. ASCII is read as keywords (solid, facet normal, outer
 * loop, vertex, endloop, endfacet, endsolid), several solids per file
 * allowed, loops of more than three vertices fan-triangulated; errors name
 * the line. Facet normals are ignored (recomputed by whoever needs them).
 *
 * Writer: binary (float32 positions, unit facet normals, an 80-byte header
 * that does not start with "solid") or ASCII (%.17g, exact round trip).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "api_internal.h"

/* ---------------------------------------------------------------- weld */

typedef struct {
    double *X;           /* welded positions, 3 per vertex */
    int nv, cap;
    int32_t *slot;       /* open-addressing table of vertex indices, -1 empty */
    size_t nslot;        /* power of two */
    api__tris T;         /* the triangles */
    const api_limits *lim;
} weld;

static void weld_free(weld *w)
{
    free(w->X);
    free(w->slot);
    free(w->T.F);
}

static uint64_t bits(double d)
{
    uint64_t u;
    d += 0.0; /* -0 -> +0: equal positions must hash alike */
    memcpy(&u, &d, 8);
    return u;
}

static size_t hash3(const double *p)
{
    uint64_t h = 0x9e3779b97f4a7c15ull;
    int k;
    for (k = 0; k < 3; k++) {
        h ^= bits(p[k]);
        h *= 0xff51afd7ed558ccdull;
        h ^= h >> 33;
    }
    return (size_t)h;
}

static mcf_status weld_grow(weld *w, mcf_error *err)
{
    size_t ns = w->nslot ? 2 * w->nslot : 1024, i;
    int32_t *s = malloc(ns * sizeof *s);
    int v;
    if (!s)
        return api__fail(err, MCF_ENOMEM, "stl: out of memory welding vertices");
    for (i = 0; i < ns; i++)
        s[i] = -1;
    for (v = 0; v < w->nv; v++) {
        size_t j = hash3(&w->X[3 * (size_t)v]) & (ns - 1);
        while (s[j] >= 0)
            j = (j + 1) & (ns - 1);
        s[j] = v;
    }
    free(w->slot);
    w->slot = s;
    w->nslot = ns;
    return MCF_OK;
}

/* The index of the vertex at p, added when new. */
static mcf_status weld_vertex(weld *w, const double *p, int32_t *out,
                              mcf_error *err)
{
    size_t j;
    mcf_status rc;
    if ((size_t)w->nv * 2 >= w->nslot && (rc = weld_grow(w, err)) != MCF_OK)
        return rc;
    j = hash3(p) & (w->nslot - 1);
    while (w->slot[j] >= 0) {
        const double *q = &w->X[3 * (size_t)w->slot[j]];
        if (q[0] == p[0] && q[1] == p[1] && q[2] == p[2]) {
            *out = w->slot[j];
            return MCF_OK;
        }
        j = (j + 1) & (w->nslot - 1);
    }
    if (w->nv >= w->lim->max_vertices)
        return api__fail(err, MCF_ELIMIT,
                         "stl: more than max_vertices (%d) distinct vertices",
                         w->lim->max_vertices);
    if (w->nv == w->cap) {
        int ncap = w->cap ? (w->cap > w->lim->max_vertices / 2
                                 ? w->lim->max_vertices : 2 * w->cap)
                          : 1024;
        double *x = realloc(w->X, 3 * sizeof *x * (size_t)ncap);
        if (!x)
            return api__fail(err, MCF_ENOMEM, "stl: out of memory for %d vertices",
                             ncap);
        w->X = x;
        w->cap = ncap;
    }
    memcpy(&w->X[3 * (size_t)w->nv], p, 3 * sizeof *p);
    w->slot[j] = w->nv;
    *out = w->nv++;
    return MCF_OK;
}

static mcf_status weld_triangle(weld *w, const int32_t t[3], mcf_error *err)
{
    long long want = 0;
    mcf_status rc = api__tris_add(&w->T, t[0], t[1], t[2], w->lim->max_faces, 1024,
                                  &want);
    if (rc == MCF_ELIMIT)
        return api__fail(err, rc, "stl: more than max_faces (%d) triangles",
                         w->lim->max_faces);
    if (rc != MCF_OK)
        return api__fail(err, rc, "stl: out of memory for %lld triangles", want);
    return MCF_OK;
}

/* -------------------------------------------------------------- binary */

static float get_float(const unsigned char *p)
{
    uint32_t u = api__get_le32(p);
    float f;
    memcpy(&f, &u, 4);
    return f;
}

static mcf_status read_binary(const unsigned char *u, uint32_t n, weld *w,
                              mcf_error *err)
{
    uint32_t i;
    mcf_status rc;
    for (i = 0; i < n; i++) {
        const unsigned char *rec = u + 84 + 50 * (size_t)i;
        int32_t t[3];
        int k, c;
        for (k = 0; k < 3; k++) {
            double p[3];
            for (c = 0; c < 3; c++) {
                p[c] = get_float(rec + 12 + 12 * k + 4 * c);
                if (!isfinite(p[c]))
                    return api__fail(err, MCF_EDECODE,
                                     "stl: triangle %u: vertex %d has a non-finite "
                                     "coordinate",
                                     i, k + 1);
            }
            if ((rc = weld_vertex(w, p, &t[k], err)) != MCF_OK)
                return rc;
        }
        if ((rc = weld_triangle(w, t, err)) != MCF_OK)
            return rc;
    }
    return MCF_OK;
}

/* --------------------------------------------------------------- ASCII */

typedef struct {
    const char *p, *end;
    long line;
} lexer;

/* Next token; line counts the newlines passed. 0 at the end of input. */
static size_t lex(lexer *x, const char **tok)
{
    while (x->p < x->end && (api__is_space(*x->p) || *x->p == '\n')) {
        if (*x->p == '\n')
            x->line++;
        x->p++;
    }
    *tok = x->p;
    while (x->p < x->end && !api__is_space(*x->p) && *x->p != '\n')
        x->p++;
    return (size_t)(x->p - *tok);
}

/* Skips a solid's name: the rest of the line, up to a keyword that some
 * writers put on the same line (everything on one line is valid STL). */
static void skip_name(lexer *x)
{
    for (;;) {
        const char *t;
        size_t n;
        while (x->p < x->end && api__is_space(*x->p))
            x->p++;
        if (x->p >= x->end || *x->p == '\n')
            return;
        t = x->p;
        while (x->p < x->end && !api__is_space(*x->p) && *x->p != '\n')
            x->p++;
        n = (size_t)(x->p - t);
        if (api__tok_is(t, n, "facet") || api__tok_is(t, n, "endsolid")
            || api__tok_is(t, n, "solid")) {
            x->p = t;
            return;
        }
    }
}

static mcf_status expect(lexer *x, const char *word, mcf_error *err)
{
    const char *t;
    size_t n = lex(x, &t);
    char shown[API__SHOWN];
    if (n == 0)
        return api__fail(err, MCF_EDECODE, "stl: line %ld: input ends, '%s' expected",
                         x->line, word);
    if (!api__tok_is(t, n, word))
        return api__fail(err, MCF_EDECODE, "stl: line %ld: '%s' expected, found '%s'",
                         x->line, word, api__show(t, n, shown));
    return MCF_OK;
}

static mcf_status number(lexer *x, double *v, mcf_error *err)
{
    const char *t;
    size_t n = lex(x, &t);
    char shown[API__SHOWN];
    if (n == 0)
        return api__fail(err, MCF_EDECODE, "stl: line %ld: input ends, number expected",
                         x->line);
    if (api__parse_double(t, n, v) != 0)
        return api__fail(err, MCF_EDECODE, "stl: line %ld: bad number '%s'", x->line,
                         api__show(t, n, shown));
    return MCF_OK;
}

static mcf_status read_ascii(const char *buf, size_t len, weld *w, mcf_error *err)
{
    lexer x = {buf, buf + len, 1};
    const char *t;
    size_t n;
    char shown[API__SHOWN];
    int solids = 0;
    mcf_status rc;

    while ((n = lex(&x, &t)) != 0) {
        if (!api__tok_is(t, n, "solid"))
            return api__fail(err, MCF_EDECODE, "stl: line %ld: 'solid' expected, found '%s'",
                             x.line, api__show(t, n, shown));
        skip_name(&x);
        solids++;
        for (;;) {
            double nrm;
            int32_t first = 0, prev = 0;
            int k = 0, c;
            n = lex(&x, &t);
            if (n == 0)
                return api__fail(err, MCF_EDECODE,
                                 "stl: line %ld: input ends inside solid %d "
                                 "('endsolid' missing)",
                                 x.line, solids);
            if (api__tok_is(t, n, "endsolid")) {
                skip_name(&x);
                break;
            }
            if (!api__tok_is(t, n, "facet"))
                return api__fail(err, MCF_EDECODE,
                                 "stl: line %ld: 'facet' or 'endsolid' expected, "
                                 "found '%s'",
                                 x.line, api__show(t, n, shown));
            if ((rc = expect(&x, "normal", err)) != MCF_OK)
                return rc;
            for (c = 0; c < 3; c++)
                if ((rc = number(&x, &nrm, err)) != MCF_OK)
                    return rc;
            if ((rc = expect(&x, "outer", err)) != MCF_OK
                || (rc = expect(&x, "loop", err)) != MCF_OK)
                return rc;
            for (;;) {
                double p[3];
                int32_t v;
                n = lex(&x, &t);
                if (api__tok_is(t, n, "endloop"))
                    break;
                if (!api__tok_is(t, n, "vertex")) {
                    if (n == 0)
                        return api__fail(err, MCF_EDECODE,
                                         "stl: line %ld: input ends inside a facet",
                                         x.line);
                    return api__fail(err, MCF_EDECODE,
                                     "stl: line %ld: 'vertex' or 'endloop' expected, "
                                     "found '%s'",
                                     x.line, api__show(t, n, shown));
                }
                for (c = 0; c < 3; c++) {
                    if ((rc = number(&x, &p[c], err)) != MCF_OK)
                        return rc;
                    if (!isfinite(p[c]))
                        return api__fail(err, MCF_EDECODE,
                                         "stl: line %ld: coordinate is not finite",
                                         x.line);
                }
                if ((rc = weld_vertex(w, p, &v, err)) != MCF_OK)
                    return rc;
                if (k == 0)
                    first = v;
                else if (k >= 2) {
                    int32_t tri[3] = {first, prev, v};
                    if ((rc = weld_triangle(w, tri, err)) != MCF_OK)
                        return rc;
                }
                prev = v;
                k++;
            }
            if (k < 3)
                return api__fail(err, MCF_EDECODE,
                                 "stl: line %ld: facet has %d vertices, at least 3 "
                                 "needed",
                                 x.line, k);
            if ((rc = expect(&x, "endfacet", err)) != MCF_OK)
                return rc;
        }
    }
    if (solids == 0)
        return api__fail(err, MCF_EDECODE, "stl: no 'solid' in the input");
    return MCF_OK;
}

/* Text that starts with "solid" and has no control bytes in its first 512
 * bytes; a binary STL has NUL bytes in its count (bytes 80..83) unless it
 * holds more than 16 million triangles. */
static int looks_ascii(const char *buf, size_t len)
{
    size_t i = 0, lim = len < 512 ? len : 512;
    while (i < len && (api__is_space(buf[i]) || buf[i] == '\n'))
        i++;
    if (len - i < 5 || memcmp(buf + i, "solid", 5) != 0)
        return 0;
    for (i = 0; i < lim; i++) {
        unsigned char c = (unsigned char)buf[i];
        if ((c < 0x20 && !api__is_space(c) && c != '\n') || c == 0x7f)
            return 0;
    }
    return 1;
}

mcf_status api_stl_decode(const void *buf, size_t len, const api_limits *lim,
                          mcf_mesh **out, mcf_error *err)
{
    api_limits def;
    weld w;
    const unsigned char *u = buf;
    mcf_status rc;

    memset(&w, 0, sizeof w);
    if ((rc = api__decode_begin("stl", buf, len, &lim, &def, err)) != MCF_OK)
        return rc;
    w.lim = lim;

    if (len >= 84 && 84 + 50 * (uint64_t)api__get_le32(u + 80) == (uint64_t)len) {
        uint32_t n = api__get_le32(u + 80);
        if (n == 0)
            return api__fail(err, MCF_EDECODE, "stl: binary STL with 0 triangles");
        if (n > (uint32_t)lim->max_faces)
            return api__fail(err, MCF_ELIMIT,
                             "stl: %u triangles exceed max_faces (%d)", n,
                             lim->max_faces);
        rc = read_binary(u, n, &w, err);
    } else if (looks_ascii(buf, len)) {
        rc = read_ascii(buf, len, &w, err);
        if (rc == MCF_OK && w.T.n == 0)
            rc = api__fail(err, MCF_EDECODE, "stl: no facets");
    } else if (len < 84) {
        return api__fail(err, MCF_EDECODE,
                         "stl: %zu bytes: neither ASCII ('solid') nor binary "
                         "(84 bytes at least)",
                         len);
    } else {
        uint32_t n = api__get_le32(u + 80);
        return api__fail(err, MCF_EDECODE,
                         "stl: binary header announces %u triangles (%llu bytes) "
                         "but the input has %zu bytes",
                         n, (unsigned long long)(84 + 50 * (uint64_t)n), len);
    }
    if (rc != MCF_OK)
        goto done;
    rc = api__mesh_new(w.nv, w.X, (int)w.T.n, w.T.F, out, err);
done:
    weld_free(&w);
    return rc;
}

/* -------------------------------------------------------------- writer */

/* Unit normal of triangle t (zero when degenerate). The edge vectors and
 * then their cross product are scaled by their largest component, so that
 * neither the product nor the length overflows or underflows for extreme
 * coordinates. */
static void normal(const double *X, const int32_t *t, double n[3])
{
    const double *a = &X[3 * t[0]], *b = &X[3 * t[1]], *c = &X[3 * t[2]];
    double u[3], v[3], l, s = 0.0;
    int k;
    for (k = 0; k < 3; k++) {
        u[k] = b[k] - a[k];
        v[k] = c[k] - a[k];
        s = fmax(s, fmax(fabs(u[k]), fabs(v[k])));
    }
    if (s > 0 && isfinite(s))
        for (k = 0; k < 3; k++) {
            u[k] /= s;
            v[k] /= s;
        }
    n[0] = u[1] * v[2] - u[2] * v[1];
    n[1] = u[2] * v[0] - u[0] * v[2];
    n[2] = u[0] * v[1] - u[1] * v[0];
    s = fmax(fabs(n[0]), fmax(fabs(n[1]), fabs(n[2])));
    if (s > 0 && isfinite(s))
        for (k = 0; k < 3; k++)
            n[k] /= s;
    l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (k = 0; k < 3; k++)
        n[k] = (l > 0 && isfinite(l)) ? n[k] / l : 0.0;
}

mcf_status api_stl_encode(const mcf_mesh *m, const api_encode_opts *o,
                          api_buf *out, mcf_error *err)
{
    int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m), i, k;
    const double *X = mcf_mesh_positions(m);
    const int32_t *F = mcf_mesh_faces(m);
    int binary = o ? o->stl_binary != 0 : 1;
    size_t len0 = out->len;
    mcf_status rc = MCF_OK;

    if (binary) {
        unsigned char head[84];
        for (i = 0; i < 3 * nv; i++)
            if (fabs(X[i]) > 3.4028234663852886e38)
                return api__fail(err, MCF_EINVAL,
                                 "stl: vertex %d coordinate %g exceeds the float "
                                 "range of binary STL",
                                 i / 3, X[i]);
        memset(head, ' ', 80);
        memcpy(head, "mcfd binary STL", 15);
        api__put_le32(head + 80, (uint32_t)nf);
        rc = api_buf_append(out, head, sizeof head);
        for (i = 0; i < nf && rc == MCF_OK; i++) {
            unsigned char rec[50];
            double n[3];
            normal(X, &F[3 * i], n);
            for (k = 0; k < 3; k++)
                api__put_f32(rec + 4 * k, (float)n[k]);
            for (k = 0; k < 9; k++)
                api__put_f32(rec + 12 + 4 * k, (float)X[3 * F[3 * i + k / 3] + k % 3]);
            rec[48] = rec[49] = 0;
            rc = api_buf_append(out, rec, sizeof rec);
        }
    } else {
        rc = api_buf_printf(out, "solid mcfd\n");
        for (i = 0; i < nf && rc == MCF_OK; i++) {
            double n[3];
            normal(X, &F[3 * i], n);
            rc = api_buf_printf(out, "facet normal %.9g %.9g %.9g\nouter loop\n",
                                n[0], n[1], n[2]);
            for (k = 0; k < 3 && rc == MCF_OK; k++) {
                const double *p = &X[3 * F[3 * i + k]];
                rc = api_buf_printf(out, "vertex %.17g %.17g %.17g\n", p[0], p[1],
                                    p[2]);
            }
            if (rc == MCF_OK)
                rc = api_buf_printf(out, "endloop\nendfacet\n");
        }
        if (rc == MCF_OK)
            rc = api_buf_printf(out, "endsolid mcfd\n");
    }
    return api__encode_end(out, len0, rc, "stl", nf, "triangles", err);
}
