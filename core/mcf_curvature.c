/* SPDX-License-Identifier: MIT */
/*
 * mcf_curvature.c - discrete curvatures per vertex and their summary:
 * area-weighted vertex normals, mean curvature from the cotan Laplacian,
 * Gaussian curvature by angle deficit, |A|^2 = 4H^2 - 2K (its discriminant
 * H^2 - K clamped at 0, so never negative), and the discrete Gauss-Bonnet
 * check.
 *
 * Signs and conventions (docs/MATH.md): L is the PSD cotan stiffness,
 * M the barycentric lumped mass, Delta X = -M^-1 L X = -2 H n, so
 * H_i = <(M^-1 L X)_i, n_i> / 2 is positive on a sphere with outward
 * normals (1/R on a sphere of radius R). K_i = (2 pi - sum of the corner
 * angles at i) / m_i on interior vertices, 0 on boundary vertices (those
 * on an edge with exactly one face). Everything is linear in the mesh
 * (a bucket sort of the edges to find the boundary, the percentiles by
 * selection) and allocates O(nv + nf) scratch.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_internal.h"

/* Bit-identical results across platforms for the vertex normals that mcf_mesh_add_noise uses: no fused
 * multiply-add contraction. GCC already does none in ISO C mode
 * (-std=c11); clang contracts within expressions unless told not to. */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

static const double mcf_pi = 3.14159265358979323846;

void mcf__vertex_normals(const double *X, const int32_t *F, int nf, int nv,
                         double *N)
{
    size_t f, i;
    memset(N, 0, 3 * (size_t)nv * sizeof *N);
    /* The unnormalized face normal (b-a) x (c-a) has length twice the
     * area, so summing it weights each face by its area. */
    for (f = 0; f < (size_t)nf; f++) {
        const int32_t *t = F + 3 * f;
        double e1[3], e2[3], cr[3];
        int k;
        mcf__sub3(X + 3 * (size_t)t[1], X + 3 * (size_t)t[0], e1);
        mcf__sub3(X + 3 * (size_t)t[2], X + 3 * (size_t)t[0], e2);
        mcf__cross3(e1, e2, cr);
        for (k = 0; k < 3; k++) {
            double *n = N + 3 * (size_t)t[k];
            n[0] += cr[0];
            n[1] += cr[1];
            n[2] += cr[2];
        }
    }
    for (i = 0; i < (size_t)nv; i++) {
        double *n = N + 3 * i, len = sqrt(mcf__dot3(n, n));
        if (len > 0 && isfinite(len)) {
            n[0] /= len;
            n[1] /= len;
            n[2] /= len;
        } else {
            n[0] = n[1] = n[2] = 0;
        }
    }
}

void mcf__vertex_gradient(const double *X, const int32_t *F, int nf, int nv,
                          const double *f, double *G)
{
    double *wsum = mcf__calloc((size_t)nv, sizeof *wsum);
    memset(G, 0, 3 * (size_t)nv * sizeof *G);
    for (size_t q = 0; q < (size_t)nf; q++) {
        const int32_t *t = F + 3 * q;
        const double *p[3] = {X + 3 * (size_t)t[0], X + 3 * (size_t)t[1], X + 3 * (size_t)t[2]};
        double a1[3], a2[3], n[3], g[3] = {0, 0, 0};
        mcf__sub3(p[1], p[0], a1);
        mcf__sub3(p[2], p[0], a2);
        mcf__cross3(a1, a2, n); /* |n| = 2A */
        double n2 = mcf__dot3(n, n);
        if (!(n2 > 0.0))
            continue; /* a zero-area face has no gradient */
        for (int k = 0; k < 3; k++) {
            /* grad phi_k = n x e_k / |n|^2, e_k the edge opposite k, ccw */
            double e[3], ne[3];
            mcf__sub3(p[(k + 2) % 3], p[(k + 1) % 3], e);
            mcf__cross3(n, e, ne);
            double s = f[t[k]] / n2;
            g[0] += s * ne[0]; g[1] += s * ne[1]; g[2] += s * ne[2];
        }
        double A = 0.5 * sqrt(n2);
        for (int k = 0; k < 3; k++) {
            double *Gi = G + 3 * (size_t)t[k];
            Gi[0] += A * g[0]; Gi[1] += A * g[1]; Gi[2] += A * g[2];
            if (wsum)
                wsum[t[k]] += A;
        }
    }
    for (size_t i = 0; wsum && i < (size_t)nv; i++)
        if (wsum[i] > 0.0) {
            G[3 * i] /= wsum[i]; G[3 * i + 1] /= wsum[i]; G[3 * i + 2] /= wsum[i];
        }
    free(wsum);
}

mcf_status mcf_gradient(const mcf_mesh *m, const double *f, double *G, mcf_error *err)
{
    if (!m || !f || !G)
        return mcf__fail(err, MCF_EINVAL, "mcf_gradient: NULL argument");
    mcf__vertex_gradient(m->X, m->F, m->nf, m->nv, f, G);
    return MCF_OK;
}

/* Topology the curvatures need: on_boundary[v] = 1 for an endpoint of an
 * edge with exactly one face; *ne the number of unique edges (sides that
 * join a vertex to itself are no edges, as in mcf_mesh_inspect). The
 * sides are bucketed by their smaller endpoint (a counting sort) and
 * each bucket, a few sides, sorted by the other: the same edges as one
 * sort of all the sides' keys, in two passes over them instead of a
 * radix sort's eight (the metrics document measures every mesh twice). */
static int cmp_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return (x > y) - (x < y);
}

static mcf_status edge_topology(const int32_t *F, int nf, int nv,
                                unsigned char *on_boundary, int *ne,
                                mcf_error *err)
{
    size_t *start = mcf__calloc((size_t)nv + 1, sizeof *start);
    uint32_t *other = mcf__malloc(3 * (size_t)nf + 1, sizeof *other);
    size_t f;
    int count = 0;

    if (!start || !other) {
        free(start);
        free(other);
        return mcf__fail(err, MCF_ENOMEM, "edge list of %d faces", nf);
    }
    for (f = 0; f < 3 * (size_t)nf; f++) {
        uint32_t u = (uint32_t)F[f], v = (uint32_t)F[f - f % 3 + (f + 1) % 3];
        if (u != v)
            start[(u < v ? u : v) + 1]++;
    }
    for (size_t a = 0; a < (size_t)nv; a++)
        start[a + 1] += start[a];
    for (f = 0; f < 3 * (size_t)nf; f++) {
        uint32_t u = (uint32_t)F[f], v = (uint32_t)F[f - f % 3 + (f + 1) % 3];
        if (u != v)
            other[start[u < v ? u : v]++] = u < v ? v : u;
    }
    /* start[a] is now bucket a's end, bucket a - 1's the start */
    memset(on_boundary, 0, (size_t)nv);
    for (size_t a = 0, lo = 0; a < (size_t)nv; lo = start[a++]) {
        size_t hi = start[a], i, j;
        if (hi - lo > 24) {
            qsort(other + lo, hi - lo, sizeof *other, cmp_u32);
        } else {
            for (i = lo + 1; i < hi; i++) { /* a few sides: by insertion */
                uint32_t x = other[i];
                for (j = i; j > lo && other[j - 1] > x; j--)
                    other[j] = other[j - 1];
                other[j] = x;
            }
        }
        for (i = lo; i < hi; i = j) {
            for (j = i + 1; j < hi && other[j] == other[i]; j++)
                ;
            count++;
            if (j - i == 1) {
                on_boundary[a] = 1;
                on_boundary[other[i]] = 1;
            }
        }
    }
    free(start);
    free(other);
    *ne = count;
    return MCF_OK;
}

void mcf__corner_sums(const double *X, const int32_t *F, int nf,
                      double *angle, double *mass, unsigned char *used)
{
    size_t f;
    for (f = 0; f < (size_t)nf; f++) {
        const int32_t *t = F + 3 * f;
        double e1[3], e2[3], cr[3], area;
        int k;
        mcf__sub3(X + 3 * (size_t)t[1], X + 3 * (size_t)t[0], e1);
        mcf__sub3(X + 3 * (size_t)t[2], X + 3 * (size_t)t[0], e2);
        mcf__cross3(e1, e2, cr);
        area = 0.5 * sqrt(mcf__dot3(cr, cr));
        for (k = 0; k < 3; k++) {
            const double *p = X + 3 * (size_t)t[k];
            double a[3], b[3], c[3];
            mcf__sub3(X + 3 * (size_t)t[(k + 1) % 3], p, a);
            mcf__sub3(X + 3 * (size_t)t[(k + 2) % 3], p, b);
            mcf__cross3(a, b, c);
            angle[t[k]] += atan2(sqrt(mcf__dot3(c, c)), mcf__dot3(a, b));
            if (mass)
                mass[t[k]] += area / 3.0;
            if (used)
                used[t[k]] = 1;
        }
    }
}

/* mcf_curvature's work, also handing the topology and angle sums it
 * found to the caller (mcf_curvature_summarize needs them too, and the
 * edge sort is the most expensive part): bnd, used (nv bytes each) and
 * angle (nv doubles) are caller-allocated scratch, *ne the edge count. */
static mcf_status curvature_fields(const mcf_mesh *m, double *N, double *H,
                                   double *K, double *A2, unsigned char *bnd,
                                   unsigned char *used, double *angle,
                                   int *ne, mcf_error *err)
{
    mcf_status rc = MCF_OK;
    double *n = NULL, *LX = NULL, *lm = NULL, *bm = NULL;
    size_t nv = (size_t)m->nv, i;

    memset(angle, 0, nv * sizeof *angle);
    memset(used, 0, nv);
    n = mcf__malloc(3 * nv, sizeof *n);
    LX = mcf__malloc(3 * nv, sizeof *LX);
    lm = mcf__malloc(nv, sizeof *lm);
    bm = mcf__calloc(nv, sizeof *bm);
    if (!n || !LX || !lm || !bm) {
        rc = mcf__fail(err, MCF_ENOMEM, "curvature of %zu vertices", nv);
        goto done;
    }
    mcf__vertex_normals(m->X, m->F, m->nf, m->nv, n);
    rc = mcf__laplacian_apply(m->X, m->F, m->nf, m->nv, MCF_LAPLACIAN_COTAN,
                              MCF_MASS_BARYCENTRIC, LX, lm, err);
    if (rc != MCF_OK)
        goto done;
    if ((rc = edge_topology(m->F, m->nf, m->nv, bnd, ne, err)) != MCF_OK)
        goto done;
    mcf__corner_sums(m->X, m->F, m->nf, angle, bm, used);

    for (i = 0; i < nv; i++) {
        double h = 0, kg = 0;
        /* A vertex whose faces all have zero area has no mass: its
         * curvature is undefined, reported as 0 like an unreferenced one. */
        if (used[i] && lm[i] > 0)
            h = 0.5 * mcf__dot3(LX + 3 * i, n + 3 * i) / lm[i];
        if (used[i] && !bnd[i] && bm[i] > 0)
            kg = (2 * mcf_pi - angle[i]) / bm[i];
        if (N) {
            N[3 * i] = n[3 * i];
            N[3 * i + 1] = n[3 * i + 1];
            N[3 * i + 2] = n[3 * i + 2];
        }
        if (H)
            H[i] = h;
        if (K)
            K[i] = kg;
        if (A2) {
            /* |A|^2 = k1^2 + k2^2 with k1,2 = H +- sqrt(H^2 - K), i.e.
             * 4H^2 - 2K. The smooth surface has H^2 - K = (k1 - k2)^2 / 4
             * >= 0, but H and K here are two independent estimates (the
             * cotan vector projected on the area-weighted normal over the
             * lumped mass; the angle deficit over the barycentric mass)
             * and nothing makes them agree: at cone-like vertices (every
             * vertex of a regular tetrahedron, two corners of a
             * triangulated cube, spikes and slivers of scans) K exceeds
             * 2H^2 and 4H^2 - 2K is negative. As Meyer et al. (2003) do
             * for the principal curvatures, the discriminant H^2 - K is
             * clamped at 0 (then k1 = k2 = H): 4H^2 - 2K where H^2 >= K,
             * 2H^2 elsewhere; continuous in H and K, never negative. */
            double d = h * h - kg;
            A2[i] = d >= 0 ? 4 * h * h - 2 * kg : 2 * h * h;
        }
    }
done:
    free(n);
    free(LX);
    free(lm);
    free(bm);
    return rc;
}

mcf_status mcf_curvature(const mcf_mesh *m, double *N, double *H, double *K,
                         double *A2, mcf_error *err)
{
    mcf_status rc;
    double *angle;
    unsigned char *bnd, *used;
    size_t nv;
    int ne;

    if (!m)
        return mcf__fail(err, MCF_EINVAL, "mcf_curvature: NULL mesh");
    nv = (size_t)m->nv;
    angle = mcf__malloc(nv, sizeof *angle);
    bnd = mcf__malloc(nv, 1);
    used = mcf__malloc(nv, 1);
    if (!angle || !bnd || !used)
        rc = mcf__fail(err, MCF_ENOMEM, "curvature of %zu vertices", nv);
    else
        rc = curvature_fields(m, N, H, K, A2, bnd, used, angle, &ne, err);
    free(angle);
    free(bnd);
    free(used);
    return rc;
}

/* Percentile q of sorted v[0..n-1], linear between order statistics at
 * position q (n - 1) (the "type 7" rule of R and NumPy's default). */
static double percentile(const double *v, size_t n, double q)
{
    double pos = q * (double)(n - 1), fl = floor(pos);
    size_t lo = (size_t)fl;
    if (lo + 1 >= n)
        return v[n - 1];
    return v[lo] + (pos - fl) * (v[lo + 1] - v[lo]);
}

/* Statistics of x over the vertices with used[i]; tmp holds nv doubles,
 * u 2 nv keys. Finite values: the percentiles by selection
 * (mcf__percentile, the same order statistics a sort gives, in linear
 * time), each on the values as the last left them; any other: by a
 * radix sort of the keys, which orders them all. */
static void stats_of(const double *x, const unsigned char *used, size_t nv,
                     double *tmp, uint64_t *u, mcf_stats *s)
{
    size_t i, n = 0;
    double sum = 0, sq = 0;
    int finite = 1;
    for (i = 0; i < nv; i++)
        if (used[i]) {
            tmp[n++] = x[i];
            finite &= isfinite(x[i]) != 0;
            sum += x[i];
            sq += x[i] * x[i];
        }
    memset(s, 0, sizeof *s);
    if (n == 0)
        return;
    s->mean = sum / (double)n;
    s->rms = sqrt(sq / (double)n);
    if (finite) {
        double lo = tmp[0], hi = tmp[0];
        for (i = 1; i < n; i++) {
            lo = tmp[i] < lo ? tmp[i] : lo;
            hi = tmp[i] > hi ? tmp[i] : hi;
        }
        /* the radix keys map -0 to +0 */
        s->min = lo == 0.0 ? 0.0 : lo;
        s->max = hi == 0.0 ? 0.0 : hi;
        s->p05 = mcf__percentile(tmp, n, 0.05) + 0.0;
        s->p50 = mcf__percentile(tmp, n, 0.50) + 0.0;
        s->p95 = mcf__percentile(tmp, n, 0.95) + 0.0;
        return;
    }
    for (i = 0, n = 0; i < nv; i++)
        if (used[i])
            u[n++] = mcf__double_key(x[i]);
    mcf__radix_sort_u64(u, NULL, n, u + nv, NULL);
    for (i = 0; i < n; i++)
        tmp[i] = mcf__key_double(u[i]);
    s->min = tmp[0];
    s->max = tmp[n - 1];
    s->p05 = percentile(tmp, n, 0.05);
    s->p50 = percentile(tmp, n, 0.50);
    s->p95 = percentile(tmp, n, 0.95);
}

mcf_status mcf_curvature_summarize(const mcf_mesh *m,
                                   mcf_curvature_summary *out, mcf_error *err)
{
    mcf_status rc = MCF_OK;
    mcf_curvature_summary s;
    double *H = NULL, *K = NULL, *A2 = NULL, *angle = NULL, *tmp = NULL;
    uint64_t *u = NULL;
    unsigned char *bnd = NULL, *used = NULL;
    double interior = 0, boundary = 0;
    size_t nv, i;
    int ne, nref = 0;

    if (!m || !out)
        return mcf__fail(err, MCF_EINVAL, "mcf_curvature_summarize: NULL");
    nv = (size_t)m->nv;
    H = mcf__malloc(nv, sizeof *H);
    K = mcf__malloc(nv, sizeof *K);
    A2 = mcf__malloc(nv, sizeof *A2);
    tmp = mcf__malloc(nv, sizeof *tmp);
    u = mcf__malloc(2 * nv, sizeof *u);
    angle = mcf__malloc(nv, sizeof *angle);
    bnd = mcf__malloc(nv, 1);
    used = mcf__malloc(nv, 1);
    if (!H || !K || !A2 || !tmp || !u || !angle || !bnd || !used) {
        rc = mcf__fail(err, MCF_ENOMEM, "curvature of %zu vertices", nv);
        goto done;
    }
    if ((rc = curvature_fields(m, NULL, H, K, A2, bnd, used, angle, &ne,
                               err)) != MCF_OK)
        goto done;

    memset(&s, 0, sizeof s);
    stats_of(H, used, nv, tmp, u, &s.H);
    stats_of(K, used, nv, tmp, u, &s.K);
    stats_of(A2, used, nv, tmp, u, &s.A2);
    /* Discrete Gauss-Bonnet: with every face's angles summing to pi,
     * sum_interior (2 pi - theta_i) + sum_boundary (pi - theta_i)
     * = 2 pi (V - E + F) on any mesh whose boundary vertices each lie on
     * one boundary curve (V_boundary = E_boundary). The deficits are summed
     * directly rather than as K_i m_i so that a massless vertex still
     * counts. */
    for (i = 0; i < nv; i++) {
        if (!used[i])
            continue;
        nref++;
        if (bnd[i])
            boundary += mcf_pi - angle[i];
        else
            interior += 2 * mcf_pi - angle[i];
    }
    s.euler = nref - ne + m->nf;
    s.total_K = interior;
    s.gauss_bonnet = interior + boundary - 2 * mcf_pi * s.euler;
    *out = s;
done:
    free(H);
    free(K);
    free(A2);
    free(tmp);
    free(u);
    free(angle);
    free(bnd);
    free(used);
    return rc;
}
