/* SPDX-License-Identifier: MIT */
/*
 * mcf_icosphere.c - mcf_mesh_new_icosphere: the subdivided icosahedron on a
 * sphere that tests, the lab's studies and the benchmarks build their
 * reference meshes from, bit-identical on every platform.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_internal.h"

/* Bit-identical results across platforms: no fused multiply-add
 * contraction. GCC already does none in ISO C mode (-std=c11); clang
 * contracts within expressions unless told not to. */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

/* Open-addressing map from an undirected edge (a < b) to its midpoint's
 * vertex index; capacity a power of two at least twice the edge count. */
typedef struct {
    uint64_t *key; /* 0 = empty; stored as key + 1 */
    int32_t *val;
    size_t mask;
} edge_map;

/* Returns the midpoint vertex of edge (a, b), creating it (projected to
 * the sphere) when first seen. */
static int32_t midpoint(edge_map *h, double *X, int32_t *nv, int32_t a,
                        int32_t b, double radius)
{
    int32_t lo = a < b ? a : b, hi = a < b ? b : a;
    uint64_t k = (((uint64_t)(uint32_t)lo << 32) | (uint32_t)hi) + 1;
    size_t i = (size_t)mcf__mix64(k) & h->mask;
    double *p, r;
    int32_t v;

    while (h->key[i] != 0) {
        if (h->key[i] == k)
            return h->val[i];
        i = (i + 1) & h->mask;
    }
    v = (*nv)++;
    p = X + 3 * (size_t)v;
    p[0] = 0.5 * (X[3 * (size_t)lo] + X[3 * (size_t)hi]);
    p[1] = 0.5 * (X[3 * (size_t)lo + 1] + X[3 * (size_t)hi + 1]);
    p[2] = 0.5 * (X[3 * (size_t)lo + 2] + X[3 * (size_t)hi + 2]);
    r = sqrt(mcf__dot3(p, p));
    p[0] *= radius / r;
    p[1] *= radius / r;
    p[2] *= radius / r;
    h->key[i] = k;
    h->val[i] = v;
    return v;
}

mcf_mesh *mcf_mesh_new_icosphere(int level, double radius, mcf_error *err)
{
    /* The icosahedron on the cyclic permutations of (+-1, +-phi, 0), with
     * counter-clockwise faces seen from outside (normals point outward). */
#define PHI 1.6180339887498948482
    static const double V0[12][3] = {
        {-1, PHI, 0}, {1, PHI, 0}, {-1, -PHI, 0}, {1, -PHI, 0},
        {0, -1, PHI}, {0, 1, PHI}, {0, -1, -PHI}, {0, 1, -PHI},
        {PHI, 0, -1}, {PHI, 0, 1}, {-PHI, 0, -1}, {-PHI, 0, 1}};
#undef PHI
    static const int32_t F0[20][3] = {
        {0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11},
        {1, 5, 9}, {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
        {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8}, {3, 8, 9},
        {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
    mcf_mesh *m = NULL;
    double *X = NULL;
    int32_t *F = NULL, *G = NULL;
    edge_map h = {NULL, NULL, 0};
    int32_t nv, nf, nvmax, nfmax;
    int l, i, k;

    if (level < 0 || level > 10) {
        mcf__fail(err, MCF_EINVAL, "icosphere level %d not in [0, 10]", level);
        return NULL;
    }
    if (!(radius > 0) || !isfinite(radius)) {
        mcf__fail(err, MCF_EINVAL, "icosphere radius %g not positive", radius);
        return NULL;
    }
    nvmax = 10 * (1 << (2 * level)) + 2;
    nfmax = 20 * (1 << (2 * level));
    X = mcf__malloc(3 * (size_t)nvmax, sizeof *X);
    F = mcf__malloc(3 * (size_t)nfmax, sizeof *F);
    G = mcf__malloc(3 * (size_t)nfmax, sizeof *G);
    if (!X || !F || !G) {
        mcf__fail(err, MCF_ENOMEM, "icosphere level %d", level);
        goto done;
    }
    for (i = 0; i < 12; i++) {
        double s = radius / sqrt(mcf__dot3(V0[i], V0[i]));
        for (k = 0; k < 3; k++)
            X[3 * i + k] = V0[i][k] * s;
    }
    for (i = 0; i < 20; i++)
        for (k = 0; k < 3; k++)
            F[3 * i + k] = F0[i][k];
    nv = 12;
    nf = 20;
    if (level > 0) {
        size_t cap = 1;
        /* Edges of the finest level before the last split: 3/2 nf. */
        while (cap < 3 * (size_t)nfmax / 4)
            cap <<= 1;
        h.key = mcf__calloc(cap, sizeof *h.key);
        h.val = mcf__malloc(cap, sizeof *h.val);
        h.mask = cap - 1;
        if (!h.key || !h.val) {
            mcf__fail(err, MCF_ENOMEM, "icosphere level %d", level);
            goto done;
        }
    }
    for (l = 0; l < level; l++) {
        int32_t *t;
        memset(h.key, 0, (h.mask + 1) * sizeof *h.key);
        for (i = 0; i < nf; i++) {
            int32_t a = F[3 * i], b = F[3 * i + 1], c = F[3 * i + 2];
            int32_t ab = midpoint(&h, X, &nv, a, b, radius);
            int32_t bc = midpoint(&h, X, &nv, b, c, radius);
            int32_t ca = midpoint(&h, X, &nv, c, a, radius);
            int32_t *g = G + 12 * (size_t)i;
            g[0] = a;  g[1] = ab;  g[2] = ca;
            g[3] = ab; g[4] = b;   g[5] = bc;
            g[6] = ca; g[7] = bc;  g[8] = c;
            g[9] = ab; g[10] = bc; g[11] = ca;
        }
        nf *= 4;
        t = F;
        F = G;
        G = t;
    }
    m = mcf_mesh_new(nv, X, nf, F, err);
done:
    free(h.key);
    free(h.val);
    free(X);
    free(F);
    free(G);
    return m;
}
