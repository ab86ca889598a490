/* SPDX-License-Identifier: MIT */
/*
 * api_off.c - Object File Format (OFF, Geomview) reader and writer on
 * memory buffers.
 *
 * Reader: the keyword OFF or a variant carrying per-vertex extras (COFF,
 * NOFF, CNOFF, STOFF, ...: colours, normals, texture coordinates, which
 * are ignored), then "nv nf [ne]" (on the keyword's line or the next),
 * nv vertex lines "x y z [extras]" and nf face lines "n i1 .. in
 * [colour]" with 0-based indices; polygons are fan-triangulated (i1, ik,
 * ik+1). '#' starts a comment anywhere; blank lines are skipped. Every
 * vertex and face is one line, so extras are told apart from data and an
 * error names its line. 4OFF/nOFF (other dimensions) and binary OFF are
 * refused. The declared counts are checked against the body size (a
 * vertex line takes at least 6 bytes, a face line 8) and then the limits
 * before anything is allocated.
 *
 * Attributes (api_off_decode_attrs): none but the polygons' sizes, so
 * the writer gives quads and polygons back as they came.
 *
 * Writer: "OFF", counts, %.17g positions (exact round trip), triangles,
 * or the input's polygons when the attributes hold them.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "api_internal.h"

typedef struct {
    api__lines in;
    const char *s, *e;      /* rest of the current line, comment stripped */
} reader;

/* Next token of the current line; 0 at its end. */
static size_t token(reader *r, const char **t)
{
    return api__token(&r->s, r->e, t);
}

/* Next line with a token (comments stripped); 0 at the end of input. */
static int next_line(reader *r)
{
    const char *le, *hash, *p, *t;
    while (api__line_next(&r->in, &r->s, &le)) {
        hash = memchr(r->s, '#', (size_t)(le - r->s));
        r->e = hash ? hash : le;
        p = r->s;
        if (api__token(&p, r->e, &t) != 0)
            return 1;
    }
    return 0;
}

/* Is the token an OFF keyword: [ST][C][N][4][n]OFF? Sets *dims when it
 * is a 4OFF/nOFF (unsupported) one. */
static int off_keyword(const char *t, size_t n, int *other_dims)
{
    size_t i = 0;
    *other_dims = 0;
    if (n < 3 || memcmp(t + n - 3, "OFF", 3) != 0)
        return 0;
    if (i + 2 <= n - 3 && t[i] == 'S' && t[i + 1] == 'T')
        i += 2;
    if (i < n - 3 && t[i] == 'C')
        i++;
    if (i < n - 3 && t[i] == 'N')
        i++;
    if (i < n - 3 && t[i] == '4') {
        i++;
        *other_dims = 1;
    }
    if (i < n - 3 && t[i] == 'n') {
        i++;
        *other_dims = 1;
    }
    return i == n - 3;
}

/* The keyword line and the counts line ("nv nf [ne]", on the keyword's
 * line or the next) into cnt, checked against the body's size, then the
 * limits. */
static mcf_status read_counts(reader *r, size_t len, const api_limits *lim,
                              long long cnt[3], mcf_error *err)
{
    const char *t;
    size_t n;
    int ncnt = 0, other;
    char shown[API__SHOWN];
    unsigned long long need;

    if (!next_line(r))
        return api__fail(err, MCF_EDECODE, "off: no OFF keyword (only comments)");
    n = token(r, &t);
    if (!off_keyword(t, n, &other))
        return api__fail(err, MCF_EDECODE, "off: line %ld: 'OFF' expected, found '%s'",
                         r->in.line, api__show(t, n, shown));
    if (other)
        return api__fail(err, MCF_EDECODE,
                         "off: line %ld: '%s' (not 3-D) is not supported", r->in.line,
                         api__show(t, n, shown));
    n = token(r, &t);
    if (api__tok_is(t, n, "BINARY"))
        return api__fail(err, MCF_EDECODE, "off: line %ld: binary OFF is not supported",
                         r->in.line);
    if (n == 0) {
        if (!next_line(r))
            return api__fail(err, MCF_EDECODE,
                             "off: line %ld: input ends before the counts line", r->in.line);
        n = token(r, &t);
    }
    /* "nv nf [ne]" */
    while (n > 0) {
        if (ncnt == 3 || api__parse_int(t, n, &cnt[ncnt]) != 0 || cnt[ncnt] < 0)
            return api__fail(err, MCF_EDECODE,
                             "off: line %ld: 'nv nf [ne]' counts expected, found '%s'",
                             r->in.line, api__show(t, n, shown));
        ncnt++;
        n = token(r, &t);
    }
    if (ncnt < 2)
        return api__fail(err, MCF_EDECODE,
                         "off: line %ld: 'nv nf [ne]' counts expected", r->in.line);

    /* Counts against the body, then the limits. */
    need = (unsigned long long)cnt[0] * 6 + (unsigned long long)cnt[1] * 8;
    if (cnt[0] > (long long)len || cnt[1] > (long long)len
        || need > (unsigned long long)(r->in.end - r->in.p) + 1)
        return api__fail(err, MCF_EDECODE,
                         "off: line %ld: %lld vertices and %lld faces cannot fit in "
                         "the remaining %zu bytes",
                         r->in.line, cnt[0], cnt[1], (size_t)(r->in.end - r->in.p));
    if (cnt[0] > lim->max_vertices)
        return api__fail(err, MCF_ELIMIT, "off: %lld vertices exceed max_vertices (%d)",
                         cnt[0], lim->max_vertices);
    if (cnt[1] > lim->max_faces)
        return api__fail(err, MCF_ELIMIT, "off: %lld faces exceed max_faces (%d)",
                         cnt[1], lim->max_faces);
    if (cnt[0] == 0)
        return api__fail(err, MCF_EDECODE, "off: no vertices");
    if (cnt[1] == 0)
        return api__fail(err, MCF_EDECODE, "off: no faces: %lld vertices only",
                         cnt[0]);
    return MCF_OK;
}

/* nv vertex lines (x y z, finite) into X. */
static mcf_status read_vertices(reader *r, long long nv, double *X, mcf_error *err)
{
    const char *t;
    size_t n;
    char shown[API__SHOWN];
    int i, k;

    for (i = 0; i < (int)nv; i++) {
        if (!next_line(r))
            return api__fail(err, MCF_EDECODE,
                             "off: line %ld: input ends at vertex %d of %lld",
                             r->in.line, i, nv);
        for (k = 0; k < 3; k++) {
            n = token(r, &t);
            if (n == 0)
                return api__fail(err, MCF_EDECODE,
                                 "off: line %ld: vertex %d has %d coordinates, 3 "
                                 "needed",
                                 r->in.line, i, k);
            if (api__parse_double(t, n, &X[3 * i + k]) != 0)
                return api__fail(err, MCF_EDECODE, "off: line %ld: bad number '%s'",
                                 r->in.line, api__show(t, n, shown));
            if (!isfinite(X[3 * i + k]))
                return api__fail(err, MCF_EDECODE,
                                 "off: line %ld: coordinate '%s' is not finite",
                                 r->in.line, api__show(t, n, shown));
        }
    }
    return MCF_OK;
}

/* Face i's line (its vertex count, then its indices into nv vertices),
 * fan-triangulated into T (first sized from nf, the declared face count);
 * *deg: its corner count. */
static mcf_status read_face(reader *r, int i, long long nv, long long nf,
                            const api_limits *lim, api__tris *T, long long *deg,
                            mcf_error *err)
{
    const char *t;
    size_t n;
    char shown[API__SHOWN];
    long long k;
    int32_t first = 0, prev = 0;

    if (!next_line(r))
        return api__fail(err, MCF_EDECODE, "off: line %ld: input ends at face %d of %lld",
                         r->in.line, i, nf);
    n = token(r, &t);
    if (api__parse_int(t, n, deg) != 0)
        return api__fail(err, MCF_EDECODE, "off: line %ld: bad vertex count '%s'",
                         r->in.line, api__show(t, n, shown));
    if (*deg < 3)
        return api__fail(err, MCF_EDECODE, "off: line %ld: face %d has %lld vertices, "
                         "at least 3 needed",
                         r->in.line, i, *deg);
    if (*deg - 2 > api__fan_max(nv, nf) - T->n)
        return api__fail(err, MCF_ELIMIT, "off: line %ld: face %d has %lld corners: the "
                         "polygons would fan into more than %lld triangles, more than "
                         "%lld vertices and %lld faces make (a closed surface of V "
                         "vertices has about 2V)",
                         r->in.line, i, *deg, api__fan_max(nv, nf), nv, nf);
    for (k = 0; k < *deg; k++) {
        long long v;
        n = token(r, &t);
        if (n == 0)
            return api__fail(err, MCF_EDECODE,
                             "off: line %ld: face %d lists %lld of %lld vertices",
                             r->in.line, i, k, *deg);
        if (api__parse_int(t, n, &v) != 0)
            return api__fail(err, MCF_EDECODE, "off: line %ld: bad index '%s'",
                             r->in.line, api__show(t, n, shown));
        if (v < 0 || v >= nv)
            return api__fail(err, MCF_EDECODE, "off: line %ld: face %d: index %lld out "
                             "of range (0..%lld)",
                             r->in.line, i, v, nv - 1);
        if (k == 0) {
            first = (int32_t)v;
        } else if (k >= 2) {
            /* First sized from the declared face count. */
            long long want = 0;
            mcf_status trc = api__tris_add(T, first, prev, (int32_t)v,
                                           lim->max_faces, nf, &want);
            if (trc == MCF_ELIMIT)
                return api__fail(err, trc,
                                 "off: line %ld: more than max_faces (%d) triangles",
                                 r->in.line, lim->max_faces);
            if (trc != MCF_OK)
                return api__fail(err, trc, "off: no memory for %lld triangles", want);
        }
        prev = (int32_t)v;
    }
    /* Anything left on the line is the face's colour: ignored. */
    return MCF_OK;
}

/* The decoder; psize (NULL: not wanted) gets each face's corner count
 * (cnt[1] of them, malloc'ed, the caller's). */
static mcf_status decode(const void *buf, size_t len, const api_limits *lim,
                         mcf_mesh **out, int32_t **psize, int *npoly, mcf_error *err)
{
    api_limits def;
    reader r;
    long long cnt[3] = {0, 0, 0}, deg;
    int i;
    double *X = NULL;
    api__tris T = {NULL, 0, 0};
    mcf_status rc;

    if ((rc = api__decode_begin("off", buf, len, &lim, &def, err)) != MCF_OK)
        return rc;
    r.in.p = buf;
    r.in.end = r.in.p + len;
    r.in.line = 0;
    if ((rc = read_counts(&r, len, lim, cnt, err)) != MCF_OK)
        return rc;

    X = malloc(3 * sizeof *X * (size_t)cnt[0]);
    if (psize && !(*psize = malloc(sizeof **psize * (size_t)cnt[1]))) {
        rc = api__fail(err, MCF_ENOMEM, "off: no memory for %lld faces", cnt[1]);
        goto done;
    }
    if (psize)
        *npoly = (int)cnt[1];
    if (!X) {
        rc = api__fail(err, MCF_ENOMEM, "off: no memory for %lld vertices", cnt[0]);
        goto done;
    }
    if ((rc = read_vertices(&r, cnt[0], X, err)) != MCF_OK)
        goto done;
    for (i = 0; i < (int)cnt[1]; i++) {
        if ((rc = read_face(&r, i, cnt[0], cnt[1], lim, &T, &deg, err)) != MCF_OK)
            goto done;
        if (psize)
            (*psize)[i] = (int32_t)deg;
    }
    if (next_line(&r)) {
        rc = api__fail(err, MCF_EDECODE, "off: line %ld: data after the last face",
                       r.in.line);
        goto done;
    }
    rc = api__mesh_new((int)cnt[0], X, (int)T.n, T.F, out, err);
done:
    free(X);
    free(T.F);
    return rc;
}

mcf_status api_off_decode(const void *buf, size_t len, const api_limits *lim,
                          mcf_mesh **out, mcf_error *err)
{
    return decode(buf, len, lim, out, NULL, NULL, err);
}

mcf_status api_off_decode_attrs(const void *buf, size_t len, const api_limits *lim,
                                mcf_mesh **out, api_attrs **attrs, mcf_error *err)
{
    int32_t *psize = NULL;
    int np = 0;
    mcf_mesh *m = NULL;
    api_attrs *a;
    mcf_status rc = decode(buf, len, lim, &m, attrs ? &psize : NULL, &np, err);
    if (rc == MCF_OK && attrs) {
        if (!(a = api_attrs_new(mcf_mesh_nvertices(m), mcf_mesh_nfaces(m))))
            rc = api__fail(err, MCF_ENOMEM, "off: out of memory");
        else if ((rc = api__attrs_polys(a, psize, np, err)) != MCF_OK)
            api_attrs_free(a);
        else
            *attrs = a;
    }
    free(psize);
    if (rc != MCF_OK) {
        mcf_mesh_free(m);
        return rc;
    }
    *out = m;
    return MCF_OK;
}

mcf_status api_off_encode(const mcf_mesh *m, api_buf *out, mcf_error *err)
{
    return api_off_encode_opts(m, NULL, out, err);
}

mcf_status api_off_encode_opts(const mcf_mesh *m, const api_encode_opts *o,
                               api_buf *out, mcf_error *err)
{
    int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m), i, n, k;
    const double *X = mcf_mesh_positions(m);
    const int32_t *F = mcf_mesh_faces(m);
    const api_attrs *a = o ? o->attrs : NULL;
    api__poly_it it = {0, 0};
    size_t len0 = out->len, *cs;
    mcf_status rc;

    if ((rc = api__attrs_check(a, m, "off", err)) != MCF_OK)
        return rc;
    if (!(cs = malloc(sizeof *cs * (size_t)api__attrs_maxpoly(a))))
        return api__fail(err, MCF_ENOMEM, "off: out of memory");
    rc = api_buf_printf(out, "OFF\n%d %d 0\n", nv, a && a->poly ? a->npoly : nf);
    for (i = 0; i < nv && rc == MCF_OK; i++)
        rc = api_buf_printf(out, "%.17g %.17g %.17g\n", X[3 * i], X[3 * i + 1],
                            X[3 * i + 2]);
    while (rc == MCF_OK && api__poly_next(a, nf, &it, cs, &n)) {
        rc = api_buf_printf(out, "%d", n);
        for (k = 0; k < n && rc == MCF_OK; k++)
            rc = api_buf_printf(out, " %ld", (long)F[cs[k]]);
        if (rc == MCF_OK)
            rc = api_buf_append(out, "\n", 1);
    }
    free(cs);
    return api__encode_end(out, len0, rc, "off", nv, "vertices", err);
}
