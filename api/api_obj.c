/* SPDX-License-Identifier: MIT */
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
 * Attributes (api_obj_decode_attrs): positions count as single precision
 * when no coordinate has more than 7 significant digits; `vt` (u, v; a
 * third w is dropped),
 * `vn` and vertex colours `v x y z r g b` become per-corner texture
 * coordinates, normals and per-vertex colours. An attribute some corner
 * lacks or refers to out of range (or a colour some vertex lacks) is
 * dropped, not an error: plain decoding never looked at those indices.
 *
 * Writer: `v` with %.17g (round-trips every double exactly) and 1-based
 * `f` triangles; with attributes (api_obj_encode_opts) `v x y z r g b`
 * when every vertex has one colour, `vt` values as they were, `vn`
 * recomputed from the surface and `f v/vt/vn` references.
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
                        int *nv, int *nf, long *nvt, long *nvn, long *npoly,
                        mcf_error *err)
{
    api__lines c = {buf, buf + len, 0};
    linecur l;
    long v = 0, f = 0, vt = 0, vn = 0, np = 0;

    while (api__line_next(&c, &l.s, &l.e)) {
        const char *t;
        size_t n = next_token(&l, &t);
        if (n == 1 && t[0] == 'v') {
            if (v >= lim->max_vertices)
                return api__fail(err, MCF_ELIMIT,
                                 "line %ld: more than max_vertices (%d) vertices",
                                 c.line, lim->max_vertices);
            v++;
        } else if (n == 2 && t[0] == 'v' && (t[1] == 't' || t[1] == 'n')) {
            /* Bounded by the line count, so no limit of their own. */
            if (t[1] == 't')
                vt++;
            else
                vn++;
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
                np++;
            }
        }
    }
    if (f > api__fan_max(v, np))
        return api__fail(err, MCF_ELIMIT,
                         "obj: %ld 'f' lines would fan into %ld triangles, more than "
                         "%ld vertices and %ld faces make (a closed surface of V "
                         "vertices has about 2V)", np, f, v, np);
    *nv = (int)v;
    *nf = (int)f;
    *npoly = np;
    *nvt = vt;
    *nvn = vn;
    return MCF_OK;
}

/* Attributes being read (api_obj_decode_attrs). An index array is freed
 * and set to NULL once some corner cannot be given a value. */
typedef struct {
    long nvt, nvn, seen_vt, seen_vn;
    double *vt, *vn, *col;          /* 2*nvt, 3*nvn, 3*nv */
    int32_t *ct, *cn;               /* 3*nf corner indices */
    int col_ok;                     /* every `v` had r g b so far */
    int maxsig;                     /* most significant digits of a coordinate */
    int32_t *psize;                 /* each `f` line's corner count */
    long np;                        /* `f` lines so far */
    api_attrs *st;                  /* the statements kept, until make_attrs */
} objattr;

/* The statements that pass through to the output, in order. */
static const char *const kept[] = {"g", "o", "s", "usemtl", "mtllib", NULL};

/* The significant digits of a number token: mantissa digits without the
 * leading zeros and, after a decimal point, the trailing ones. */
static int sig_digits(const char *t, size_t n)
{
    int lead = 1, digits = 0, zeros = 0, frac = 0;
    size_t i;
    for (i = 0; i < n && t[i] != 'e' && t[i] != 'E'; i++) {
        char ch = t[i];
        if (ch == '.') {
            frac = 1;
        } else if (ch >= '0' && ch <= '9') {
            if (ch == '0' && lead)
                continue;
            lead = 0;
            if (ch == '0') {
                zeros++;
            } else {
                digits += zeros + 1;
                zeros = 0;
            }
        }
    }
    /* Trailing zeros of the integer part are significant placeholders. */
    return frac ? digits : digits + zeros;
}

/* The 0-based index of an optional vt/vn reference of n bytes (n == 0:
 * absent), 1-based or negative relative to the seen so far; -1 when
 * absent or out of range. */
static long attr_ref(const char *t, size_t n, long seen, long total)
{
    char num[24];
    char *end;
    long long k;
    if (n == 0 || n >= sizeof num)
        return -1;
    memcpy(num, t, n);
    num[n] = '\0';
    errno = 0;
    k = strtoll(num, &end, 10);
    if (end != num + n || errno == ERANGE || k == 0)
        return -1;
    if (k > 0)
        return k <= total ? (long)(k - 1) : -1;
    return -k <= seen ? (long)(seen + k) : -1;
}

/* The vertex index of a face reference "v", "v/vt", "v//vn", "v/vt/vn",
 * converted to 0-based. seen: vertices read so far; total: in the file. */
static mcf_status face_ref(const char *t, size_t n, long line, int seen,
                           int total, int32_t *out, const objattr *A,
                           long *ivt, long *ivn, mcf_error *err)
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
    if (A) {
        /* "v/vt", "v//vn", "v/vt/vn": the spans between the slashes. */
        const char *a = slash ? slash + 1 : t + n, *e = t + n;
        const char *b = a < e ? memchr(a, '/', (size_t)(e - a)) : NULL;
        size_t la = (size_t)((b ? b : e) - a);
        *ivt = attr_ref(a, la, A->seen_vt, A->nvt);
        *ivn = b ? attr_ref(b + 1, (size_t)(e - b - 1), A->seen_vn, A->nvn) : -1;
    }
    return MCF_OK;
}

/* A "v" line's x y z into x (and, while every vertex has them, its
 * r g b into A->col for vertex i). */
static mcf_status parse_vertex(linecur *l, long line, double *x, int i, objattr *A,
                               mcf_error *err)
{
    char shown[API__SHOWN];
    int k;
    for (k = 0; k < 3; k++) {
        const char *nt;
        size_t nn = next_token(l, &nt);
        if (nn == 0)
            return api__fail(err, MCF_EDECODE,
                             "line %ld: vertex has %d coordinates, 3 needed",
                             line, k);
        if (api__parse_double(nt, nn, &x[k]) != 0)
            return api__fail(err, MCF_EDECODE,
                             "line %ld: bad number '%s'", line,
                             api__show_utf8(nt, nn, shown));
        if (!isfinite(x[k]))
            return api__fail(err, MCF_EDECODE,
                             "line %ld: coordinate '%s' is not finite",
                             line, api__show_utf8(nt, nn, shown));
        if (A) {
            int sd = sig_digits(nt, nn);
            if (sd > A->maxsig)
                A->maxsig = sd;
        }
    }
    if (A && A->col_ok) {
        /* Exactly r g b after x y z, each a finite number. */
        double *col = A->col + 3 * (size_t)i;
        for (k = 0; k < 3 && A->col_ok; k++) {
            const char *nt;
            size_t nn = next_token(l, &nt);
            if (nn == 0 || api__parse_double(nt, nn, &col[k]) != 0
                || !isfinite(col[k]))
                A->col_ok = 0;
        }
        if (A->col_ok) {
            const char *nt;
            if (next_token(l, &nt) != 0)
                A->col_ok = 0;
        }
    }
    return MCF_OK;
}

/* A "vt" (vt) or "vn" line into A; an unreadable value drops the
 * attribute, never an error. */
static void parse_attr_value(linecur *l, int vt, objattr *A)
{
    int k, want = vt ? 2 : 3;
    double *x = vt ? A->vt + 2 * A->seen_vt : A->vn + 3 * A->seen_vn;
    for (k = 0; k < want; k++) {
        const char *nt;
        size_t nn = next_token(l, &nt);
        x[k] = 0.0; /* "vt u" alone: v = 0, as the format says */
        if (nn == 0 && vt && k == 1)
            break;
        if (nn == 0 || api__parse_double(nt, nn, &x[k]) != 0
            || !isfinite(x[k])) {
            /* An unreadable value drops the attribute. */
            if (vt) {
                free(A->ct);
                A->ct = NULL;
            } else {
                free(A->cn);
                A->cn = NULL;
            }
            break;
        }
    }
    if (vt)
        A->seen_vt++;
    else
        A->seen_vn++;
}

/* Triangle tri's corner attribute indices (a, b, c) into *cp, or the
 * attribute dropped (*cp freed) when a corner has none. */
static void put_corners(int32_t **cp, long tri, long a, long b, long c)
{
    if (!*cp)
        return;
    if (a < 0 || b < 0 || c < 0) {
        free(*cp);
        *cp = NULL;
        return;
    }
    (*cp)[3 * tri] = (int32_t)a;
    (*cp)[3 * tri + 1] = (int32_t)b;
    (*cp)[3 * tri + 2] = (int32_t)c;
}

/* An "f" line, fan-triangulated into F from triangle *tri on (seen:
 * the vertices so far, for relative indices). */
static mcf_status parse_face(linecur *l, long line, int seen, int nv, int32_t *F,
                             long *tri, objattr *A, mcf_error *err)
{
    int32_t first = 0, prev = 0, cur = 0;
    long tf = -1, tp = -1, tc = -1, nfst = -1, np = -1, nc = -1;
    int k = 0;
    const char *nt;
    size_t nn;
    mcf_status rc;
    while ((nn = next_token(l, &nt)) > 0) {
        if ((rc = face_ref(nt, nn, line, seen, nv, &cur, A, &tc, &nc,
                           err)) != MCF_OK)
            return rc;
        if (k == 0) {
            first = cur;
            tf = tc;
            nfst = nc;
        } else if (k >= 2) {
            F[3 * *tri] = first;
            F[3 * *tri + 1] = prev;
            F[3 * *tri + 2] = cur;
            if (A) {
                put_corners(&A->ct, *tri, tf, tp, tc);
                put_corners(&A->cn, *tri, nfst, np, nc);
            }
            (*tri)++;
        }
        prev = cur;
        tp = tc;
        np = nc;
        k++;
    }
    if (k < 3)
        return api__fail(err, MCF_EDECODE,
                         "line %ld: face has %d vertices, at least 3 needed",
                         line, k);
    if (A)
        A->psize[A->np++] = k;
    return MCF_OK;
}

/* Any other statement (keyword t): one of those skipped (its text kept in
 * A when it is one of the kept ones), else an error. */
static mcf_status parse_other(const linecur *l, const char *t, size_t n, long line,
                              objattr *A, mcf_error *err)
{
    char shown[API__SHOWN];
    int i;
    for (i = 0; skipped[i]; i++)
        if (api__tok_is(t, n, skipped[i]))
            break;
    if (!skipped[i])
        return api__fail(err, MCF_EDECODE,
                         "line %ld: unknown statement '%s'", line,
                         api__show_utf8(t, n, shown));
    for (i = 0; A && kept[i]; i++)
        if (api__tok_is(t, n, kept[i])) {
            /* the line from its keyword, without trailing blanks */
            const char *e = l->e;
            while (e > t && api__is_space((unsigned char)e[-1]))
                e--;
            return api__attrs_stmt(A->st, (int32_t)A->np, t, (size_t)(e - t), err);
        }
    return MCF_OK;
}

/* Pass 2: parses into X (3*nv) and F (3*nf). */
static mcf_status parse(const char *buf, size_t len, int nv, double *X,
                        int32_t *F, objattr *A, mcf_error *err)
{
    api__lines c = {buf, buf + len, 0};
    linecur l;
    int seen = 0;
    long tri = 0;
    mcf_status rc = MCF_OK;

    while (rc == MCF_OK && api__line_next(&c, &l.s, &l.e)) {
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
            rc = parse_vertex(&l, c.line, X + 3 * (size_t)seen, seen, A, err);
            seen++;
        } else if (A && n == 2 && t[0] == 'v' && (t[1] == 't' || t[1] == 'n')) {
            parse_attr_value(&l, t[1] == 't', A);
        } else if (n == 1 && t[0] == 'f') {
            rc = parse_face(&l, c.line, seen, nv, F, &tri, A, err);
        } else {
            rc = parse_other(&l, t, n, c.line, A, err);
        }
    }
    return rc;
}

mcf_status api_obj_decode(const void *buf, size_t len, const api_limits *lim,
                          mcf_mesh **out, mcf_error *err)
{
    return api_obj_decode_attrs(buf, len, lim, out, NULL, err);
}

/* Hands what A holds to a new handle for m in *attrs; A's arrays are the
 * handle's or freed afterwards either way. */
static mcf_status make_attrs(objattr *A, const mcf_mesh *m, api_attrs **attrs,
                             mcf_error *err)
{
    int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m);
    api_attrs *a = api_attrs_new(nv, nf);
    mcf_status rc = MCF_OK;
    if (!a)
        return api__fail(err, MCF_ENOMEM, "obj: out of memory for the attributes");
    /* Text of at most 7 significant digits (what %g of a float and most
     * exporters write) is single precision: a float holds it. */
    a->float32 = A->maxsig <= 7;
    if (rc == MCF_OK && A->ct && A->nvt > 0) {
        rc = api__attrs_take(a, API_ATTR_TEXCOORD, 2, (int)A->nvt, A->vt, A->ct, err);
        A->vt = NULL;
        A->ct = NULL;
    }
    if (rc == MCF_OK && A->cn && A->nvn > 0) {
        rc = api__attrs_take(a, API_ATTR_NORMAL, 3, (int)A->nvn, A->vn, A->cn, err);
        A->vn = NULL;
        A->cn = NULL;
    }
    if (rc == MCF_OK && A->col_ok && nv > 0) {
        /* Per vertex: a corner's value is its vertex. */
        int32_t *cc = malloc(sizeof *cc * (size_t)(3 * (size_t)nf + 1));
        if (!cc) {
            rc = api__fail(err, MCF_ENOMEM, "obj: out of memory for the colours");
        } else {
            memcpy(cc, mcf_mesh_faces(m), sizeof *cc * 3 * (size_t)nf);
            rc = api__attrs_take(a, API_ATTR_COLOR, 3, nv, A->col, cc, err);
            A->col = NULL;
        }
    }
    if (rc == MCF_OK)
        rc = api__attrs_polys(a, A->psize, (int)A->np, err);
    if (rc != MCF_OK) {
        api_attrs_free(a);
        return rc;
    }
    /* the statements move over */
    a->stmt = A->st->stmt;
    a->nstmt = A->st->nstmt;
    A->st->stmt = NULL;
    A->st->nstmt = 0;
    *attrs = a;
    return MCF_OK;
}

mcf_status api_obj_decode_attrs(const void *buf, size_t len,
                                const api_limits *lim, mcf_mesh **out,
                                api_attrs **attrs, mcf_error *err)
{
    api_limits def;
    int nv = 0, nf = 0;
    long nvt = 0, nvn = 0, npoly = 0;
    double *X = NULL;
    int32_t *F = NULL;
    objattr A, *pa = NULL;
    mcf_mesh *m = NULL;
    mcf_status rc;

    memset(&A, 0, sizeof A);

    if ((rc = api__decode_begin("obj", buf, len, &lim, &def, err)) != MCF_OK)
        return rc;
    /* A UTF-8 byte-order mark, as some Windows exporters write. */
    if (len >= 3 && memcmp(buf, "\xEF\xBB\xBF", 3) == 0) {
        buf = (const char *)buf + 3;
        len -= 3;
    }
    if ((rc = count(buf, len, lim, &nv, &nf, &nvt, &nvn, &npoly, err)) != MCF_OK)
        return rc;
    X = malloc(3 * sizeof *X * (size_t)(nv ? nv : 1));
    F = malloc(3 * sizeof *F * (size_t)(nf ? nf : 1));
    if (!X || !F) {
        rc = api__fail(err, MCF_ENOMEM, "obj: no memory for %d vertices, %d faces",
                       nv, nf);
        goto done;
    }
    if (attrs) {
        size_t nc = 3 * (size_t)nf + 1;
        pa = &A;
        A.nvt = nvt;
        A.nvn = nvn;
        A.col_ok = 1;
        A.vt = malloc(2 * sizeof *A.vt * (size_t)(nvt + 1));
        A.vn = malloc(3 * sizeof *A.vn * (size_t)(nvn + 1));
        A.col = malloc(3 * sizeof *A.col * (size_t)(nv + 1));
        A.ct = nvt ? malloc(sizeof *A.ct * nc) : NULL;
        A.cn = nvn ? malloc(sizeof *A.cn * nc) : NULL;
        A.psize = malloc(sizeof *A.psize * (size_t)(npoly + 1));
        A.st = api_attrs_new(0, 0);
        if (!A.vt || !A.vn || !A.col || (nvt && !A.ct) || (nvn && !A.cn) || !A.psize ||
            !A.st) {
            rc = api__fail(err, MCF_ENOMEM,
                           "obj: no memory for the attributes of %d faces", nf);
            goto done;
        }
    }
    if ((rc = parse(buf, len, nv, X, F, pa, err)) != MCF_OK)
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
    if ((rc = api__mesh_new(nv, X, nf, F, &m, err)) != MCF_OK)
        goto done;
    if (attrs && (rc = make_attrs(&A, m, attrs, err)) != MCF_OK) {
        mcf_mesh_free(m);
        goto done;
    }
    *out = m;
done:
    free(X);
    free(F);
    free(A.vt);
    free(A.vn);
    free(A.col);
    free(A.ct);
    free(A.cn);
    free(A.psize);
    api_attrs_free(A.st);
    return rc;
}

mcf_status api_obj_encode(const mcf_mesh *m, api_buf *out, mcf_error *err)
{
    return api_obj_encode_opts(m, NULL, out, err);
}

mcf_status api_obj_encode_opts(const mcf_mesh *m, const api_encode_opts *o,
                               api_buf *out, mcf_error *err)
{
    int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m), i, k;
    const double *X = mcf_mesh_positions(m);
    const int32_t *F = mcf_mesh_faces(m);
    const api_attrs *a = o ? o->attrs : NULL;
    const api__attr *tc = NULL, *nm = NULL;
    double *col = NULL, *N = NULL;
    size_t len0 = out->len;
    mcf_status rc;

    if ((rc = api__attrs_check(a, m, "obj", err)) != MCF_OK)
        return rc;
    if (a) {
        tc = a->a[API_ATTR_TEXCOORD].corners ? &a->a[API_ATTR_TEXCOORD] : NULL;
        nm = a->a[API_ATTR_NORMAL].corners ? &a->a[API_ATTR_NORMAL] : NULL;
        if (a->a[API_ATTR_COLOR].corners) {
            col = malloc(sizeof *col * 4 * (size_t)(nv + 1));
            if (!col)
                return api__fail(err, MCF_ENOMEM, "obj: out of memory for colours");
            if (!api__attr_per_vertex(&a->a[API_ATTR_COLOR], m, col)) {
                free(col); /* colours differing at one vertex: OBJ cannot */
                col = NULL;
            }
        }
        if (nm && (rc = api__attrs_normals(a, m, &N, err)) != MCF_OK) {
            free(col);
            return rc;
        }
    }

    rc = api_buf_printf(out, "# mcfd: %d vertices, %d %s\n", nv,
                        a && a->poly ? a->npoly : nf, a && a->poly ? "polygons" : "triangles");
    for (i = 0; i < nv && rc == MCF_OK; i++) {
        rc = api_buf_printf(out, "v %.17g %.17g %.17g", X[3 * i], X[3 * i + 1],
                            X[3 * i + 2]);
        if (rc == MCF_OK && col) {
            int nc = a->a[API_ATTR_COLOR].ncomp;
            /* OBJ colours are r g b: an alpha channel is dropped. */
            rc = api_buf_printf(out, " %.17g %.17g %.17g", col[nc * i],
                                col[nc * i + 1], col[nc * i + 2]);
        }
        if (rc == MCF_OK)
            rc = api_buf_append(out, "\n", 1);
    }
    for (i = 0; tc && i < tc->nvalues && rc == MCF_OK; i++)
        rc = api_buf_printf(out, "vt %.17g %.17g\n", tc->values[2 * i],
                            tc->values[2 * i + 1]);
    for (i = 0; nm && i < nm->nvalues && rc == MCF_OK; i++)
        rc = api_buf_printf(out, "vn %.9g %.9g %.9g\n", N[3 * i], N[3 * i + 1],
                            N[3 * i + 2]);
    {
        /* polygons as they came, each statement before its polygon */
        api__poly_it it = {0, 0};
        size_t *cs = malloc(sizeof *cs * (size_t)api__attrs_maxpoly(a));
        int n, s = 0;
        if (!cs)
            rc = MCF_ENOMEM;
        while (rc == MCF_OK && api__poly_next(a, nf, &it, cs, &n)) {
            for (; a && s < a->nstmt && a->stmt[s].at < it.p && rc == MCF_OK; s++)
                rc = api_buf_printf(out, "%s\n", a->stmt[s].text);
            if (rc == MCF_OK)
                rc = api_buf_append(out, "f", 1);
            for (k = 0; k < n && rc == MCF_OK; k++) {
                size_t c = cs[k];
                long v = (long)F[c] + 1;
                if (tc && nm)
                    rc = api_buf_printf(out, " %ld/%ld/%ld", v, (long)tc->corners[c] + 1,
                                        (long)nm->corners[c] + 1);
                else if (tc)
                    rc = api_buf_printf(out, " %ld/%ld", v, (long)tc->corners[c] + 1);
                else if (nm)
                    rc = api_buf_printf(out, " %ld//%ld", v, (long)nm->corners[c] + 1);
                else
                    rc = api_buf_printf(out, " %ld", v);
            }
            if (rc == MCF_OK)
                rc = api_buf_append(out, "\n", 1);
        }
        for (; a && s < a->nstmt && rc == MCF_OK; s++)
            rc = api_buf_printf(out, "%s\n", a->stmt[s].text);
        free(cs);
    }
    free(col);
    free(N);
    return api__encode_end(out, len0, rc, "obj", nv, "vertices", err);
}
