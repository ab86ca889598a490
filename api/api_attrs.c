/* SPDX-License-Identifier: MIT */
/*
 * api_attrs.c - the attribute side channel (api.h, "attributes"): texture
 * coordinates, colours and normals that travel from a decoder to an
 * encoder next to the core's pure-geometry mcf_mesh.
 *
 * Every attribute is stored per face corner (a value table plus 3*nf value
 * indices), the one layout that holds OBJ's per-corner vt/vn, Draco's
 * point-mapped attributes and PLY's per-vertex properties alike. Smoothing
 * moves vertices only, so the corner layout stays valid for the smoothed
 * mesh; normals alone are recomputed (api__attrs_normals), grouped as the
 * input grouped them, so a crease whose corners carried distinct normals
 * stays a crease. Small and not tuned: one pass over the corners per call.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "api_internal.h"

static const char *const kind_names[] = {"normal", "texcoord", "colour"};

api_attrs *api_attrs_new(int nv, int nf)
{
    api_attrs *a;
    int k;
    if (nv < 0 || nf < 0)
        return NULL;
    a = calloc(1, sizeof *a);
    if (!a)
        return NULL;
    a->nv = nv;
    a->nf = nf;
    a->pos_bits = -1;
    for (k = 0; k < API_ATTR_KINDS; k++)
        a->a[k].bits = -1;
    return a;
}

static void attr_clear(api__attr *at)
{
    free(at->values);
    free(at->corners);
    memset(at, 0, sizeof *at);
    at->bits = -1;
}

void api_attrs_free(api_attrs *a)
{
    int k;
    if (!a)
        return;
    for (k = 0; k < API_ATTR_KINDS; k++)
        attr_clear(&a->a[k]);
    free(a->gltf);
    free(a->poly);
    for (k = 0; k < a->nstmt; k++)
        free(a->stmt[k].text);
    free(a->stmt);
    for (k = 0; k < a->nscal; k++) {
        free(a->scal[k].name);
        free(a->scal[k].values);
    }
    free(a->scal);
    free(a->not_kept);
    free(a);
}

/* The checks of api_attrs_set, on the arrays it is about to store. */
static mcf_status check_attr(const api_attrs *a, api_attr_kind k, int ncomp,
                             int nvalues, const double *values,
                             const int32_t *corners, mcf_error *err)
{
    long long i, n;
    if (!a || (unsigned)k >= API_ATTR_KINDS)
        return api__fail(err, MCF_EINVAL, "attributes: bad handle or kind");
    if (ncomp != (k == API_ATTR_TEXCOORD ? 2 : 3)
        && !(k == API_ATTR_COLOR && ncomp == 4))
        return api__fail(err, MCF_EINVAL, "attributes: %s with %d components",
                         kind_names[k], ncomp);
    if (nvalues < 0 || (nvalues > 0 && !values))
        return api__fail(err, MCF_EINVAL, "attributes: %s: %d values",
                         kind_names[k], nvalues);
    if (!corners)
        return api__fail(err, MCF_EINVAL, "attributes: %s without corner indices",
                         kind_names[k]);
    n = 3LL * a->nf;
    if (corners)
        for (i = 0; i < n; i++)
            if (corners[i] < 0 || corners[i] >= nvalues)
                return api__fail(err, MCF_EINVAL,
                                 "attributes: %s of corner %lld is value %ld of %d",
                                 kind_names[k], i, (long)corners[i], nvalues);
    for (i = 0; i < (long long)nvalues * ncomp; i++)
        if (!isfinite(values[i]))
            return api__fail(err, MCF_EINVAL,
                             "attributes: %s value %lld is not finite",
                             kind_names[k], i / ncomp);
    return MCF_OK;
}

mcf_status api__attrs_take(api_attrs *a, api_attr_kind k, int ncomp,
                           int nvalues, double *values, int32_t *corners,
                           mcf_error *err)
{
    mcf_status rc = check_attr(a, k, ncomp, nvalues, values, corners, err);
    if (rc != MCF_OK) {
        free(values);
        free(corners);
        return rc;
    }
    attr_clear(&a->a[k]);
    a->a[k].ncomp = ncomp;
    a->a[k].nvalues = nvalues;
    a->a[k].values = values;
    a->a[k].corners = corners;
    return MCF_OK;
}

mcf_status api_attrs_set(api_attrs *a, api_attr_kind k, int ncomp,
                         int nvalues, const double *values,
                         const int32_t *corners, mcf_error *err)
{
    double *v;
    int32_t *c;
    size_t nc, nvv;
    mcf_status rc = check_attr(a, k, ncomp, nvalues, values, corners, err);
    if (rc != MCF_OK)
        return rc;
    nc = 3 * (size_t)a->nf;
    nvv = (size_t)nvalues * (size_t)ncomp;
    v = malloc(sizeof *v * (nvv ? nvv : 1));
    c = malloc(sizeof *c * (nc ? nc : 1));
    if (!v || !c) {
        free(v);
        free(c);
        return api__fail(err, MCF_ENOMEM, "attributes: out of memory");
    }
    if (nvv)
        memcpy(v, values, sizeof *v * nvv);
    if (nc)
        memcpy(c, corners, sizeof *c * nc);
    return api__attrs_take(a, k, ncomp, nvalues, v, c, err);
}

int api_attrs_get(const api_attrs *a, api_attr_kind k, int *ncomp,
                  int *nvalues, const double **values, const int32_t **corners)
{
    const api__attr *at;
    if (!a || (unsigned)k >= API_ATTR_KINDS || !a->a[k].corners)
        return 0;
    at = &a->a[k];
    if (ncomp)
        *ncomp = at->ncomp;
    if (nvalues)
        *nvalues = at->nvalues;
    if (values)
        *values = at->values;
    if (corners)
        *corners = at->corners;
    return 1;
}

int api_attrs_float32(const api_attrs *a)
{
    return a ? a->float32 : 0;
}

int api_attrs_draco_bits(const api_attrs *a, int k)
{
    if (!a)
        return -1;
    if (k == API_ATTR_POSITION)
        return a->pos_bits;
    if (k < 0 || k >= API_ATTR_KINDS || !a->a[k].corners)
        return -1;
    return a->a[k].bits;
}

mcf_status api__attrs_check(const api_attrs *a, const mcf_mesh *m,
                            const char *codec, mcf_error *err)
{
    if (!a)
        return MCF_OK;
    if (a->nv != mcf_mesh_nvertices(m) || a->nf != mcf_mesh_nfaces(m))
        return api__fail(err, MCF_EINVAL,
                         "%s: the attributes belong to a mesh of %d vertices and "
                         "%d faces, this one has %d and %d",
                         codec, a->nv, a->nf, mcf_mesh_nvertices(m),
                         mcf_mesh_nfaces(m));
    return MCF_OK;
}

/* Twice the area-weighted normal of triangle f (the cross product). */
static void face_normal(const double *X, const int32_t *t, double n[3])
{
    const double *p = X + 3 * (size_t)t[0], *q = X + 3 * (size_t)t[1],
                 *r = X + 3 * (size_t)t[2];
    double u[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]};
    double v[3] = {r[0] - p[0], r[1] - p[1], r[2] - p[2]};
    n[0] = u[1] * v[2] - u[2] * v[1];
    n[1] = u[2] * v[0] - u[0] * v[2];
    n[2] = u[0] * v[1] - u[1] * v[0];
}

static void normalize_all(double *N, size_t n)
{
    size_t i;
    for (i = 0; i < n; i++) {
        double *v = N + 3 * i, l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        if (l > 0 && isfinite(l)) {
            v[0] /= l;
            v[1] /= l;
            v[2] /= l;
        } else {
            v[0] = v[1] = 0;
            v[2] = 1;
        }
    }
}

mcf_status api__attrs_normals(const api_attrs *a, const mcf_mesh *m,
                              double **N, mcf_error *err)
{
    const api__attr *at = &a->a[API_ATTR_NORMAL];
    const double *X = mcf_mesh_positions(m);
    const int32_t *F = mcf_mesh_faces(m);
    int nf = mcf_mesh_nfaces(m), f, k;
    double *out = calloc((size_t)(at->nvalues ? at->nvalues : 1), 3 * sizeof *out);
    if (!out)
        return api__fail(err, MCF_ENOMEM, "normals: out of memory for %d values",
                         at->nvalues);
    for (f = 0; f < nf; f++) {
        double n[3];
        face_normal(X, F + 3 * (size_t)f, n);
        for (k = 0; k < 3; k++) {
            double *o = out + 3 * (size_t)at->corners[3 * (size_t)f + k];
            o[0] += n[0];
            o[1] += n[1];
            o[2] += n[2];
        }
    }
    normalize_all(out, (size_t)at->nvalues);
    *N = out;
    return MCF_OK;
}

void api__vertex_normals(const mcf_mesh *m, double *N)
{
    const double *X = mcf_mesh_positions(m);
    const int32_t *F = mcf_mesh_faces(m);
    int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m), f, k;
    memset(N, 0, 3 * sizeof *N * (size_t)nv);
    for (f = 0; f < nf; f++) {
        double n[3];
        face_normal(X, F + 3 * (size_t)f, n);
        for (k = 0; k < 3; k++) {
            double *o = N + 3 * (size_t)F[3 * (size_t)f + k];
            o[0] += n[0];
            o[1] += n[1];
            o[2] += n[2];
        }
    }
    normalize_all(N, (size_t)nv);
}

int api__attr_per_vertex(const api__attr *at, const mcf_mesh *m, double *out)
{
    const int32_t *F = mcf_mesh_faces(m);
    int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m), f, k, c;
    int32_t *first = malloc(sizeof *first * (size_t)(nv ? nv : 1));
    int ok = first != NULL;
    for (f = 0; ok && f < nv; f++)
        first[f] = -1;
    memset(out, 0, sizeof *out * (size_t)nv * (size_t)at->ncomp);
    for (f = 0; ok && f < nf; f++)
        for (k = 0; ok && k < 3; k++) {
            int32_t v = F[3 * (size_t)f + k], val = at->corners[3 * (size_t)f + k];
            if (first[v] < 0) {
                first[v] = val;
                memcpy(out + (size_t)v * at->ncomp,
                       at->values + (size_t)val * at->ncomp,
                       sizeof *out * (size_t)at->ncomp);
            } else if (first[v] != val) {
                for (c = 0; c < at->ncomp; c++)
                    if (at->values[(size_t)val * at->ncomp + c]
                        != at->values[(size_t)first[v] * at->ncomp + c])
                        ok = 0;
            }
        }
    free(first);
    return ok;
}

/* A value and where it was, for api__attr_dedupe's sort. */
typedef struct {
    double v[4];
    int32_t idx;
} keyed;

static int cmp_keyed(const void *pa, const void *pb)
{
    const keyed *a = pa, *b = pb;
    int c;
    for (c = 0; c < 4; c++)
        if (a->v[c] != b->v[c])
            return a->v[c] < b->v[c] ? -1 : 1;
    return (a->idx > b->idx) - (a->idx < b->idx);
}

mcf_status api__attr_dedupe(api__attr *at, size_t ncorners, mcf_error *err)
{
    int n = at->nvalues, nc = at->ncomp, i, c, m = 0;
    keyed *k = malloc(sizeof *k * (size_t)(n ? n : 1));
    int32_t *map = malloc(sizeof *map * (size_t)(n ? n : 1));
    size_t j;
    if (!k || !map) {
        free(k);
        free(map);
        return api__fail(err, MCF_ENOMEM, "attributes: out of memory");
    }
    for (i = 0; i < n; i++) {
        memset(k[i].v, 0, sizeof k[i].v);
        for (c = 0; c < nc; c++)
            k[i].v[c] = at->values[(size_t)i * nc + c];
        k[i].idx = i;
    }
    qsort(k, (size_t)n, sizeof *k, cmp_keyed);
    /* Values in sorted order, equal ones once; map: old -> new index. */
    for (i = 0; i < n; i++) {
        if (i == 0 || memcmp(k[i].v, k[i - 1].v, sizeof k[i].v) != 0) {
            for (c = 0; c < nc; c++)
                at->values[(size_t)m * nc + c] = k[i].v[c];
            m++;
        }
        map[k[i].idx] = m - 1;
    }
    for (j = 0; j < ncorners; j++)
        at->corners[j] = map[at->corners[j]];
    at->nvalues = m;
    free(k);
    free(map);
    return MCF_OK;
}

/* ------------------------------------------------ polygons and statements */

mcf_status api__attrs_polys(api_attrs *a, const int32_t *sizes, int npoly,
                            mcf_error *err)
{
    long long tri = 0;
    int p, max = 3;
    for (p = 0; p < npoly; p++) {
        if (sizes[p] < 3)
            return api__fail(err, MCF_EINVAL, "attributes: polygon %d of %d corners", p,
                             (int)sizes[p]);
        tri += sizes[p] - 2;
        max = sizes[p] > max ? sizes[p] : max;
    }
    if (tri != a->nf)
        return api__fail(err, MCF_EINVAL,
                         "attributes: %d polygons make %lld triangles, the mesh has %d",
                         npoly, tri, a->nf);
    free(a->poly);
    a->poly = NULL;
    a->npoly = npoly;
    a->maxpoly = max;
    if (max == 3)
        return MCF_OK; /* triangles: nothing to keep */
    if (!(a->poly = malloc(sizeof *a->poly * (size_t)npoly)))
        return api__fail(err, MCF_ENOMEM, "attributes: out of memory for %d polygons",
                         npoly);
    memcpy(a->poly, sizes, sizeof *a->poly * (size_t)npoly);
    return MCF_OK;
}

/* n bytes of s as a new NUL-terminated string; NULL on allocation failure. */
static char *copy_text(const char *s, size_t n)
{
    char *t = malloc(n + 1);
    if (t) {
        memcpy(t, s, n);
        t[n] = '\0';
    }
    return t;
}

mcf_status api__attrs_stmt(api_attrs *a, int32_t at, const char *s, size_t n,
                           mcf_error *err)
{
    char *t = copy_text(s, n);
    api__stmt *st = realloc(a->stmt, sizeof *st * ((size_t)a->nstmt + 1));
    if (st)
        a->stmt = st;
    if (!t || !st) {
        free(t);
        return api__fail(err, MCF_ENOMEM, "attributes: out of memory for statements");
    }
    a->stmt[a->nstmt].at = at;
    a->stmt[a->nstmt++].text = t;
    return MCF_OK;
}

/* ------------------------------------ pass-through scalars, what is not kept */

mcf_status api__attrs_scalar(api_attrs *a, const char *name, size_t n, int type,
                             double *values, mcf_error *err)
{
    char *t = copy_text(name, n);
    api__scalar *sc = realloc(a->scal, sizeof *sc * ((size_t)a->nscal + 1));
    if (sc)
        a->scal = sc;
    if (!t || !sc) {
        free(t);
        free(values);
        return api__fail(err, MCF_ENOMEM, "attributes: out of memory for a property");
    }
    a->scal[a->nscal].name = t;
    a->scal[a->nscal].type = type;
    a->scal[a->nscal++].values = values;
    return MCF_OK;
}

mcf_status api__attrs_drop(api_attrs *a, const char *what, size_t n, mcf_error *err)
{
    size_t old = a->not_kept ? strlen(a->not_kept) : 0;
    char *t = realloc(a->not_kept, old + n + 3);
    if (!t)
        return api__fail(err, MCF_ENOMEM, "attributes: out of memory");
    if (old) {
        memcpy(t + old, ", ", 2);
        old += 2;
    }
    memcpy(t + old, what, n);
    t[old + n] = '\0';
    a->not_kept = t;
    a->nnot_kept++;
    return MCF_OK;
}

/* Appends "<sep><what>" to buf (n bytes) at *len, truncating. */
static void put_item(char *buf, size_t n, size_t *len, const char *what, const char *name)
{
    int w;
    if (*len >= n)
        return;
    w = snprintf(buf + *len, n - *len, "%s%s%s", *len ? ", " : "", what, name);
    *len = w < 0 ? n : *len + (size_t)w;
}

int api_attrs_not_kept(const api_attrs *a, api_format out, char *buf, size_t n)
{
    size_t len = 0;
    int k, count = 0;
    if (n)
        buf[0] = '\0';
    if (!a)
        return 0;
    for (k = 0; out != API_FMT_PLY && k < a->nscal; k++, count++)
        put_item(buf, n, &len, "vertex ", a->scal[k].name);
    if (a->not_kept) {
        put_item(buf, n, &len, "", a->not_kept);
        count += a->nnot_kept;
    }
    if (len >= n && n >= 4)
        memcpy(buf + n - 4, "...", 4);
    return count;
}

int api__attrs_maxpoly(const api_attrs *a)
{
    return a && a->poly ? a->maxpoly : 3;
}

int api__poly_next(const api_attrs *a, int nf, api__poly_it *it, size_t *c, int *n)
{
    int k, f = it->face;
    int size = a && a->poly ? (it->p < a->npoly ? a->poly[it->p] : 0) : 3;
    if (size < 3 || f + size - 2 > nf)
        return 0;
    /* the fan (c0, ck, ck+1): its first face gives corners 0 and 1, every
     * face its last */
    c[0] = 3 * (size_t)f;
    c[1] = 3 * (size_t)f + 1;
    for (k = 0; k < size - 2; k++)
        c[k + 2] = 3 * (size_t)(f + k) + 2;
    *n = size;
    it->face = f + size - 2;
    it->p++;
    return 1;
}
