/* SPDX-License-Identifier: MIT */
/*
 * mcf_turned.c - the default request's drift repair: faces the fairing
 * filter's output turned against its own smoothed normal field, taken
 * back by moving their vertices along that field only (issue 31, "no
 * mesh comes back with more faces flipped against its true surface than
 * it had").
 *
 * The filter moves each vertex along its own normal (the filtered
 * surface's, or the feature stage's), and where that normal is off the
 * surface's by an angle a, a move of length d also slides the vertex
 * d sin(a) along the surface. On meshes of long thin triangles (blade.obj:
 * median area 0.16 h^2, width about a tenth of the length) a slide of a
 * hundredth of an edge turns a face over. Measured with the clean mesh
 * (2026-11-28, make quality's noise, seed 1; the output's displacement
 * from the input split along the clean vertex normals): with the clean
 * heights and the output's slides, blade.obj at `normal` 0.5 h keeps 1,487
 * of its 1,541 faces facing against the clean mesh, couplingdown_sub2 at
 * 0.5 h 5,814 of 6,656; with the output's heights and the input's places
 * along the surface, 424 and 1,548 (the inputs: 1,098 and 4,084). The
 * slides turn the faces, not the heights.
 *
 * Without the clean mesh: the field m is the output's area-weighted
 * vertex normals averaged over TURN_RINGS rings (each round: a face sums
 * its corners' unit normals, a vertex sums its faces' sums); a face is
 * turned when its normal points against the sum of m at its corners. On
 * the clean blade.obj and couplingdown_sub2.obj no face is; on blade's
 * output at `out` 0.5 h, 85-87% of the faces so found (4 to 8 rings) face
 * against the clean mesh too. A vertex of a turned face moves to X_in + m <m, x - X_in> (its
 * displacement along m only: its place along the surface as the input
 * had it) when that leaves fewer turned faces around it; vertices in
 * index order, each seeing the moves before it, up to TURN_ROUNDS rounds.
 * Projecting every vertex instead, or every vertex of a turned face,
 * undid the filter's tangential relaxation where it had helped (blade.obj
 * `normal` 0.1 h: 118 faces against the clean mesh -> 152-246).
 *
 * Pure C11; allocation in mcf__turned_repair only.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_internal.h"

/* the rings the field is averaged over, and the rounds of moves: measured
 * in mcf__turned_repair's comment (mcf_internal.h) */
enum { TURN_RINGS = 16, TURN_ROUNDS = 4 };

/* v scaled to unit length in place (0 stays 0). */
static void unit(double *v)
{
    double l = sqrt(mcf__dot3(v, v));
    if (l > 0.0)
        for (int e = 0; e < 3; e++)
            v[e] /= l;
}

/* Face f of X turned against the field (fm: per face, the sum of the
 * field at its corners): its normal points against it. A face without
 * area is not. */
static int turned(const double *X, const int32_t *F, const double *fm, int f)
{
    double e1[3], e2[3], n[3];
    const int32_t *t = F + 3 * (size_t)f;
    mcf__sub3(X + 3 * (size_t)t[1], X + 3 * (size_t)t[0], e1);
    mcf__sub3(X + 3 * (size_t)t[2], X + 3 * (size_t)t[0], e2);
    mcf__cross3(e1, e2, n);
    return mcf__dot3(n, fm + 3 * (size_t)f) < 0.0;
}

/* The turned faces among vertex i's (vf[vp[i] .. vp[i + 1])). */
static int turned_around(const double *X, const int32_t *F, const double *fm, const int *vp, const int *vf, int i)
{
    int c = 0;
    for (int r = vp[i]; r < vp[i + 1]; r++)
        c += turned(X, F, fm, vf[r]);
    return c;
}

/* The field m (3*nv) of X: its area-weighted vertex normals averaged
 * over TURN_RINGS rings, unit; W (3*nv) scratch. Each round's sums go
 * into the other buffer (no copy back) and a vertex is scaled to unit
 * where the next round's sums are cleared: the same operations in the
 * same order as a copy and a separate pass, the same numbers bit for
 * bit, for one sweep over the vertices a round instead of three. */
static void field(const double *X, const int32_t *F, int nf, int nv, double *m, double *W)
{
    double *a = m, *b = W;
    memset(a, 0, 3 * sizeof(double) * (size_t)nv);
    for (int f = 0; f < nf; f++) {
        double e1[3], e2[3], n[3];
        const int32_t *t = F + 3 * (size_t)f;
        mcf__sub3(X + 3 * (size_t)t[1], X + 3 * (size_t)t[0], e1);
        mcf__sub3(X + 3 * (size_t)t[2], X + 3 * (size_t)t[0], e2);
        mcf__cross3(e1, e2, n);
        for (int k = 0; k < 3; k++)
            for (int e = 0; e < 3; e++)
                a[3 * (size_t)t[k] + e] += n[e];
    }
    for (int ring = 1; ring < TURN_RINGS; ring++) {
        for (int i = 0; i < nv; i++) {
            unit(a + 3 * (size_t)i);
            b[3 * (size_t)i] = b[3 * (size_t)i + 1] = b[3 * (size_t)i + 2] = 0.0;
        }
        for (int f = 0; f < nf; f++) {
            const int32_t *t = F + 3 * (size_t)f;
            double s[3];
            for (int e = 0; e < 3; e++)
                s[e] = a[3 * (size_t)t[0] + e] + a[3 * (size_t)t[1] + e] + a[3 * (size_t)t[2] + e];
            for (int k = 0; k < 3; k++)
                for (int e = 0; e < 3; e++)
                    b[3 * (size_t)t[k] + e] += s[e];
        }
        double *tmp = a;
        a = b;
        b = tmp;
    }
    for (int i = 0; i < nv; i++)
        unit(a + 3 * (size_t)i);
    if (a != m)
        memcpy(m, a, 3 * sizeof(double) * (size_t)nv);
}

mcf_status mcf__turned_repair(double *X, const double *X_in, const int32_t *F, int nf, int nv, int *moved,
                              mcf_error *err)
{
    double *m = mcf__malloc(3 * (size_t)nv + 1, sizeof(double)), *W = mcf__malloc(3 * (size_t)nv + 1, sizeof(double));
    double *fm = mcf__malloc(3 * (size_t)nf + 1, sizeof(double));
    int *vp = mcf__calloc((size_t)nv + 2, sizeof(int)), *vf = mcf__malloc(3 * (size_t)nf + 1, sizeof(int));
    unsigned char *cand = mcf__malloc((size_t)nv + 1, 1);
    mcf_status rc = MCF_OK;
    *moved = 0;
    if (!m || !W || !fm || !vp || !vf || !cand) {
        rc = mcf__fail(err, MCF_ENOMEM, "turned faces: out of memory (%d faces)", nf);
        goto out;
    }
    field(X, F, nf, nv, m, W);
    for (int f = 0; f < nf; f++)
        for (int e = 0; e < 3; e++)
            fm[3 * (size_t)f + e] = m[3 * (size_t)F[3 * f] + e] + m[3 * (size_t)F[3 * f + 1] + e] +
                                    m[3 * (size_t)F[3 * f + 2] + e];
    mcf__vertex_faces(F, nf, nv, vp, vf);
    for (int round = 0; round < TURN_ROUNDS; round++) {
        int any = 0, acc = 0;
        memset(cand, 0, (size_t)nv);
        for (int f = 0; f < nf; f++)
            if (turned(X, F, fm, f)) {
                any = 1;
                for (int k = 0; k < 3; k++)
                    cand[F[3 * f + k]] = 1;
            }
        if (!any)
            break;
        for (int i = 0; i < nv; i++) {
            if (!cand[i])
                continue;
            double *x = X + 3 * (size_t)i, keep[3], d[3];
            const double *x0 = X_in + 3 * (size_t)i, *mi = m + 3 * (size_t)i;
            mcf__sub3(x, x0, d);
            double a = mcf__dot3(mi, d);
            int before = turned_around(X, F, fm, vp, vf, i);
            memcpy(keep, x, sizeof keep);
            for (int e = 0; e < 3; e++)
                x[e] = x0[e] + a * mi[e];
            if (turned_around(X, F, fm, vp, vf, i) < before)
                acc++;
            else
                memcpy(x, keep, sizeof keep);
        }
        *moved += acc;
        if (acc == 0)
            break;
    }
out:
    free(m);
    free(W);
    free(fm);
    free(vp);
    free(vf);
    free(cand);
    return rc;
}
