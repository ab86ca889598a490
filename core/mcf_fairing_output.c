/* SPDX-License-Identifier: MIT */
/*
 * mcf_fairing_output.c - the fairing filter's result (docs/fairing.md,
 * "The output", "How far a vertex may move", "The fold guard"): the
 * filtered displacement along the normals of the filtered surface, its
 * tangential relaxation back onto that surface, the bounds on a move from
 * the input, and the guard's positions for mcf__unfold. The run's state:
 * mcf_fairing_ctx.h.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_fairing_ctx.h"

/* the largest move of a vertex from the input, in noise levels: Gaussian
 * noise moves a vertex further than 3 of its deviations along the normal
 * once in 370; a filter that moves it further takes away shape (the
 * coarse car.drc, noise 0.1 mean edges: error 2.63x the input's without
 * the two bounds, 1.31x with them; snowden (seed 1) and dragon_vrip_res2
 * (seed 2) at 0.1: 0.573 -> 0.547 and 0.561 -> 0.547 of the input's; no
 * shared scan worse, 8 meshes x 3 levels of noise along the normals and
 * 3 meshes x 3 isotropic measured; 4 deviations: car 1.46x). Beyond it a
 * move is taken back linearly, to none at MAX_MOVE (1 + MOVE_TAPER): a
 * move that long is a feature the filter removes, which clamping keeps
 * removing by MAX_MOVE (car.drc, isotropic noise 0.1, seeds 2-3: 1.010
 * and 1.024 of the input's error clamped, 0.988 and 0.996 tapered) */
#define MAX_MOVE 3.0
#define MOVE_TAPER 2.0
/* the guard's positions move a vertex along the surface by at most one
 * noise level (guard_positions) */
#define GUARD_TANGENTIAL 1.0

/* The tangential relaxation: every free vertex of X moves by the part of
 * Yt - X0 in its tangent plane (normals N), then back onto the surface X
 * had: to the closest point of the faces around it and its neighbours.
 * ENOMEM only. */
static mcf_status tangential_output(fair_ctx *c, const double *Yt, const double *N, double *X,
                                    mcf_error *err)
{
    int nv = c->nv;
    int *vp = mcf__calloc((size_t)nv + 1, sizeof(int)), *vf = mcf__malloc(3 * (size_t)c->nf + 1, sizeof(int));
    double *S = mcf__malloc(3 * (size_t)nv, sizeof(double));
    c->bytes += sizeof(int) * (4 * (size_t)nv + 3 * (size_t)c->nf);
    if (!vp || !vf || !S) {
        free(vp);
        free(vf);
        free(S);
        return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d faces)", c->nf);
    }
    for (size_t q = 0; q < 3 * (size_t)c->nf; q++)
        vp[c->F[q] + 1]++;
    for (int i = 0; i < nv; i++)
        vp[i + 1] += vp[i];
    for (int f = 0; f < c->nf; f++)
        for (int k = 0; k < 3; k++)
            vf[vp[c->F[3 * f + k]]++] = f;
    for (int i = nv; i > 0; i--)
        vp[i] = vp[i - 1];
    vp[0] = 0;
    memcpy(S, X, 3 * sizeof(double) * (size_t)nv);
    for (int k = 0; k < c->nfree; k++) {
        int i = c->vert[k];
        const double *n = N + 3 * (size_t)i;
        double d[3], p[3], best = INFINITY, q[3], bq[3];
        mcf__sub3(Yt + 3 * (size_t)i, c->X0 + 3 * (size_t)i, d);
        double a = mcf__dot3(n, d);
        for (int e = 0; e < 3; e++)
            p[e] = S[3 * (size_t)i + e] + d[e] - a * n[e];
        memcpy(bq, S + 3 * (size_t)i, 3 * sizeof(double));
        for (int t = c->g.ptr[i] - 1; t < c->g.ptr[i + 1]; t++) {
            int v = t < c->g.ptr[i] ? i : c->g.adj[t];
            for (int r = vp[v]; r < vp[v + 1]; r++) {
                const int32_t *tri = c->F + 3 * (size_t)vf[r];
                mcf__closest_on_triangle(p, S + 3 * (size_t)tri[0], S + 3 * (size_t)tri[1], S + 3 * (size_t)tri[2], q);
                double e3[3];
                mcf__sub3(q, p, e3);
                double dd = mcf__dot3(e3, e3);
                if (dd < best) {
                    best = dd;
                    memcpy(bq, q, sizeof q);
                }
            }
        }
        memcpy(X + 3 * (size_t)i, bq, sizeof bq);
    }
    free(vp);
    free(vf);
    free(S);
    return MCF_OK;
}

/* X = X0 + n <n, Y - X0> on the free vertices, n the normals of Y, into
 * X; N (3*nv) gets those normals. */
static void normal_output(fair_ctx *c, const double *Y, double *X, double *N)
{
    mcf__vertex_normals(Y, c->F, c->nf, c->nv, N);
    memcpy(X, c->X0, 3 * sizeof(double) * (size_t)c->nv);
    for (int k = 0; k < c->nfree; k++) {
        size_t i = (size_t)c->vert[k];
        double d[3];
        mcf__sub3(Y + 3 * i, c->X0 + 3 * i, d);
        double a = mcf__dot3(N + 3 * i, d);
        for (int e = 0; e < 3; e++)
            X[3 * i + e] += a * N[3 * i + e];
    }
}

/* Moves from the input longer than rmax taken back (the noise does not
 * move a vertex that far: what the filter takes beyond it is the shape):
 * a move of length l > rmax to rmax - (l - rmax) / MOVE_TAPER, none
 * from rmax (1 + MOVE_TAPER) on; on the vertices marked in only (NULL:
 * all). */
void mcf__fair_clamp_moves(const fair_ctx *c, double *X, double rmax, const unsigned char *only)
{
    mcf__fair_clamp_from(c, c->Xin, X, rmax, only);
}

void mcf__fair_clamp_from(const fair_ctx *c, const double *ref, double *X, double rmax, const unsigned char *only)
{
    for (int i = 0; i < c->nv; i++) {
        if (only && !only[i])
            continue;
        double d[3], *x = X + 3 * (size_t)i;
        const double *x0 = ref + 3 * (size_t)i;
        mcf__sub3(x, x0, d);
        double l = sqrt(mcf__dot3(d, d));
        if (l > rmax)
            for (int e = 0; e < 3; e++)
                x[e] = x0[e] + d[e] * (fmax(0.0, rmax - (l - rmax) / MOVE_TAPER) / l);
    }
}

/* The guard's first positions, into c->Ybest: Y's displacement along
 * the input's normals (what SURE judged) and its part along the surface
 * up to GUARD_TANGENTIAL noise levels. Y's own positions, whose uniform
 * Laplacian slides vertices along long thin triangles, moved car.drc's
 * vertices by up to MAX_MOVE along the surface (noise 0.25 along the
 * normals, seed 1: 1.03x the input's error; 0.96x with this); without any
 * tangential part spot at noise 0.5 (seeds 1-3) kept 11, 14 and 3 more
 * faces against the clean mesh's than the input (4, -6, -17 with Y's;
 * 4, -7, -8 with this). */
static void guard_positions(fair_ctx *c)
{
    double tmax = GUARD_TANGENTIAL * c->s;
    for (int k = 0; k < c->nfree; k++) {
        size_t i = (size_t)c->vert[k];
        const double *n = c->n0 + 3 * i;
        double d[3], t[3];
        mcf__sub3(c->Ybest + 3 * i, c->X0 + 3 * i, d);
        double a = mcf__dot3(n, d);
        for (int e = 0; e < 3; e++)
            t[e] = d[e] - a * n[e];
        double tl = sqrt(mcf__dot3(t, t)), f = tl > tmax ? tmax / tl : 1.0;
        for (int e = 0; e < 3; e++)
            c->Ybest[3 * i + e] = c->X0[3 * i + e] + a * n[e] + f * t[e];
    }
}

/* The output into X: along the normals of the filtered surface, relaxed
 * in its tangent planes, clamped, guarded. */
mcf_status mcf__fair_output(fair_ctx *c, double *X, mcf_error *err)
{
    int nv = c->nv, nf = c->nf, left;
    double s = c->s, s_t = c->s_t;
    mcf_flow_stats *st = c->st;
    mcf_status rc;
    if (c->kbest == 0 && c->kbest_t == 0) {
        /* nothing to remove: the input as it came (crease vertices too) */
        memcpy(X, c->Xin, 3 * sizeof(double) * (size_t)nv);
        return MCF_OK;
    }
    normal_output(c, c->Ybest, X, c->Y);
    if (c->kbest_t > 0 && (rc = tangential_output(c, c->Yt, c->Y, X, err)) != MCF_OK)
        return rc;
    guard_positions(c);
    /* no vertex moves further than MAX_MOVE noise levels (normal, and
     * both tangential parts when the result takes a tangential step)
     * from the input, nor do the guard's positions */
    double rmax = MAX_MOVE * sqrt(s * s + (c->kbest_t > 0 ? 2.0 * s_t * s_t : 0.0));
    if (rmax > 0.0) {
        mcf__fair_clamp_moves(c, X, rmax, NULL);
        mcf__fair_clamp_moves(c, c->Ybest, rmax, NULL);
    }
    /* quantized positions: each vertex within the cell of its grid point
     * (mcf__lattice_clip: the truth is there, and no vertex ends further
     * from it) */
    if (c->grid[0] > 0.0) {
        mcf__lattice_clip(X, c->Xin, nv, NULL, c->grid);
        mcf__lattice_clip(c->Ybest, c->Xin, nv, NULL, c->grid);
    }
    /* the faces the input had without area, turned by the output against
     * the filtered normals (c->Y: Y's normals), taken back (mcf_flips.c) */
    int flip_moves;
    if (c->p->fairing_robust && (rc = mcf__flips_repair(X, c->Xin, c->Y, c->F, nf, nv, c->grid[0] > 0.0, &st->flips_repaired,
                                                        &flip_moves, err)) != MCF_OK)
        return rc;
    /* the faces turned against the output's smoothed normal field: the
     * slides along the surface taken back where that turns fewer
     * (mcf_turned.c) */
    if (c->p->fairing_robust &&
        (rc = mcf__turned_repair(X, c->Xin, c->F, nf, nv, &st->turned_repaired, err)) != MCF_OK)
        return rc;
    if ((rc = mcf__unfold(X, c->Xin, c->fn_orig, c->Ybest, c->F, nf, nv, &st->guard_rounds, &st->guard_vertices,
                          &left, err)) != MCF_OK)
        return rc;
    c->bytes += (6 * sizeof(double) + 1) * (size_t)nf + (3 * sizeof(double) + 1) * (size_t)nv;
    return MCF_OK;
}

mcf_status mcf__fair_feature_output(fair_ctx *c, const double *Yf, const unsigned char *fixed, double sf, double *X,
                                    mcf_error *err)
{
    return mcf__feature_output(c->Xin, c->fn_orig, Yf, c->F, c->nf, c->nv, fixed, MAX_MOVE * sf,
                               c->grid[0] > 0.0 ? c->grid : NULL,
                               c->p->fairing_robust ? &c->st->flips_repaired : NULL,
                               c->p->fairing_robust ? &c->st->turned_repaired : NULL, X, &c->st->guard_rounds,
                               &c->st->guard_vertices, err);
}
