/* SPDX-License-Identifier: MIT */
/*
 * mcf_creases.c - the creases of a noisy mesh, for the fairing filters
 * (mcf_fairing.c): the sharp edges of the surface smoothed a little that
 * form long chains, whose vertices the filters hold, and those vertices
 * smoothed along their chain (across it only). docs/fairing.md has the
 * reasons in words.
 *
 * Pure C11; no globals.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_internal.h"

/* measured on a box and a capped cylinder (90-degree edges, every one
 * found up to noise 0.25 and 90% at 0.5) against the shared scans, whose
 * sharpest ridges also pass 35 degrees: 40 degrees on the smoothed
 * surface, chains of 12 edges, 3 passes along them */
#define CREASE_ANGLE 40.0
#define CREASE_PASSES 3
#define CREASE_MIN_EDGES 12

/* The slot of edge (a, b) in a's row of the graph (rows are sorted). */
static int edge_slot(const mcf__graph *g, int a, int b)
{
    int lo = g->ptr[a], hi = g->ptr[a + 1] - 1;
    while (lo <= hi) {
        int mid = (lo + hi) / 2;
        if (g->adj[mid] == b)
            return mid;
        if (g->adj[mid] < b)
            lo = mid + 1;
        else
            hi = mid - 1;
    }
    return -1;
}

static int uf_find(int *up, int x)
{
    while (up[x] != x)
        x = up[x] = up[up[x]];
    return x;
}

/* ce[t] = 1 on the edges (slot t of the smaller end's row) between two
 * faces whose unit normals fn meet at more than CREASE_ANGLE; cnt[t] gets
 * the faces of the edge, f1 (scratch) its first. */
static void sharp_edges(const mcf__graph *g, const int32_t *F, int nf, const double *fn,
                        int *f1, int *cnt, unsigned char *ce)
{
    double cosmax = cos(CREASE_ANGLE * MCF_PI / 180.0);
    for (int f = 0; f < nf; f++)
        for (int k = 0; k < 3; k++) {
            int a = F[3 * f + k], b = F[3 * f + (k + 1) % 3];
            if (a == b)
                continue;
            int t = edge_slot(g, a < b ? a : b, a < b ? b : a);
            if (t < 0)
                continue;
            if (cnt[t] == 1 && mcf__dot3(fn + 3 * (size_t)f1[t], fn + 3 * (size_t)f) < cosmax)
                ce[t] = 1;
            if (cnt[t] == 0)
                f1[t] = f;
            else if (cnt[t] >= 1 && cnt[t] != 1)
                ce[t] = 0;
            cnt[t]++;
        }
}

/* Keeps the sharp edges of two faces that form chains of at least
 * CREASE_MIN_EDGES (components of the sharp edges; up, size: nv scratch),
 * marks them in both directions and counts each vertex's crease edges
 * (cdeg). */
static void keep_chains(const mcf__graph *g, int nv, const int *cnt, unsigned char *ce,
                        int *up, int *size, int *cdeg)
{
    for (int i = 0; i < nv; i++)
        up[i] = i;
    for (int a = 0; a < nv; a++)
        for (int t = g->ptr[a]; t < g->ptr[a + 1]; t++)
            if (ce[t] && cnt[t] == 2)
                up[uf_find(up, a)] = uf_find(up, g->adj[t]);
            else
                ce[t] = 0;
    for (int a = 0; a < nv; a++)
        for (int t = g->ptr[a]; t < g->ptr[a + 1]; t++)
            if (ce[t])
                size[uf_find(up, a)]++;
    for (int a = 0; a < nv; a++)
        for (int t = g->ptr[a]; t < g->ptr[a + 1]; t++)
            if (ce[t] && size[uf_find(up, a)] < CREASE_MIN_EDGES)
                ce[t] = 0;
    /* both directions, the degrees along creases */
    for (int a = 0; a < nv; a++)
        for (int t = g->ptr[a]; t < g->ptr[a + 1]; t++)
            if (ce[t] && g->adj[t] > a) {
                int u = edge_slot(g, g->adj[t], a);
                if (u >= 0)
                    ce[u] = 1;
                cdeg[a]++;
                cdeg[g->adj[t]]++;
            }
}

/* The chains' inner vertices (cdeg 2, not fixed) of X smoothed along them
 * by CREASE_PASSES Taubin passes on the chain alone, into X; P and tmp
 * (3*nv) scratch. */
static void smooth_chains(const mcf__graph *g, int nv, const unsigned char *fixed,
                          const unsigned char *ce, const int *cdeg, double *X, double *P,
                          double *tmp)
{
    static const double coef[2] = {MCF_TAUBIN_LAMBDA, MCF_TAUBIN_MU};
    memcpy(P, X, 3 * sizeof(double) * (size_t)nv);
    for (int pass = 0; pass < CREASE_PASSES; pass++)
        for (int h = 0; h < 2; h++) {
            memcpy(tmp, P, 3 * sizeof(double) * (size_t)nv);
            for (int i = 0; i < nv; i++) {
                if (cdeg[i] != 2 || fixed[i])
                    continue;
                double avg[3] = {0, 0, 0};
                for (int t = g->ptr[i]; t < g->ptr[i + 1]; t++)
                    if (ce[t])
                        for (int e = 0; e < 3; e++)
                            avg[e] += 0.5 * tmp[3 * (size_t)g->adj[t] + e];
                /* across the chain only: its tangent (the two
                 * neighbours' difference) part is dropped, so a
                 * vertex stays where the scanner put it along the
                 * crease (on coarse meshes with uneven edges, e.g.
                 * car.drc, Taubin along the chain slid vertices by
                 * whole edges) */
                double tan[3] = {0, 0, 0}, d[3], sign = 1.0;
                for (int t = g->ptr[i]; t < g->ptr[i + 1]; t++)
                    if (ce[t]) {
                        for (int e = 0; e < 3; e++)
                            tan[e] += sign * tmp[3 * (size_t)g->adj[t] + e];
                        sign = -1.0;
                    }
                for (int e = 0; e < 3; e++)
                    d[e] = coef[h] * (avg[e] - tmp[3 * (size_t)i + e]);
                double tt = mcf__dot3(tan, tan), a = tt > 0.0 ? mcf__dot3(d, tan) / tt : 0.0;
                for (int e = 0; e < 3; e++)
                    P[3 * (size_t)i + e] += d[e] - a * tan[e];
            }
        }
    memcpy(X, P, 3 * sizeof(double) * (size_t)nv);
}

int mcf__creases_smooth(const mcf__graph *g, int nv, const unsigned char *fixed, const unsigned char *chains,
                        double *X)
{
    double *P = mcf__malloc(3 * (size_t)nv, sizeof(double)), *tmp = mcf__malloc(3 * (size_t)nv, sizeof(double));
    int *cdeg = mcf__calloc((size_t)nv + 1, sizeof(int)), rc = P && tmp && cdeg ? 0 : -1;
    if (rc == 0) {
        for (int a = 0; a < nv; a++)
            for (int t = g->ptr[a]; t < g->ptr[a + 1]; t++)
                cdeg[a] += chains[t];
        smooth_chains(g, nv, fixed, chains, cdeg, X, P, tmp);
    }
    free(P);
    free(tmp);
    free(cdeg);
    return rc;
}

/* The stages' shares of the time (tick), measured on the 435k dragon
 * (2026-11-28, 2 loaded cores: 1.10 s, 0.47 s, about 0.15 s): the 10
 * Taubin passes, the sharp edges and chains; the chains' smoothing the
 * rest. */
#define CREASE_TICK_PASSES 0.65
#define CREASE_TICK_CHAINS 0.9
int mcf__creases(const mcf__graph *g, const int32_t *F, int nf, int nv,
                 const unsigned char *fixed, double *X, unsigned char *crease, unsigned char *chains,
                 const mcf__tick *tick)
{
    int ne = g->ptr[nv], ncrease = 0;
    double *P = mcf__malloc(3 * (size_t)nv, sizeof(double)), *tmp = mcf__malloc(3 * (size_t)nv, sizeof(double));
    double *fn = mcf__malloc(3 * (size_t)nf, sizeof(double));
    int *f1 = mcf__malloc((size_t)ne + 1, sizeof(int)), *cnt = mcf__calloc((size_t)ne + 1, sizeof(int));
    int *up = mcf__malloc((size_t)nv, sizeof(int)), *size = mcf__calloc((size_t)nv, sizeof(int));
    unsigned char *ce = mcf__calloc((size_t)ne + 1, 1);
    int *cdeg = mcf__calloc((size_t)nv, sizeof(int));
    if (!P || !tmp || !fn || !f1 || !cnt || !up || !size || !ce || !cdeg) {
        ncrease = -1;
        goto done;
    }
    /* the unit face normals of X smoothed by 10 Taubin passes */
    memcpy(P, X, 3 * sizeof(double) * (size_t)nv);
    mcf__graph_taubin(g, fixed, P, 3, 10, tmp, 1, NULL);
    mcf__ticked(tick, "creases", CREASE_TICK_PASSES);
    mcf__face_normals(P, F, nf, fn);
    for (int f = 0; f < nf; f++) {
        double *n = fn + 3 * (size_t)f;
        double l = sqrt(mcf__dot3(n, n));
        for (int e = 0; e < 3; e++)
            n[e] = l > 0.0 ? n[e] / l : 0.0;
    }
    sharp_edges(g, F, nf, fn, f1, cnt, ce);
    keep_chains(g, nv, cnt, ce, up, size, cdeg);
    mcf__ticked(tick, "creases", CREASE_TICK_CHAINS);
    for (int i = 0; i < nv; i++) {
        crease[i] = cdeg[i] > 0;
        ncrease += crease[i];
    }
    if (ncrease > 0)
        smooth_chains(g, nv, fixed, ce, cdeg, X, P, tmp);
    if (chains)
        memcpy(chains, ce, (size_t)ne);
done:
    free(P);
    free(tmp);
    free(fn);
    free(f1);
    free(cnt);
    free(up);
    free(size);
    free(ce);
    free(cdeg);
    return ncrease;
}
