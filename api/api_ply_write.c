/* SPDX-License-Identifier: MIT */
/*
 * api_ply_write.c - the Stanford PLY writer (api_ply_encode; the reader:
 * api_ply.c).
 *
 * Writer: ascii or binary_little_endian (independent of the host's byte
 * order), x y z as float when the attributes say the input was single
 * precision, else double; with attributes, nx ny nz recomputed from the
 * surface (per vertex), texcoords as vertex s t (or, at UV seams, the face
 * `texcoord` list), uchar red green blue [alpha]; optional float
 * `mean_curvature` and `gaussian_curvature` vertex properties (given, or
 * computed with ply_curvature); `property list uchar int vertex_indices`
 * triangles, or the input's polygons when the attributes hold them (of at
 * most 127 corners, so a face texcoord list's count fits its uchar);
 * the input's other vertex scalars (api__scalar) last, with their names
 * and types, values as they came.
 * ASCII uses %.17g for doubles, %.9g for floats (exact round
 * trips).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "api_ply_internal.h"

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
    const api__scalar *S;   /* the input's other vertex scalars */
    int ns;
} plyextra;

/* Whether scalar k is written: not one this writer computes itself. */
static int scalar_kept(const plyextra *x, int k)
{
    const char *n = x->S[k].name;
    return !(x->H && strcmp(n, "mean_curvature") == 0)
           && !(x->K && strcmp(n, "gaussian_curvature") == 0);
}

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
    x->S = a->scal;
    x->ns = a->nscal;
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

/* The header: x y z as float or double, the attributes x carries, and
 * nfaces faces (with their texcoord lists when x has them). */
static mcf_status write_header(api_buf *out, const plyextra *x, int binary, int nv,
                               int nfaces)
{
    const char *real;
    mcf_status rc;
    int k;

    real = x->f32 ? "float" : "double";
    rc = api_buf_printf(out,
                        "ply\nformat %s 1.0\ncomment mcfd\nelement vertex %d\n"
                        "property %s x\nproperty %s y\nproperty %s z\n",
                        binary ? "binary_little_endian" : "ascii", nv, real, real,
                        real);
    if (rc == MCF_OK && x->N)
        rc = api_buf_printf(out, "property %s nx\nproperty %s ny\nproperty %s nz\n",
                            real, real, real);
    if (rc == MCF_OK && x->T)
        rc = api_buf_printf(out, "property %s s\nproperty %s t\n", real, real);
    if (rc == MCF_OK && x->C)
        rc = api_buf_printf(out, "property uchar red\nproperty uchar green\n"
                                 "property uchar blue\n%s",
                            x->ccomp == 4 ? "property uchar alpha\n" : "");
    if (rc == MCF_OK && x->H)
        rc = api_buf_printf(out, "property float mean_curvature\n");
    if (rc == MCF_OK && x->K)
        rc = api_buf_printf(out, "property float gaussian_curvature\n");
    for (k = 0; k < x->ns && rc == MCF_OK; k++)
        if (scalar_kept(x, k))
            rc = api_buf_printf(out, "property %s %s\n",
                                api__ply_type_name((ptype)x->S[k].type), x->S[k].name);
    if (rc == MCF_OK)
        rc = api_buf_printf(out, "element face %d\nproperty list uchar int "
                                 "vertex_indices\n%s",
                            nfaces, x->ftc ? "" : "end_header\n");
    if (rc == MCF_OK && x->ftc)
        rc = api_buf_printf(out, "property list uchar %s texcoord\nend_header\n",
                            real);
    return rc;
}

/* Appends v as a little-endian value of PLY type t (v came from a value of
 * that type, so the conversion is exact). */
static void put_typed(unsigned char *p, size_t *n, double v, ptype t)
{
    switch (t) {
    case T_I8: case T_U8:
        p[*n] = t == T_I8 ? (unsigned char)(signed char)v : (unsigned char)v;
        break;
    case T_I16: case T_U16: {
        uint16_t u = t == T_I16 ? (uint16_t)(int16_t)v : (uint16_t)v;
        p[*n] = (unsigned char)u;
        p[*n + 1] = (unsigned char)(u >> 8);
        break;
    }
    case T_I32: case T_U32:
        api__put_le32(p + *n, t == T_I32 ? (uint32_t)(int32_t)v : (uint32_t)v);
        break;
    case T_F32:
        api__put_f32(p + *n, (float)v);
        break;
    default:
        put_double(p + *n, v);
        break;
    }
    *n += api__ply_type_size[t == T_NONE ? T_F64 : t];
}

/* Vertex i's row (X its position): binary little-endian or ASCII. */
static mcf_status vertex_binary(api_buf *out, const plyextra *x, const double *X, int i)
{
    /* x y z, normals, texcoords (8 bytes each), colours, H, K, scalars */
    unsigned char v[8 * 8 + 4 + 2 * 4 + 8 * API__SCALARS_MAX];
    size_t n = 0;
    int k;
    for (k = 0; k < 3; k++)
        put_real(v, &n, X[3 * i + k], x->f32);
    for (k = 0; x->N && k < 3; k++)
        put_real(v, &n, x->N[3 * i + k], x->f32);
    for (k = 0; x->T && k < 2; k++)
        put_real(v, &n, x->T[2 * i + k], x->f32);
    for (k = 0; x->C && k < x->ccomp; k++)
        v[n++] = color_byte(x->C[x->ccomp * i + k]);
    if (x->H) {
        api__put_f32(v + n, (float)x->H[i]);
        n += 4;
    }
    if (x->K) {
        api__put_f32(v + n, (float)x->K[i]);
        n += 4;
    }
    for (k = 0; k < x->ns; k++)
        if (scalar_kept(x, k))
            put_typed(v, &n, x->S[k].values[i], (ptype)x->S[k].type);
    return api_buf_append(out, v, n);
}

static mcf_status vertex_ascii(api_buf *out, const plyextra *x, const double *X, int i)
{
    mcf_status rc;
    int k;
    rc = api_buf_printf(out, x->f32 ? "%.9g %.9g %.9g" : "%.17g %.17g %.17g",
                        x->f32 ? (double)(float)X[3 * i] : X[3 * i],
                        x->f32 ? (double)(float)X[3 * i + 1] : X[3 * i + 1],
                        x->f32 ? (double)(float)X[3 * i + 2] : X[3 * i + 2]);
    for (k = 0; x->N && k < 3 && rc == MCF_OK; k++)
        rc = print_real(out, x->N[3 * i + k], x->f32);
    for (k = 0; x->T && k < 2 && rc == MCF_OK; k++)
        rc = print_real(out, x->T[2 * i + k], x->f32);
    for (k = 0; x->C && k < x->ccomp && rc == MCF_OK; k++)
        rc = api_buf_printf(out, " %u", (unsigned)color_byte(x->C[x->ccomp * i + k]));
    if (rc == MCF_OK && x->H)
        rc = api_buf_printf(out, " %.9g", (double)(float)x->H[i]);
    if (rc == MCF_OK && x->K)
        rc = api_buf_printf(out, " %.9g", (double)(float)x->K[i]);
    for (k = 0; k < x->ns && rc == MCF_OK; k++) {
        ptype t = (ptype)x->S[k].type;
        if (scalar_kept(x, k))
            rc = is_int_type(t) ? api_buf_printf(out, " %.0f", x->S[k].values[i])
                                : print_real(out, x->S[k].values[i], t == T_F32);
    }
    if (rc == MCF_OK)
        rc = api_buf_append(out, "\n", 1);
    return rc;
}

/* Texcoord value k (2 per corner) of the polygon whose corners are cs. */
static double face_tc(const plyextra *x, const size_t *cs, int k)
{
    return x->ftc->values[2 * (size_t)x->ftc->corners[cs[k / 2]] + (size_t)(k % 2)];
}

/* The row of a polygon of pn corners (cs: their corner indices into F),
 * with its texcoord list when there is one; fb: room for the binary row. */
static mcf_status face_binary(api_buf *out, const plyextra *x, const int32_t *F,
                              const size_t *cs, int pn, unsigned char *fb)
{
    size_t b = 1;
    int k;
    fb[0] = (unsigned char)pn;
    for (k = 0; k < pn; k++, b += 4)
        api__put_le32(fb + b, (uint32_t)F[cs[k]]);
    if (x->ftc) {
        fb[b++] = (unsigned char)(2 * pn);
        for (k = 0; k < 2 * pn; k++)
            put_real(fb, &b, face_tc(x, cs, k), x->f32);
    }
    return api_buf_append(out, fb, b);
}

static mcf_status face_ascii(api_buf *out, const plyextra *x, const int32_t *F,
                             const size_t *cs, int pn)
{
    mcf_status rc = api_buf_printf(out, "%d", pn);
    int k;
    for (k = 0; k < pn && rc == MCF_OK; k++)
        rc = api_buf_printf(out, " %ld", (long)F[cs[k]]);
    if (rc == MCF_OK && x->ftc) {
        rc = api_buf_printf(out, " %d", 2 * pn);
        for (k = 0; k < 2 * pn && rc == MCF_OK; k++)
            rc = print_real(out, face_tc(x, cs, k), x->f32);
    }
    if (rc == MCF_OK)
        rc = api_buf_append(out, "\n", 1);
    return rc;
}

mcf_status api_ply_encode(const mcf_mesh *m, const api_encode_opts *o,
                          api_buf *out, mcf_error *err)
{
    int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m), i;
    const double *X = mcf_mesh_positions(m);
    const int32_t *F = mcf_mesh_faces(m);
    int binary = o ? o->ply_binary != 0 : 1, pn;
    size_t len0 = out->len, *cs;
    unsigned char *fb;
    const api_attrs *pa;
    api__poly_it it = {0, 0};
    plyextra x;
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
    rc = write_header(out, &x, binary, nv, pa && pa->poly ? pa->npoly : nf);
    for (i = 0; i < nv && rc == MCF_OK; i++)
        rc = binary ? vertex_binary(out, &x, X, i) : vertex_ascii(out, &x, X, i);
    while (rc == MCF_OK && api__poly_next(pa, nf, &it, cs, &pn))
        rc = binary ? face_binary(out, &x, F, cs, pn, fb) : face_ascii(out, &x, F, cs, pn);
    free(cs);
    free(fb);
    extra_free(&x);
    return api__encode_end(out, len0, rc, "ply", nv, "vertices", err);
}
