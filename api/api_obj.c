/*
 * api_obj.c - Wavefront OBJ reader and writer on memory buffers.
 *
 * Reader: `v x y z [w | r g b]` and `f` with `v`, `v/vt`, `v//vn` or
 * `v/vt/vn` references, 1-based or negative (relative to the vertices read
 * so far); polygons are fan-triangulated (v0, vi, vi+1). Texture, normal,
 * grouping, material, smoothing, line and free-form statements are
 * skipped; anything else is an error. Two passes: the first only counts
 * `v` lines and triangles so every limit is checked, naming the line where
 * it is crossed, before anything is allocated; the second parses into
 * exact-size arrays. The buffer is not NUL-terminated: every number is
 * copied into a small local buffer before strtod/strtol see it. Positive
 * indices may refer to vertices defined later in the file (the first pass
 * knows the total), as most readers allow.
 *
 * Writer: `v` with %.17g (round-trips every double exactly) and 1-based
 * `f` triangles.
 */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "api_internal.h"

/* Statements that carry nothing a triangle mesh needs. */
static const char *const skipped[] = {
    "vt", "vn", "vp", "g", "o", "s", "usemtl", "mtllib", "l", "p",
    "cstype", "deg", "bmat", "step", "curv", "curv2", "surf", "parm",
    "trim", "hole", "scrv", "sp", "end", "con", "mg", "bevel", "c_interp",
    "d_interp", "lod", "shadow_obj", "trace_obj", "ctech", "stech", "maplib",
    "usemap", "call", "csh", NULL};

typedef struct {
    const char *s, *e;     /* rest of the current line */
} linecur;

/* Next white-space separated token; a token starting with '#' ends the
 * line (trailing comment). Returns its length, 0 at the end of the line. */
static size_t next_token(linecur *l, const char **tok)
{
    size_t n = api__token(&l->s, l->e, tok);
    if (n > 0 && **tok == '#') {
        l->s = l->e;
        return 0;
    }
    return n;
}

/* The first control byte of a line (other than white space), or -1. */
static int binary_byte(const linecur *l)
{
    const char *s;
    for (s = l->s; s < l->e; s++) {
        unsigned char ch = (unsigned char)*s;
        if ((ch < 0x20 && !api__is_space(ch)) || ch == 0x7f)
            return ch;
    }
    return -1;
}

/* Pass 1: counts vertices and triangles, checking the limits as they grow. */
static mcf_status count(const char *buf, size_t len, const api_limits *lim,
                        int *nv, int *nf, mcf_error *err)
{
    api__lines c = {buf, buf + len, 0};
    linecur l;
    long v = 0, f = 0;

    while (api__line_next(&c, &l.s, &l.e)) {
        const char *t;
        size_t n = next_token(&l, &t);
        if (n == 1 && t[0] == 'v') {
            if (v >= lim->max_vertices)
                return api__fail(err, MCF_ELIMIT,
                                 "line %ld: more than max_vertices (%d) vertices",
                                 c.line, lim->max_vertices);
            v++;
        } else if (n == 1 && t[0] == 'f') {
            long k = 0;
            while (next_token(&l, &t))
                k++;
            if (k >= 3) {
                if (k - 2 > (long)lim->max_faces - f)
                    return api__fail(err, MCF_ELIMIT,
                                     "line %ld: more than max_faces (%d) triangles",
                                     c.line, lim->max_faces);
                f += k - 2;
            }
        }
    }
    *nv = (int)v;
    *nf = (int)f;
    return MCF_OK;
}

/* The vertex index of a face reference "v", "v/vt", "v//vn", "v/vt/vn",
 * converted to 0-based. seen: vertices read so far; total: in the file. */
static mcf_status face_ref(const char *t, size_t n, long line, int seen,
                           int total, int32_t *out, mcf_error *err)
{
    char tmp[API__SHOWN], num[24], shown[API__SHOWN];
    const char *slash = memchr(t, '/', n);
    size_t vlen = slash ? (size_t)(slash - t) : n;
    char *end;
    long long k;
    size_t i;
    int slashes = 0;

    /* What follows the vertex index: "/vt", "//vn" or "/vt/vn", digits
     * (optionally negative) only; the values themselves are not used. */
    for (i = vlen; i < n; i++) {
        char ch = t[i];
        if (ch == '/') {
            if (++slashes > 2)
                break;
        } else if (!((ch >= '0' && ch <= '9') || ch == '-')) {
            break;
        }
    }
    if (i < n || (slashes == 1 && vlen + 1 == n))
        return api__fail(err, MCF_EDECODE, "line %ld: bad face vertex '%s'",
                         line, api__show_utf8(t, n, shown));
    if (vlen == 0 || vlen >= sizeof num)
        return api__fail(err, MCF_EDECODE,
                         "line %ld: bad face vertex index '%s'", line,
                         api__show_utf8(t, n, shown));
    memcpy(num, t, vlen);
    num[vlen] = '\0';
    errno = 0;
    k = strtoll(num, &end, 10);
    if (end != num + vlen || num[0] == '+' || api__is_space(num[0]))
        return api__fail(err, MCF_EDECODE,
                         "line %ld: bad face vertex index '%s'", line,
                         api__show_utf8(t, n, shown));
    if (k == 0)
        return api__fail(err, MCF_EDECODE,
                         "line %ld: face index 0 (OBJ indices start at 1)", line);
    if (k > 0) {
        if (errno == ERANGE || k > total)
            return api__fail(err, MCF_EDECODE,
                             "line %ld: face index %s out of range (1..%d)",
                             line, api__show_utf8(num, vlen, tmp), total);
        *out = (int32_t)(k - 1);
    } else {
        if (errno == ERANGE || -k > seen)
            return api__fail(err, MCF_EDECODE,
                             "line %ld: face index %s out of range (-%d..-1)",
                             line, api__show_utf8(num, vlen, tmp), seen);
        *out = (int32_t)(seen + k);
    }
    return MCF_OK;
}

/* Pass 2: parses into X (3*nv) and F (3*nf). */
static mcf_status parse(const char *buf, size_t len, int nv, double *X,
                        int32_t *F, mcf_error *err)
{
    api__lines c = {buf, buf + len, 0};
    linecur l;
    int seen = 0;
    long tri = 0;
    char shown[API__SHOWN];

    while (api__line_next(&c, &l.s, &l.e)) {
        const char *t;
        size_t n;
        int bad = binary_byte(&l);

        if (bad >= 0)
            return api__fail(err, MCF_EDECODE,
                             "line %ld: binary data (byte 0x%02x), not OBJ text",
                             c.line, (unsigned)bad);
        n = next_token(&l, &t);
        if (n == 0)
            continue;
        if (n == 1 && t[0] == 'v') {
            double *x = X + 3 * (size_t)seen;
            int k;
            for (k = 0; k < 3; k++) {
                const char *nt;
                size_t nn = next_token(&l, &nt);
                if (nn == 0)
                    return api__fail(err, MCF_EDECODE,
                                     "line %ld: vertex has %d coordinates, 3 needed",
                                     c.line, k);
                if (api__parse_double(nt, nn, &x[k]) != 0)
                    return api__fail(err, MCF_EDECODE,
                                     "line %ld: bad number '%s'", c.line,
                                     api__show_utf8(nt, nn, shown));
                if (!isfinite(x[k]))
                    return api__fail(err, MCF_EDECODE,
                                     "line %ld: coordinate '%s' is not finite",
                                     c.line, api__show_utf8(nt, nn, shown));
            }
            seen++;
        } else if (n == 1 && t[0] == 'f') {
            int32_t first = 0, prev = 0, cur = 0;
            int k = 0;
            const char *nt;
            size_t nn;
            mcf_status rc;
            while ((nn = next_token(&l, &nt)) > 0) {
                if ((rc = face_ref(nt, nn, c.line, seen, nv, &cur, err)) != MCF_OK)
                    return rc;
                if (k == 0)
                    first = cur;
                else if (k >= 2) {
                    F[3 * tri] = first;
                    F[3 * tri + 1] = prev;
                    F[3 * tri + 2] = cur;
                    tri++;
                }
                prev = cur;
                k++;
            }
            if (k < 3)
                return api__fail(err, MCF_EDECODE,
                                 "line %ld: face has %d vertices, at least 3 needed",
                                 c.line, k);
        } else {
            int i;
            for (i = 0; skipped[i]; i++)
                if (api__tok_is(t, n, skipped[i]))
                    break;
            if (!skipped[i])
                return api__fail(err, MCF_EDECODE,
                                 "line %ld: unknown statement '%s'", c.line,
                                 api__show_utf8(t, n, shown));
        }
    }
    return MCF_OK;
}

mcf_status api_obj_decode(const void *buf, size_t len, const api_limits *lim,
                          mcf_mesh **out, mcf_error *err)
{
    api_limits def;
    int nv = 0, nf = 0;
    double *X = NULL;
    int32_t *F = NULL;
    mcf_status rc;

    if ((rc = api__decode_begin("obj", buf, len, &lim, &def, err)) != MCF_OK)
        return rc;
    /* A UTF-8 byte-order mark, as some Windows exporters write. */
    if (len >= 3 && memcmp(buf, "\xEF\xBB\xBF", 3) == 0) {
        buf = (const char *)buf + 3;
        len -= 3;
    }
    if ((rc = count(buf, len, lim, &nv, &nf, err)) != MCF_OK)
        return rc;
    X = malloc(3 * sizeof *X * (size_t)(nv ? nv : 1));
    F = malloc(3 * sizeof *F * (size_t)(nf ? nf : 1));
    if (!X || !F) {
        rc = api__fail(err, MCF_ENOMEM, "obj: no memory for %d vertices, %d faces",
                       nv, nf);
        goto done;
    }
    if ((rc = parse(buf, len, nv, X, F, err)) != MCF_OK)
        goto done;
    if (nv == 0) {
        rc = api__fail(err, MCF_EDECODE, "obj: no vertices ('v' lines)");
        goto done;
    }
    if (nf == 0) {
        rc = api__fail(err, MCF_EDECODE,
                       "obj: no faces ('f' lines): %d vertices only", nv);
        goto done;
    }
    rc = api__mesh_new(nv, X, nf, F, out, err);
done:
    free(X);
    free(F);
    return rc;
}

mcf_status api_obj_encode(const mcf_mesh *m, api_buf *out, mcf_error *err)
{
    int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m), i;
    const double *X = mcf_mesh_positions(m);
    const int32_t *F = mcf_mesh_faces(m);
    size_t len0 = out->len;
    mcf_status rc;

    rc = api_buf_printf(out, "# mcfd: %d vertices, %d triangles\n", nv, nf);
    for (i = 0; i < nv && rc == MCF_OK; i++)
        rc = api_buf_printf(out, "v %.17g %.17g %.17g\n", X[3 * i],
                            X[3 * i + 1], X[3 * i + 2]);
    for (i = 0; i < nf && rc == MCF_OK; i++)
        rc = api_buf_printf(out, "f %ld %ld %ld\n", (long)F[3 * i] + 1,
                            (long)F[3 * i + 1] + 1, (long)F[3 * i + 2] + 1);
    return api__encode_end(out, len0, rc, "obj", nv, "vertices", err);
}
