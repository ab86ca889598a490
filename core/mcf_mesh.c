/* SPDX-License-Identifier: MIT */
/*
 * mcf_mesh.c - the mesh object of libmcf: construction with validation of
 * what would make arithmetic unsafe (indices, non-finite coordinates),
 * an exact topological/geometric inspection, area, volume and
 * deterministic normal noise (icospheres: mcf_icosphere.c).
 *
 * A mesh owns two flat arrays: 3*nv doubles and 3*nf int32 indices. Only
 * what would corrupt memory or poison every later computation is refused;
 * everything else a real scan contains (degenerate, duplicate and
 * non-manifold faces, unreferenced vertices, holes) is accepted and counted
 * by mcf_mesh_inspect(), which sorts the 3*nf half-edges once: O(nf log nf)
 * time, about 80 bytes per face of scratch.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_internal.h"

/* Bit-identical results across platforms for icospheres and noise: no fused
 * multiply-add contraction. GCC already does none in ISO C mode
 * (-std=c11); clang contracts within expressions unless told not to. */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

/* ------------------------------------------------------------ lifecycle */

mcf_mesh *mcf_mesh_new(int nv, const double *X, int nf, const int32_t *F,
                       mcf_error *err)
{
    mcf_mesh *m;
    size_t i, n;

    if (nv <= 0) {
        mcf__fail(err, MCF_EMESH, "mesh has %d vertices (need at least 1)", nv);
        return NULL;
    }
    if (nf <= 0) {
        mcf__fail(err, MCF_EMESH, "mesh has %d faces (need at least 1)", nf);
        return NULL;
    }
    if (!X || !F) {
        mcf__fail(err, MCF_EINVAL, "mesh arrays are NULL");
        return NULL;
    }
    n = 3 * (size_t)nv;
    for (i = 0; i < n; i++) {
        if (!isfinite(X[i])) {
            mcf__fail(err, MCF_EMESH, "vertex %zu: coordinate %c is %g",
                      i / 3, "xyz"[i % 3], X[i]);
            return NULL;
        }
    }
    n = 3 * (size_t)nf;
    for (i = 0; i < n; i++) {
        if (F[i] < 0 || F[i] >= nv) {
            mcf__fail(err, MCF_EMESH,
                      "face %zu: vertex index %ld out of range [0, %d)",
                      i / 3, (long)F[i], nv);
            return NULL;
        }
    }
    m = malloc(sizeof *m);
    if (!m) {
        mcf__fail(err, MCF_ENOMEM, "mesh of %d vertices", nv);
        return NULL;
    }
    m->nv = nv;
    m->nf = nf;
    m->X = mcf__malloc(3 * (size_t)nv, sizeof *m->X);
    m->F = mcf__malloc(3 * (size_t)nf, sizeof *m->F);
    if (!m->X || !m->F) {
        mcf_mesh_free(m);
        mcf__fail(err, MCF_ENOMEM, "mesh of %d vertices, %d faces", nv, nf);
        return NULL;
    }
    memcpy(m->X, X, 3 * (size_t)nv * sizeof *X);
    memcpy(m->F, F, 3 * (size_t)nf * sizeof *F);
    return m;
}

mcf_mesh *mcf_mesh_dup(const mcf_mesh *m, mcf_error *err)
{
    if (!m) {
        mcf__fail(err, MCF_EINVAL, "mcf_mesh_dup: NULL mesh");
        return NULL;
    }
    return mcf_mesh_new(m->nv, m->X, m->nf, m->F, err);
}

void mcf_mesh_free(mcf_mesh *m)
{
    if (!m)
        return;
    free(m->X);
    free(m->F);
    free(m);
}

int mcf_mesh_nvertices(const mcf_mesh *m) { return m->nv; }
int mcf_mesh_nfaces(const mcf_mesh *m) { return m->nf; }
const double *mcf_mesh_positions(const mcf_mesh *m) { return m->X; }
double *mcf_mesh_positions_mut(mcf_mesh *m) { return m->X; }
const int32_t *mcf_mesh_faces(const mcf_mesh *m) { return m->F; }

/* ----------------------------------------------------------- inspection */

/* One half-edge: the side of face `face` from corner k to corner k+1. */
typedef struct {
    uint64_t key; /* min << 32 | max */
    int32_t face;
    int32_t k;
} half_edge;

static int half_edge_cmp(const void *pa, const void *pb)
{
    const half_edge *a = pa, *b = pb;
    if (a->key != b->key)
        return a->key < b->key ? -1 : 1;
    if (a->face != b->face)
        return a->face < b->face ? -1 : 1;
    return (a->k > b->k) - (a->k < b->k);
}

typedef struct {
    int32_t v[3];
    int32_t face;
} face_key;

static int face_key_cmp(const void *pa, const void *pb)
{
    const face_key *a = pa, *b = pb;
    int i;
    for (i = 0; i < 3; i++)
        if (a->v[i] != b->v[i])
            return a->v[i] < b->v[i] ? -1 : 1;
    return (a->face > b->face) - (a->face < b->face);
}

static int32_t uf_find(int32_t *p, int32_t x)
{
    int32_t r = x;
    while (p[r] != r)
        r = p[r];
    while (p[x] != r) {
        int32_t n = p[x];
        p[x] = r;
        x = n;
    }
    return r;
}

static void uf_union(int32_t *p, int32_t a, int32_t b)
{
    a = uf_find(p, a);
    b = uf_find(p, b);
    if (a != b) {
        /* Union by index keeps it deterministic; path compression keeps
         * it fast enough for meshes. */
        if (a < b)
            p[b] = a;
        else
            p[a] = b;
    }
}

/* The two sorts of mcf_mesh_inspect when bucket_sort (below) has no
 * scratch: by radix (mcf__radix_sort_u64) on the key with the position as
 * payload, then a gather: qsort took most of an inspection. Both arrays are made in face order, so the stable sort by
 * key gives the order of the comparators above (key, then face), and
 * those serve as the fallback when the scratch cannot be had (or a face
 * key does not fit in 64 bits: more than 2^21 vertices).
 *
 * sort_by_key sorts the n records of sz bytes at base so: k holds their
 * keys and as many again of scratch (NULL: qsort by cmp), and is freed. */
static void sort_by_key(void *base, size_t n, size_t sz, uint64_t *k,
                        int (*cmp)(const void *, const void *))
{
    uint32_t *p = k ? mcf__malloc(2 * n, sizeof *p) : NULL;
    unsigned char *out = NULL, *b = base;
    size_t i;

    if (p) {
        for (i = 0; i < n; i++)
            p[i] = (uint32_t)i;
        mcf__radix_sort_u64(k, p, n, k + n, p + n);
        free(k); /* before the gather's copy: peak about qsort's */
        k = NULL;
        out = mcf__malloc(n, sz);
    }
    if (out) {
        for (i = 0; i < n; i++)
            memcpy(out + i * sz, b + (size_t)p[i] * sz, sz);
        memcpy(b, out, n * sz);
    } else {
        qsort(b, n, sz, cmp);
    }
    free(k);
    free(p);
    free(out);
}

/* Sorts the n records of sz (at most 16) bytes at base by cmp, whose
 * first criterion is the vertex lead() gives (< nv): a counting sort by
 * it (stable), then each vertex's bucket, a few records on a mesh, by
 * insertion (qsort past 32 records: a vertex of high degree). Both
 * comparators are total orders, so the result is theirs, as the radix
 * sort's was, in two passes over the records instead of six or more (and
 * instead of qsort on a face key over 2^21 vertices: the 7M scan). 0 when
 * the scratch cannot be had (the caller sorts otherwise). */
static int bucket_sort(void *base, size_t n, size_t sz, size_t nv,
                       uint32_t (*lead)(const void *),
                       int (*cmp)(const void *, const void *))
{
    size_t *start = mcf__calloc(nv + 1, sizeof *start);
    unsigned char *out = start ? mcf__malloc(n ? n : 1, sz) : NULL, *b = base, t[16];
    size_t i, j;

    if (!out || sz > sizeof t) {
        free(start);
        free(out);
        return 0;
    }
    for (i = 0; i < n; i++)
        start[lead(b + i * sz) + 1]++;
    for (i = 0; i < nv; i++)
        start[i + 1] += start[i];
    for (i = 0; i < n; i++)
        memcpy(out + start[lead(b + i * sz)]++ * sz, b + i * sz, sz);
    /* start[v] is now bucket v's end, bucket v - 1's the start */
    for (size_t v = 0, lo = 0; v < nv; lo = start[v++]) {
        size_t hi = start[v];
        if (hi - lo > 32) {
            qsort(out + lo * sz, hi - lo, sz, cmp);
            continue;
        }
        for (i = lo + 1; i < hi; i++) {
            memcpy(t, out + i * sz, sz);
            for (j = i; j > lo && cmp(out + (j - 1) * sz, t) > 0; j--)
                memcpy(out + j * sz, out + (j - 1) * sz, sz);
            memcpy(out + j * sz, t, sz);
        }
    }
    memcpy(b, out, n * sz);
    free(start);
    free(out);
    return 1;
}

static uint32_t half_edge_lead(const void *p)
{
    return (uint32_t)(((const half_edge *)p)->key >> 32);
}

static uint32_t face_key_lead(const void *p)
{
    return (uint32_t)((const face_key *)p)->v[0];
}

static void sort_half_edges(half_edge *he, size_t n, size_t nv)
{
    if (bucket_sort(he, n, sizeof *he, nv, half_edge_lead, half_edge_cmp))
        return;
    uint64_t *k = n <= UINT32_MAX ? mcf__malloc(2 * n, sizeof *k) : NULL;

    for (size_t i = 0; k && i < n; i++)
        k[i] = he[i].key;
    sort_by_key(he, n, sizeof *he, k, half_edge_cmp);
}

static void sort_face_keys(face_key *fk, size_t n, size_t nv)
{
    if (bucket_sort(fk, n, sizeof *fk, nv, face_key_lead, face_key_cmp))
        return;
    uint64_t *k = nv <= (size_t)1 << 21 && n <= UINT32_MAX
                      ? mcf__malloc(2 * n, sizeof *k) : NULL;

    for (size_t i = 0; k && i < n; i++)
        k[i] = (uint64_t)fk[i].v[0] << 42 | (uint64_t)fk[i].v[1] << 21 |
               (uint64_t)fk[i].v[2];
    sort_by_key(fk, n, sizeof *fk, k, face_key_cmp);
}

/* Corner index (3f + j) of vertex v in the face of half-edge e. */
static int32_t corner_of(const int32_t *F, const half_edge *e, int32_t v)
{
    int32_t c0 = 3 * e->face + e->k;
    int32_t c1 = 3 * e->face + (e->k + 1) % 3;
    return F[c0] == v ? c0 : c1;
}

/* The sum of the three face-edge lengths of all faces over 3 nf: on a
 * closed manifold mesh, where every edge has two faces, it equals the mean
 * over unique edges exactly. */
static double face_edge_mean(const double *X, const int32_t *F, int nf)
{
    double s = 0;
    size_t f;
    for (f = 0; f < (size_t)nf; f++) {
        int k;
        for (k = 0; k < 3; k++) {
            double d[3];
            mcf__sub3(X + 3 * (size_t)F[3 * f + k],
                      X + 3 * (size_t)F[3 * f + (k + 1) % 3], d);
            s += sqrt(mcf__dot3(d, d));
        }
    }
    return nf > 0 ? s / (3.0 * nf) : 0;
}

/* Degenerate-face threshold. A face is degenerate when it repeats an
 * index or when its area is at most MCF_DEGENERATE_REL * lmax^2, lmax its
 * longest edge: the area of a truly collinear (or collapsed) triangle,
 * computed from a cross product, is rounding noise of order 1e-16 lmax^2,
 * so 1e-14 flags exactly those with margin, independently of the mesh's
 * scale, while a thin but genuine sliver (aspect 1e-12 would be needed to
 * hit it) is kept. */
#define MCF_DEGENERATE_REL 1e-14

/* mcf_mesh_inspect's scratch: the half-edges (sorted by edge), the sorted
 * vertex triple of every face, union-finds over the corners and the
 * vertices, a mark per vertex. */
typedef struct {
    half_edge *he;
    size_t nh;
    face_key *fk;
    int32_t *cuf, *vuf;
    unsigned char *used;
} inspect_scratch;

/* Bounding box, area, volume, degenerate, unreferenced and duplicate
 * faces; fills the half-edges and face keys. */
static void inspect_faces(const mcf_mesh *m, inspect_scratch *s, mcf_mesh_info *r)
{
    const double *X = m->X;
    const int32_t *F = m->F;
    size_t nv = (size_t)m->nv, nf = (size_t)m->nf, i, f;
    int k;

    /* Bounding box over all vertices (unreferenced included: they are part
     * of the data and would be written back out). */
    for (k = 0; k < 3; k++) {
        r->bbox_min[k] = X[k];
        r->bbox_max[k] = X[k];
    }
    for (i = 0; i < nv; i++)
        for (k = 0; k < 3; k++) {
            double x = X[3 * i + k];
            if (x < r->bbox_min[k]) r->bbox_min[k] = x;
            if (x > r->bbox_max[k]) r->bbox_max[k] = x;
        }

    /* Per face: area, volume, degeneracy, the sorted key, half-edges. */
    for (f = 0; f < nf; f++) {
        const int32_t *t = F + 3 * f;
        const double *a = X + 3 * (size_t)t[0], *b = X + 3 * (size_t)t[1],
                     *c = X + 3 * (size_t)t[2];
        double e1[3], e2[3], e3[3], cr[3], area, lmax;
        int32_t s0 = t[0], s1 = t[1], s2 = t[2], tmp;

        mcf__sub3(b, a, e1);
        mcf__sub3(c, a, e2);
        mcf__sub3(c, b, e3);
        mcf__cross3(e1, e2, cr);
        area = 0.5 * sqrt(mcf__dot3(cr, cr));
        lmax = fmax(mcf__dot3(e1, e1), fmax(mcf__dot3(e2, e2),
                                            mcf__dot3(e3, e3)));
        r->area += area;
        mcf__cross3(b, c, cr);
        r->volume += mcf__dot3(a, cr) / 6.0;
        if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2] ||
            area <= MCF_DEGENERATE_REL * lmax)
            r->degenerate_faces++;
        for (k = 0; k < 3; k++)
            s->used[t[k]] = 1;

        if (s0 > s1) { tmp = s0; s0 = s1; s1 = tmp; }
        if (s1 > s2) { tmp = s1; s1 = s2; s2 = tmp; }
        if (s0 > s1) { tmp = s0; s0 = s1; s1 = tmp; }
        s->fk[f].v[0] = s0;
        s->fk[f].v[1] = s1;
        s->fk[f].v[2] = s2;
        s->fk[f].face = (int32_t)f;

        /* A side joining a vertex to itself (repeated index) is no edge. */
        for (k = 0; k < 3; k++) {
            int32_t u = t[k], v = t[(k + 1) % 3];
            if (u == v)
                continue;
            if (u > v) { tmp = u; u = v; v = tmp; }
            s->he[s->nh].key = ((uint64_t)(uint32_t)u << 32) | (uint32_t)v;
            s->he[s->nh].face = (int32_t)f;
            s->he[s->nh].k = k;
            s->nh++;
        }
    }
    for (i = 0; i < nv; i++)
        if (!s->used[i])
            r->unreferenced++;

    /* Duplicate faces: same sorted vertex triple as an earlier face. */
    sort_face_keys(s->fk, nf, nv);
    for (f = 1; f < nf; f++)
        if (memcmp(s->fk[f].v, s->fk[f - 1].v, sizeof s->fk[f].v) == 0)
            r->duplicate_faces++;
}

/* Edges: counts, lengths, boundary, non-manifold and inconsistently
 * oriented ones; joins the corners of a vertex across shared edges (cuf)
 * and the endpoints of boundary edges (vuf). */
static void inspect_edges(const mcf_mesh *m, inspect_scratch *s, mcf_mesh_info *r)
{
    const double *X = m->X;
    const int32_t *F = m->F;
    size_t nv = (size_t)m->nv, nf = (size_t)m->nf, nh = s->nh, i, j, q, f;
    double esum = 0;
    int k;

    /* Edges. The corners of one vertex are joined through every edge two
     * of their faces share (and within a face that repeats the vertex); a
     * vertex whose corners fall into several classes has a face fan in
     * several pieces: a non-manifold ("bowtie") vertex. Faces are joined
     * through non-manifold edges too, so that a vertex is counted only
     * when its fan really falls apart; the edges themselves are counted
     * in nonmanifold_edges. (Joining through manifold edges only would
     * also flag every vertex of a non-manifold edge or of a duplicated
     * face; this is the definition ../shared/meshes/SOURCES.md counts
     * with: 16 vertices on dragon_vrip_res2, 2 on test_nm.) */
    for (i = 0; i < 3 * nf; i++)
        s->cuf[i] = (int32_t)i;
    for (f = 0; f < nf; f++)
        for (k = 0; k < 3; k++)
            for (j = (size_t)k + 1; j < 3; j++)
                if (F[3 * f + k] == F[3 * f + j])
                    uf_union(s->cuf, (int32_t)(3 * f + k), (int32_t)(3 * f + j));
    for (i = 0; i < nv; i++)
        s->vuf[i] = (int32_t)i;
    sort_half_edges(s->he, nh, (size_t)m->nv);
    r->min_edge = HUGE_VAL;
    r->max_edge = 0;
    for (i = 0; i < nh; i = j) {
        int32_t u = (int32_t)(s->he[i].key >> 32), v = (int32_t)(s->he[i].key & 0xffffffffu);
        double d[3], len;
        size_t cnt;
        for (j = i + 1; j < nh && s->he[j].key == s->he[i].key; j++)
            ;
        cnt = j - i;
        r->ne++;
        mcf__sub3(X + 3 * (size_t)u, X + 3 * (size_t)v, d);
        len = sqrt(mcf__dot3(d, d));
        esum += len;
        if (len < r->min_edge) r->min_edge = len;
        if (len > r->max_edge) r->max_edge = len;
        if (cnt == 1) {
            r->boundary_edges++;
            uf_union(s->vuf, u, v);
        } else if (cnt > 2) {
            r->nonmanifold_edges++;
        } else {
            int fwd_a = F[3 * s->he[i].face + s->he[i].k] == u;
            int fwd_b = F[3 * s->he[i + 1].face + s->he[i + 1].k] == u;
            if (fwd_a == fwd_b)
                r->inconsistent_orientation++;
        }
        for (q = i + 1; q < j; q++) {
            uf_union(s->cuf, corner_of(F, s->he + i, u), corner_of(F, s->he + q, u));
            uf_union(s->cuf, corner_of(F, s->he + i, v), corner_of(F, s->he + q, v));
        }
    }
    if (r->ne > 0)
        r->mean_edge = esum / r->ne;
    else
        r->min_edge = 0;
}

/* Boundary loops, non-manifold vertices, components, Euler
 * characteristic and genus, from the union-finds inspect_edges built. */
static void inspect_topology(const mcf_mesh *m, inspect_scratch *s, mcf_mesh_info *r)
{
    const int32_t *F = m->F;
    size_t nv = (size_t)m->nv, nf = (size_t)m->nf, nh = s->nh, i, j, f;

    /* Boundary loops: components of the boundary-edge graph. A vertex is
     * on it when it is an endpoint of a boundary edge; count the roots. */
    memset(s->used, 0, nv);
    for (i = 0; i < nh; i = j) {
        for (j = i + 1; j < nh && s->he[j].key == s->he[i].key; j++)
            ;
        if (j - i == 1) {
            s->used[s->he[i].key >> 32] = 1;
            s->used[s->he[i].key & 0xffffffffu] = 1;
        }
    }
    for (i = 0; i < nv; i++)
        if (s->used[i] && uf_find(s->vuf, (int32_t)i) == (int32_t)i)
            r->boundary_loops++;

    /* Non-manifold vertices: more than one root corner at a vertex. The
     * counter per vertex reuses s->vuf (loops are counted already). */
    memset(s->vuf, 0, nv * sizeof *s->vuf);
    for (i = 0; i < 3 * nf; i++)
        if (uf_find(s->cuf, (int32_t)i) == (int32_t)i)
            s->vuf[F[i]]++;
    for (i = 0; i < nv; i++)
        if (s->vuf[i] > 1)
            r->nonmanifold_vertices++;

    /* Components: vertices joined through faces, referenced ones counted. */
    memset(s->used, 0, nv);
    for (i = 0; i < nv; i++)
        s->vuf[i] = (int32_t)i;
    for (f = 0; f < nf; f++) {
        uf_union(s->vuf, F[3 * f], F[3 * f + 1]);
        uf_union(s->vuf, F[3 * f], F[3 * f + 2]);
        s->used[F[3 * f]] = 1;
        s->used[F[3 * f + 1]] = 1;
        s->used[F[3 * f + 2]] = 1;
    }
    for (i = 0; i < nv; i++)
        if (s->used[i] && uf_find(s->vuf, (int32_t)i) == (int32_t)i)
            r->components++;

    r->euler = (r->nv - r->unreferenced) - r->ne + r->nf;
    r->manifold = r->nonmanifold_edges == 0 && r->nonmanifold_vertices == 0;
    r->closed = r->boundary_edges == 0;
    r->genus = -1;
    if (r->manifold && r->components == 1) {
        int twice = 2 - r->euler - r->boundary_loops;
        /* An odd or negative value means a non-orientable surface. */
        if (twice >= 0 && twice % 2 == 0)
            r->genus = twice / 2;
    }
}

mcf_status mcf_mesh_inspect(const mcf_mesh *m, mcf_mesh_info *info,
                            mcf_error *err)
{
    mcf_status rc = MCF_OK;
    mcf_mesh_info r;
    inspect_scratch s;
    size_t nv, nf;

    if (!m || !info)
        return mcf__fail(err, MCF_EINVAL, "mcf_mesh_inspect: NULL argument");
    nv = (size_t)m->nv;
    nf = (size_t)m->nf;
    memset(&r, 0, sizeof r);
    r.nv = m->nv;
    r.nf = m->nf;
    memset(&s, 0, sizeof s);
    s.he = mcf__malloc(3 * nf, sizeof *s.he);
    s.fk = mcf__malloc(nf, sizeof *s.fk);
    s.cuf = mcf__malloc(3 * nf, sizeof *s.cuf);
    s.vuf = mcf__malloc(nv, sizeof *s.vuf);
    s.used = mcf__calloc(nv, 1);
    if (!s.he || !s.fk || !s.cuf || !s.vuf || !s.used) {
        rc = mcf__fail(err, MCF_ENOMEM, "inspecting %zu faces", nf);
    } else {
        inspect_faces(m, &s, &r);
        inspect_edges(m, &s, &r);
        inspect_topology(m, &s, &r);
        *info = r;
    }
    free(s.he);
    free(s.fk);
    free(s.cuf);
    free(s.vuf);
    free(s.used);
    return rc;
}

double mcf_mesh_area(const mcf_mesh *m)
{
    double s = 0;
    size_t f;
    for (f = 0; f < (size_t)m->nf; f++) {
        const int32_t *t = m->F + 3 * f;
        double e1[3], e2[3], cr[3];
        mcf__sub3(m->X + 3 * (size_t)t[1], m->X + 3 * (size_t)t[0], e1);
        mcf__sub3(m->X + 3 * (size_t)t[2], m->X + 3 * (size_t)t[0], e2);
        mcf__cross3(e1, e2, cr);
        s += 0.5 * sqrt(mcf__dot3(cr, cr));
    }
    return s;
}

#if defined(__GNUC__) && defined(__x86_64__)
#define AV_AVX2 1
#include <immintrin.h>

/* One coordinate of corner k of the four faces t[0..11], one per lane. */
__attribute__((target("avx2"), always_inline)) static inline __m256d av_coord(const double *X, const int32_t *t,
                                                                              int k, int d)
{
    return _mm256_set_pd(X[3 * (size_t)t[9 + k] + d], X[3 * (size_t)t[6 + k] + d], X[3 * (size_t)t[3 + k] + d],
                         X[3 * (size_t)t[k] + d]);
}

/* mcf__area_volume's per-face terms of the nb blocks of four faces F[0 ..
 * 12 nb - 1] in AVX2 lanes (the scalar loop's operations in its order, no
 * fused multiply-add), summed face by face in order as the scalar loop
 * does: the same bits. The rescale of every implicit step runs it
 * (armadillo: about 0.8 ms a step scalar). s: A, cx, cy, cz, v. */
__attribute__((target("avx2")))
static void area_volume_avx2(const double *X, const int32_t *F, int nb, double s[5])
{
    for (int b = 0; b < nb; b++) {
        const int32_t *t = F + 12 * (size_t)b;
        __m256d a0 = av_coord(X, t, 0, 0), a1 = av_coord(X, t, 0, 1), a2 = av_coord(X, t, 0, 2);
        __m256d b0 = av_coord(X, t, 1, 0), b1 = av_coord(X, t, 1, 1), b2 = av_coord(X, t, 1, 2);
        __m256d d0 = av_coord(X, t, 2, 0), d1 = av_coord(X, t, 2, 1), d2 = av_coord(X, t, 2, 2);
        __m256d e10 = b0 - a0, e11 = b1 - a1, e12 = b2 - a2, e20 = d0 - a0, e21 = d1 - a1, e22 = d2 - a2;
        __m256d n0 = e11 * e22 - e12 * e21, n1 = e12 * e20 - e10 * e22, n2 = e10 * e21 - e11 * e20;
        __m256d af = _mm256_set1_pd(0.5) * _mm256_sqrt_pd(n0 * n0 + n1 * n1 + n2 * n2);
        __m256d tx = af * (a0 + b0 + d0), ty = af * (a1 + b1 + d1), tz = af * (a2 + b2 + d2);
        __m256d bd0 = b1 * d2 - b2 * d1, bd1 = b2 * d0 - b0 * d2, bd2 = b0 * d1 - b1 * d0;
        __m256d tv = a0 * bd0 + a1 * bd1 + a2 * bd2;
        double l[5][4];
        _mm256_storeu_pd(l[0], af);
        _mm256_storeu_pd(l[1], tx);
        _mm256_storeu_pd(l[2], ty);
        _mm256_storeu_pd(l[3], tz);
        _mm256_storeu_pd(l[4], tv);
        for (int j = 0; j < 4; j++)
            for (int q = 0; q < 5; q++)
                s[q] += l[q][j];
    }
}
#endif

/* Total area, area centroid (may be NULL) and signed enclosed volume
 * (divergence theorem, may be NULL) in one pass. Returns the area. */
double mcf__area_volume(const double *X, const int32_t *F, int nf, double *centroid,
                        double *volume)
{
    double A = 0.0, cx = 0.0, cy = 0.0, cz = 0.0, v = 0.0;
    int f = 0;
#if defined(AV_AVX2)
    if (__builtin_cpu_supports("avx2")) {
        double s[5] = {0.0, 0.0, 0.0, 0.0, 0.0};
        f = nf / 4 * 4;
        area_volume_avx2(X, F, nf / 4, s);
        A = s[0], cx = s[1], cy = s[2], cz = s[3], v = s[4];
    }
#endif
    for (; f < nf; f++) {
        const double *a = X + 3 * (size_t)F[3 * f], *b = X + 3 * (size_t)F[3 * f + 1],
                     *d = X + 3 * (size_t)F[3 * f + 2];
        double e1[3], e2[3], n[3], bd[3];
        mcf__sub3(b, a, e1);
        mcf__sub3(d, a, e2);
        mcf__cross3(e1, e2, n);
        double af = 0.5 * sqrt(mcf__dot3(n, n));
        A += af;
        cx += af * (a[0] + b[0] + d[0]);
        cy += af * (a[1] + b[1] + d[1]);
        cz += af * (a[2] + b[2] + d[2]);
        mcf__cross3(b, d, bd);
        v += mcf__dot3(a, bd);
    }
    if (centroid) {
        centroid[0] = A > 0 ? cx / (3.0 * A) : 0.0;
        centroid[1] = A > 0 ? cy / (3.0 * A) : 0.0;
        centroid[2] = A > 0 ? cz / (3.0 * A) : 0.0;
    }
    if (volume)
        *volume = v / 6.0;
    return A;
}

double mcf_mesh_area_centroid(const mcf_mesh *m, double centroid[3])
{
    return mcf__area_volume(m->X, m->F, m->nf, centroid, NULL);
}

/* Signed volume by the divergence theorem: sum over faces of the signed
 * volume of the tetrahedron (origin, a, b, c), det[a b c] / 6. Exact for a
 * closed mesh whatever the origin; positive when faces point outward. */
double mcf_mesh_volume(const mcf_mesh *m)
{
    double s = 0;
    size_t f;
    for (f = 0; f < (size_t)m->nf; f++) {
        const int32_t *t = m->F + 3 * f;
        double cr[3];
        mcf__cross3(m->X + 3 * (size_t)t[1], m->X + 3 * (size_t)t[2], cr);
        s += mcf__dot3(m->X + 3 * (size_t)t[0], cr) / 6.0;
    }
    return s;
}

/* ---------------------------------------------------------------- noise */

/* splitmix64 (Steele, Lea, Flood 2014): a 64-bit state, full period,
 * integer-only, hence the same stream on every platform. */
typedef struct {
    uint64_t s;
    double spare;
    int has_spare;
} rng;

static uint64_t rng_next(rng *g)
{
    g->s += UINT64_C(0x9e3779b97f4a7c15);
    return mcf__mix64(g->s);
}

/* Uniform in (-1, 1) with 53 random bits: (2k + 1 - 2^53) / 2^53. */
static double rng_sym(rng *g)
{
    int64_t k = (int64_t)(rng_next(g) >> 11);
    return (double)(2 * k + 1 - (INT64_C(1) << 53)) / 9007199254740992.0;
}

/* Natural log for s in (0, 1] from +, -, *, / and frexp only, so that it
 * rounds identically wherever IEEE-754 doubles are used (libm's log is
 * not correctly rounded on every platform). x = 2^e w, w in
 * [sqrt(1/2), sqrt(2)); log w = 2 atanh(u), u = (w-1)/(w+1), |u| < 0.172,
 * whose series to u^27 is accurate to below 1e-20 relative. */
static double portable_log(double x)
{
    static const double ln2 = 0.69314718055994530942;
    int e;
    double w = frexp(x, &e), u, u2, term, sum;
    int n;

    if (w < 0.70710678118654752440) {
        w *= 2;
        e--;
    }
    u = (w - 1) / (w + 1);
    u2 = u * u;
    term = u;
    sum = 0;
    for (n = 1; n <= 27; n += 2) {
        sum += term / n;
        term *= u2;
    }
    return 2 * sum + e * ln2;
}

/* Standard normal by Marsaglia's polar method (Box-Muller without the
 * trigonometric functions, whose last bits vary between libms). */
static double rng_gauss(rng *g)
{
    double u, v, s;
    if (g->has_spare) {
        g->has_spare = 0;
        return g->spare;
    }
    do {
        u = rng_sym(g);
        v = rng_sym(g);
        s = u * u + v * v;
    } while (s >= 1 || s == 0);
    s = sqrt(-2 * portable_log(s) / s); /* sqrt is correctly rounded */
    g->spare = v * s;
    g->has_spare = 1;
    return u * s;
}

void mcf__gauss_fill(uint64_t seed, double *z, size_t n)
{
    rng g = {seed, 0.0, 0};
    for (size_t i = 0; i < n; i++)
        z[i] = rng_gauss(&g);
}

mcf_status mcf_mesh_add_noise(mcf_mesh *m, double rho, uint64_t seed,
                              mcf_error *err)
{
    double *N, sigma;
    rng g;
    size_t i;

    if (!m)
        return mcf__fail(err, MCF_EINVAL, "mcf_mesh_add_noise: NULL mesh");
    if (!(rho >= 0) || !isfinite(rho))
        return mcf__fail(err, MCF_EINVAL, "noise rho %g not >= 0", rho);
    N = mcf__malloc(3 * (size_t)m->nv, sizeof *N);
    if (!N)
        return mcf__fail(err, MCF_ENOMEM, "noise normals of %d vertices",
                         m->nv);
    mcf__vertex_normals(m->X, m->F, m->nf, m->nv, N);
    sigma = rho * face_edge_mean(m->X, m->F, m->nf);
    g.s = seed;
    g.spare = 0;
    g.has_spare = 0;
    /* One draw per vertex, in index order, also where the normal is zero
     * (unreferenced), so vertex i always gets the i-th draw. */
    for (i = 0; i < (size_t)m->nv; i++) {
        double z = sigma * rng_gauss(&g);
        m->X[3 * i] += z * N[3 * i];
        m->X[3 * i + 1] += z * N[3 * i + 1];
        m->X[3 * i + 2] += z * N[3 * i + 2];
    }
    free(N);
    return MCF_OK;
}
