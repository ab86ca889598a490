/* SPDX-License-Identifier: MIT */
/*
 * api_gltf_decode.c - glTF 2.0 (GLB and .gltf) decoding: the weld that
 * turns a document's triangle primitives into the one surface core
 * smooths, and the side channel the encoder rewrites the document from.
 * The checks before any parser runs are api_gltf_check.c's; tinygltf's
 * reading of the document and its accessors is api_gltf.cc's.
 *
 * The weld: the vertices of all triangle primitives of one mesh (and of
 * meshes that share a POSITION accessor) that sit at bitwise the same
 * position become one vertex, so primitives (material boundaries) and UV
 * or normal seams do not open when the surface moves; triangles that the
 * weld collapses are left out of the flow (they stay in the file). Meshes
 * are smoothed in their own coordinates (node transforms are not applied:
 * a mesh instanced by several nodes is one surface), each mesh a separate
 * component of the one mcf_mesh. Vertices are numbered in order of first
 * appearance. The side channel (api_attrs): normals grouped by (welded
 * vertex, input normal), so a seam whose sides shared a normal keeps one,
 * texture coordinates (v flipped: api_attrs holds OBJ's bottom-up
 * convention) and colours when every primitive has them, each table
 * holding only values some corner uses; and the plan record
 * (api_gltf_plan.c). The encoder writes positions and normals in place, so
 * two accessors it writes may not share bytes (check_overlaps).
 */
#include <stdlib.h>
#include <string.h>

#include "api_internal.h"

/* ------------------------------------------------------------------ weld */

/* One vertex of a primitive, keyed for the weld (and the normal groups). */
typedef struct {
    double k[4];            /* group, x, y, z (or welded vertex, nx, ny, nz) */
    int32_t prim, vert;
} wkey;

static int cmp_wkey(const void *pa, const void *pb)
{
    const wkey *a = pa, *b = pb;
    int c;
    for (c = 0; c < 4; c++)
        if (a->k[c] != b->k[c])
            return a->k[c] < b->k[c] ? -1 : 1;
    if (a->prim != b->prim)
        return a->prim < b->prim ? -1 : 1;
    return (a->vert > b->vert) - (a->vert < b->vert);
}

/* x with -0 as 0, so equal coordinates compare equal. */
static double z0(double x)
{
    return x == 0.0 ? 0.0 : x;
}

/* Union-find over meshes: meshes sharing a plain POSITION accessor weld
 * as one. */
static int root_of(int *up, int i)
{
    while (up[i] != i)
        i = up[i] = up[up[i]];
    return i;
}

/* Sorts keys and numbers their runs (equal k) in order of their first
 * member's (prim, vert) position, ord giving each prim's first global
 * index: run id per key into id (by key index after sorting). Returns the
 * run count, -1 out of memory. */
static long long number_runs(wkey *w, size_t n, const long long *base, int32_t *id)
{
    size_t i, r = 0;
    long long *first;
    size_t *run_of;
    qsort(w, n, sizeof *w, cmp_wkey);
    first = malloc(sizeof *first * (n ? n : 1));
    run_of = malloc(sizeof *run_of * (n ? n : 1));
    if (!first || !run_of) {
        free(first);
        free(run_of);
        return -1;
    }
    for (i = 0; i < n; i++) {
        if (i == 0 || memcmp(w[i].k, w[i - 1].k, sizeof w[i].k) != 0)
            first[r++] = base[w[i].prim] + w[i].vert;
        run_of[i] = r - 1;
    }
    /* rank the runs by their first member (already the smallest (prim,
     * vert) of each run, as the sort's tie-break puts it first) */
    {
        wkey *t = malloc(sizeof *t * (r ? r : 1));
        int32_t *rank = malloc(sizeof *rank * (r ? r : 1));
        size_t j;
        if (!t || !rank) {
            free(t);
            free(rank);
            free(first);
            free(run_of);
            return -1;
        }
        for (j = 0; j < r; j++) {
            memset(&t[j], 0, sizeof t[j]);
            t[j].k[0] = (double)first[j];
            t[j].vert = (int32_t)j;
        }
        qsort(t, r, sizeof *t, cmp_wkey);
        for (j = 0; j < r; j++)
            rank[t[j].vert] = (int32_t)j;
        for (i = 0; i < n; i++)
            id[i] = rank[run_of[i]];
        free(t);
        free(rank);
    }
    free(first);
    free(run_of);
    return (long long)r;
}

/* The weld: each prim's vmap and the positions X of the nv welded
 * vertices (malloc'ed). */
static mcf_status weld(api__gltf_doc *d, double **X, int *nv, long long *base,
                       mcf_error *err)
{
    int nmesh = 0, nacc = 0, p, *up, *owner;
    size_t n = 0, i;
    wkey *w;
    int32_t *id;
    long long r;
    for (p = 0; p < d->nprim; p++) {
        nmesh = d->prim[p].mesh + 1 > nmesh ? d->prim[p].mesh + 1 : nmesh;
        nacc = d->prim[p].pos.acc + 1 > nacc ? d->prim[p].pos.acc + 1 : nacc;
        base[p] = p ? base[p - 1] + d->prim[p - 1].nvert : 0;
    }
    up = malloc(sizeof *up * (size_t)(nmesh + nacc));
    if (!up)
        return api__fail(err, MCF_ENOMEM, "gltf: out of memory");
    owner = up + nmesh; /* a plain POSITION accessor's first mesh */
    for (p = 0; p < nmesh; p++)
        up[p] = p;
    for (p = 0; p < nacc; p++)
        owner[p] = -1;
    for (p = 0; p < d->nprim; p++) {
        const api__gltf_prim *g = &d->prim[p];
        if (g->draco_view < 0 && g->pos.acc >= 0) {
            if (owner[g->pos.acc] < 0)
                owner[g->pos.acc] = g->mesh;
            else
                up[root_of(up, g->mesh)] = root_of(up, owner[g->pos.acc]);
        }
        if (!(d->prim[p].vmap = malloc(sizeof(int32_t) * (size_t)d->prim[p].nvert + 1))) {
            free(up);
            return api__fail(err, MCF_ENOMEM, "gltf: out of memory");
        }
        for (i = 0; i < (size_t)d->prim[p].nvert; i++)
            d->prim[p].vmap[i] = -1;
        for (i = 0; i < 3 * (size_t)d->prim[p].ntri; i++)
            if (d->prim[p].vmap[d->prim[p].tri[i]] == -1) {
                d->prim[p].vmap[d->prim[p].tri[i]] = -2; /* in a triangle */
                n++;
            }
    }
    w = malloc(sizeof *w * (n ? n : 1));
    id = malloc(sizeof *id * (n ? n : 1));
    if (!w || !id) {
        free(up);
        free(w);
        free(id);
        return api__fail(err, MCF_ENOMEM, "gltf: out of memory welding %zu vertices", n);
    }
    for (i = 0, p = 0; p < d->nprim; p++) {
        const api__gltf_prim *g = &d->prim[p];
        int v;
        for (v = 0; v < g->nvert; v++)
            if (g->vmap[v] == -2) {
                const double *x = g->xyz + 3 * (size_t)v;
                w[i].k[0] = root_of(up, g->mesh);
                w[i].k[1] = z0(x[0]);
                w[i].k[2] = z0(x[1]);
                w[i].k[3] = z0(x[2]);
                w[i].prim = p;
                w[i++].vert = v;
            }
    }
    free(up);
    r = number_runs(w, n, base, id);
    if (r < 0) {
        free(w);
        free(id);
        return api__fail(err, MCF_ENOMEM, "gltf: out of memory welding");
    }
    *X = malloc(3 * sizeof **X * (size_t)(r ? r : 1));
    if (!*X) {
        free(w);
        free(id);
        return api__fail(err, MCF_ENOMEM, "gltf: out of memory");
    }
    for (i = 0; i < n; i++) {
        d->prim[w[i].prim].vmap[w[i].vert] = id[i];
        memcpy(*X + 3 * (size_t)id[i], w[i].k + 1, 3 * sizeof(double));
    }
    free(w);
    free(id);
    *nv = (int)r;
    return MCF_OK;
}

/* Normal groups: (welded vertex, input normal) -> one value; *ngroups
 * values in N (malloc'ed). Prims without normals keep ngroup NULL. */
static mcf_status normal_groups(api__gltf_doc *d, const long long *base,
                                double **N, int *ngroups, mcf_error *err)
{
    size_t n = 0, i;
    int p;
    wkey *w;
    int32_t *id;
    long long r;
    for (p = 0; p < d->nprim; p++)
        if (d->prim[p].nxyz) {
            int v;
            if (!(d->prim[p].ngroup = malloc(sizeof(int32_t) * (size_t)d->prim[p].nvert + 1)))
                return api__fail(err, MCF_ENOMEM, "gltf: out of memory");
            for (v = 0; v < d->prim[p].nvert; v++) {
                d->prim[p].ngroup[v] = -1;
                n += d->prim[p].vmap[v] >= 0;
            }
        }
    w = malloc(sizeof *w * (n ? n : 1));
    id = malloc(sizeof *id * (n ? n : 1));
    if (!w || !id) {
        free(w);
        free(id);
        return api__fail(err, MCF_ENOMEM, "gltf: out of memory");
    }
    for (i = 0, p = 0; p < d->nprim; p++) {
        const api__gltf_prim *g = &d->prim[p];
        int v;
        for (v = 0; g->nxyz && v < g->nvert; v++)
            if (g->vmap[v] >= 0) {
                w[i].k[0] = g->vmap[v];
                w[i].k[1] = z0(g->nxyz[3 * (size_t)v]);
                w[i].k[2] = z0(g->nxyz[3 * (size_t)v + 1]);
                w[i].k[3] = z0(g->nxyz[3 * (size_t)v + 2]);
                w[i].prim = p;
                w[i++].vert = v;
            }
    }
    r = number_runs(w, n, base, id);
    *N = r >= 0 ? malloc(3 * sizeof **N * (size_t)(r ? r : 1)) : NULL;
    if (!*N) {
        free(w);
        free(id);
        return api__fail(err, MCF_ENOMEM, "gltf: out of memory");
    }
    for (i = 0; i < n; i++) {
        d->prim[w[i].prim].ngroup[w[i].vert] = id[i];
        memcpy(*N + 3 * (size_t)id[i], w[i].k + 1, 3 * sizeof(double));
    }
    free(w);
    free(id);
    *ngroups = (int)r;
    return MCF_OK;
}

/* The faces of the flow (welded, collapsed triangles left out) and, per
 * face corner, its primitive and vertex. */
static mcf_status faces(const api__gltf_doc *d, int32_t **F, int32_t **cp,
                        int32_t **cv, int *nf, mcf_error *err)
{
    size_t n = 0, t;
    int p, k;
    for (p = 0; p < d->nprim; p++)
        n += (size_t)d->prim[p].ntri;
    *F = malloc(3 * sizeof **F * (n ? n : 1));
    *cp = malloc(3 * sizeof **cp * (n ? n : 1));
    *cv = malloc(3 * sizeof **cv * (n ? n : 1));
    if (!*F || !*cp || !*cv)
        return api__fail(err, MCF_ENOMEM, "gltf: out of memory for %zu faces", n);
    *nf = 0;
    for (p = 0; p < d->nprim; p++) {
        const api__gltf_prim *g = &d->prim[p];
        for (t = 0; t < (size_t)g->ntri; t++) {
            const int32_t *c = g->tri + 3 * t;
            int32_t a = g->vmap[c[0]], b = g->vmap[c[1]], e = g->vmap[c[2]];
            if (a == b || b == e || a == e)
                continue;
            for (k = 0; k < 3; k++) {
                (*F)[3 * (size_t)*nf + k] = g->vmap[c[k]];
                (*cp)[3 * (size_t)*nf + k] = p;
                (*cv)[3 * (size_t)*nf + k] = c[k];
            }
            (*nf)++;
        }
    }
    if (*nf == 0)
        return api__fail(err, MCF_EDECODE, "gltf: every triangle is degenerate");
    return MCF_OK;
}

/* Keeps only the values of at that some corner uses (at most one per
 * corner, as every decoder's attributes), renumbering the corners; *kept
 * (when not NULL) the old -> new map (-1: dropped), malloc'ed. */
static mcf_status keep_used(api__attr *at, size_t ncorners, int32_t **kept,
                            mcf_error *err)
{
    int32_t *map = malloc(sizeof *map * (size_t)(at->nvalues ? at->nvalues : 1));
    int i, n = 0;
    size_t c;
    if (!map)
        return api__fail(err, MCF_ENOMEM, "gltf: out of memory");
    for (i = 0; i < at->nvalues; i++)
        map[i] = -1;
    for (c = 0; c < ncorners; c++)
        if (map[at->corners[c]] < 0)
            map[at->corners[c]] = 0;
    for (i = 0; i < at->nvalues; i++)
        if (map[i] == 0) {
            memmove(at->values + (size_t)n * at->ncomp, at->values + (size_t)i * at->ncomp,
                    sizeof *at->values * (size_t)at->ncomp);
            map[i] = n++;
        }
    for (c = 0; c < ncorners; c++)
        at->corners[c] = map[at->corners[c]];
    at->nvalues = n;
    if (kept)
        *kept = map;
    else
        free(map);
    return MCF_OK;
}

/* Texture coordinates (k = API_ATTR_TEXCOORD) or colours into a when
 * every primitive has them: one value per primitive vertex, deduplicated. */
static mcf_status side_attr(const api__gltf_doc *d, api_attrs *a, api_attr_kind k,
                            const int32_t *cp, const int32_t *cv, const long long *base,
                            mcf_error *err)
{
    int nc = k == API_ATTR_TEXCOORD ? 2 : 3, p;
    size_t nvals = 0, i, nf3 = 3 * (size_t)a->nf;
    double *vals;
    int32_t *corners;
    mcf_status rc;
    for (p = 0; p < d->nprim; p++) {
        const double *src = k == API_ATTR_TEXCOORD ? d->prim[p].uv : d->prim[p].rgba;
        if (!src)
            return MCF_OK;
        for (i = 0; k == API_ATTR_COLOR && i < (size_t)d->prim[p].nvert; i++)
            if (src[4 * i + 3] != 1.0)
                nc = 4;
        nvals += (size_t)d->prim[p].nvert;
    }
    vals = malloc(sizeof *vals * (size_t)nc * nvals + 1);
    corners = malloc(sizeof *corners * nf3 + 1);
    if (!vals || !corners) {
        free(vals);
        free(corners);
        return api__fail(err, MCF_ENOMEM, "gltf: out of memory");
    }
    for (p = 0; p < d->nprim; p++) {
        const api__gltf_prim *g = &d->prim[p];
        for (i = 0; i < (size_t)g->nvert; i++) {
            double *o = vals + (size_t)nc * (size_t)(base[p] + (long long)i);
            if (k == API_ATTR_TEXCOORD) {
                o[0] = g->uv[2 * i];
                o[1] = 1.0 - g->uv[2 * i + 1]; /* glTF's v runs top-down */
            } else {
                memcpy(o, g->rgba + 4 * i, sizeof *o * (size_t)nc);
            }
        }
    }
    for (i = 0; i < nf3; i++)
        corners[i] = (int32_t)(base[cp[i]] + cv[i]);
    rc = api__attrs_take(a, k, nc, (int)nvals, vals, corners, err);
    if (rc == MCF_OK)
        rc = keep_used(&a->a[k], nf3, NULL, err);
    return rc == MCF_OK ? api__attr_dedupe(&a->a[k], nf3, err) : rc;
}

/* The normal attribute: the groups' input normals; corners of primitives
 * without normals get a value per welded vertex after them. */
static mcf_status side_normals(api__gltf_doc *d, api_attrs *a, double *N,
                               int ngroups, const int32_t *F, const int32_t *cp,
                               const int32_t *cv, mcf_error *err)
{
    size_t i, nf3 = 3 * (size_t)a->nf;
    int32_t *corners = malloc(sizeof *corners * nf3 + 1);
    double *vals = realloc(N, 3 * sizeof *vals * ((size_t)ngroups + (size_t)a->nv));
    if (!corners || !vals) {
        free(corners);
        free(vals ? vals : N);
        return api__fail(err, MCF_ENOMEM, "gltf: out of memory");
    }
    for (i = 0; i < (size_t)a->nv; i++) {
        double *o = vals + 3 * ((size_t)ngroups + i);
        o[0] = o[1] = 0.0;
        o[2] = 1.0;
    }
    for (i = 0; i < nf3; i++) {
        const int32_t *ng = d->prim[cp[i]].ngroup;
        corners[i] = ng ? ng[cv[i]] : ngroups + F[i];
    }
    {
        int32_t *map;
        int p;
        mcf_status rc = api__attrs_take(a, API_ATTR_NORMAL, 3, ngroups + a->nv, vals,
                                        corners, err);
        if (rc != MCF_OK || (rc = keep_used(&a->a[API_ATTR_NORMAL], nf3, &map, err)) != MCF_OK)
            return rc;
        /* the primitives' groups follow (-1: only in collapsed triangles) */
        for (p = 0; p < d->nprim; p++)
            for (i = 0; d->prim[p].ngroup && i < (size_t)d->prim[p].nvert; i++)
                if (d->prim[p].ngroup[i] >= 0)
                    d->prim[p].ngroup[i] = map[d->prim[p].ngroup[i]];
        free(map);
        return MCF_OK;
    }
}

/* A byte region the encoder writes: VEC3 floats of one accessor. */
typedef struct {
    long long lo, hi, off;      /* span [lo, hi), first element at off */
    int buf, stride, acc;
} region;

static int cmp_region(const void *pa, const void *pb)
{
    const region *a = pa, *b = pb;
    if (a->buf != b->buf)
        return a->buf < b->buf ? -1 : 1;
    return (a->lo > b->lo) - (a->lo < b->lo);
}

/* The encoder writes positions and normals in place: two accessors it
 * writes must not share a byte (one would overwrite the other), unless
 * they interleave in the same stride. A shared accessor is one region. */
static mcf_status check_overlaps(const api__gltf_doc *d, mcf_error *err)
{
    region *r = malloc(sizeof *r * (2 * (size_t)d->nprim + 1));
    int n = 0, i, j, p, k;
    if (!r)
        return api__fail(err, MCF_ENOMEM, "gltf: out of memory");
    for (p = 0; p < d->nprim; p++)
        for (k = 0; k < 2; k++) {
            const api__gltf_at *at = k ? &d->prim[p].nrm : &d->prim[p].pos;
            if (at->buf < 0)
                continue;
            r[n].buf = at->buf;
            r[n].off = r[n].lo = at->off;
            r[n].hi = at->off + (long long)at->stride * (d->prim[p].nvert - 1) + 12;
            r[n].stride = at->stride;
            r[n++].acc = at->acc;
        }
    qsort(r, (size_t)n, sizeof *r, cmp_region);
    for (i = 0; i < n; i++)
        for (j = i + 1; j < n && r[j].buf == r[i].buf && r[j].lo < r[i].hi; j++) {
            long long gap = (r[j].off - r[i].off) % r[i].stride;
            if (r[j].acc == r[i].acc && r[j].off == r[i].off)
                continue;
            if (r[j].acc != r[i].acc && r[j].stride == r[i].stride && gap >= 12 &&
                gap <= r[i].stride - 12)
                continue; /* interleaved */
            {
                const int a = r[i].acc, b = r[j].acc, buf = r[i].buf;
                free(r);
                return api__fail(err, MCF_EDECODE,
                                 "gltf: accessors %d and %d (POSITION or NORMAL) share "
                                 "bytes of buffer %d; each needs its own to be written "
                                 "back", a, b, buf);
            }
        }
    free(r);
    return MCF_OK;
}

static mcf_status decode_doc(api__gltf_doc *d, const api_limits *lim,
                             mcf_mesh **out, api_attrs **attrs, mcf_error *err)
{
    double *X = NULL, *N = NULL;
    int32_t *F = NULL, *cp = NULL, *cv = NULL;
    long long *base = malloc(sizeof *base * (size_t)d->nprim);
    int nv = 0, nf = 0, ng = 0, p, has_n = 0;
    mcf_mesh *m = NULL;
    api_attrs *a = NULL;
    api_buf plan;
    mcf_status rc;

    api_buf_init(&plan, API_GLTF_RECORD_MAX(lim));
    if (!base)
        return api__fail(err, MCF_ENOMEM, "gltf: out of memory");
    if ((rc = check_overlaps(d, err)) != MCF_OK || (rc = weld(d, &X, &nv, base, err)) != MCF_OK ||
        (rc = faces(d, &F, &cp, &cv, &nf, err)) != MCF_OK)
        goto done;
    if (nv > lim->max_vertices || nf > lim->max_faces) {
        rc = api__fail(err, MCF_ELIMIT, "gltf: %d vertices and %d faces exceed "
                       "max_vertices (%d) or max_faces (%d)", nv, nf,
                       lim->max_vertices, lim->max_faces);
        goto done;
    }
    for (p = 0; p < d->nprim; p++)
        has_n |= d->prim[p].nxyz != NULL;
    if ((rc = api__mesh_new(nv, X, nf, F, &m, err)) != MCF_OK)
        goto done;
    if (!(a = api_attrs_new(nv, nf))) {
        rc = api__fail(err, MCF_ENOMEM, "gltf: out of memory");
        goto done;
    }
    a->float32 = 1;
    for (p = 0; p < d->nprim && a->pos_bits < 0; p++)
        if (d->prim[p].draco_view >= 0)
            a->pos_bits = d->prim[p].draco.attr[d->prim[p].draco_pos].bits;
    if (has_n) {
        if ((rc = normal_groups(d, base, &N, &ng, err)) != MCF_OK)
            goto done;
        rc = side_normals(d, a, N, ng, F, cp, cv, err);
        N = NULL; /* taken (or freed) */
        if (rc != MCF_OK)
            goto done;
    }
    if ((rc = side_attr(d, a, API_ATTR_TEXCOORD, cp, cv, base, err)) != MCF_OK ||
        (rc = side_attr(d, a, API_ATTR_COLOR, cp, cv, base, err)) != MCF_OK ||
        (rc = api__gltf_plan(d, &plan, err)) != MCF_OK)
        goto done;
    a->gltf = (unsigned char *)api_buf_detach(&plan, &a->gltf_len);
    *out = m;
    m = NULL;
    if (attrs) {
        *attrs = a;
        a = NULL;
    }
done:
    free(base);
    free(X);
    free(N);
    free(F);
    free(cp);
    free(cv);
    api_buf_free(&plan);
    mcf_mesh_free(m);
    api_attrs_free(a);
    return rc;
}

mcf_status api_gltf_decode_attrs(const void *buf, size_t len, const api_limits *lim,
                                 mcf_mesh **out, api_attrs **attrs, mcf_error *err)
{
    api_limits def;
    api__gltf_doc d;
    const char *json = buf;
    char *tiny = NULL;
    size_t json_len = len, tiny_len = 0;
    mcf_status rc = api__decode_begin("gltf", buf, len, &lim, &def, err);
    if (rc != MCF_OK)
        return rc;
    memset(&d, 0, sizeof d);
    d.container = len >= 4 && memcmp(buf, "glTF", 4) == 0 ? API_FMT_GLB : API_FMT_GLTF;
    if (d.container == API_FMT_GLB) {
        const unsigned char *bin;
        size_t bin_len;
        if ((rc = api__glb_split(buf, len, &json, &json_len, &bin, &bin_len, err)) != MCF_OK)
            return rc;
    }
    if ((rc = api__gltf_check_json(buf, len, json, json_len, d.container == API_FMT_GLB, &tiny,
                         &tiny_len, err)) == MCF_OK &&
        (rc = api__gltf_parse(tiny ? tiny : buf, tiny ? tiny_len : len, json, json_len,
                              lim, &d, err)) == MCF_OK)
        rc = decode_doc(&d, lim, out, attrs, err);
    free(tiny);
    api__gltf_doc_free(&d);
    return rc;
}
