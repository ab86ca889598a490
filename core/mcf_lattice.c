/* SPDX-License-Identifier: MIT */
/*
 * mcf_lattice.c - quantized positions (docs/fairing.md, "Quantized
 * positions"): the grid the free vertices' coordinates sit on, read off
 * the positions alone, and the projection of a result into the cells the
 * input's grid points stand for.
 */
#include <math.h>
#include <stdlib.h>

#include "mcf_internal.h"

/* Two coordinates within LATTICE_TOL mean edges are one grid level, and a
 * coordinate within it of a level is on the grid. A quantizer writes
 * off + k q in double precision (error ~1e-16 of the coordinate); a mesh
 * stored in single precision (draco) is off by ~1e-7 of its extent, many
 * mean edges' 1e-6, and reads as no grid. */
#define LATTICE_TOL 1e-6
/* at least this share of the free vertices on the grid, on every axis */
#define LATTICE_SHARE 0.99
/* a grid step of at most this many mean edges: a coarser one is a
 * design whose edges join neighbouring grid points (a box of unit squares
 * split by their diagonals: q = 0.88 of its mean edge), not a
 * quantization (make quality's quant at 0.5 h: q 0.48-0.50 of the noisy
 * mesh's mean edge on car.drc, blade.obj, couplingdown_sub2.obj) */
#define LATTICE_MAX_STEP 0.6
/* too few free vertices to tell a grid from chance */
#define LATTICE_MIN_VERTICES 16
/* the values of an evenly spaced sample of at most this many free
 * vertices are read first: a mesh on no grid (nearly every one) leaves
 * after sorting those, not all (three sorts of 7M values cost seconds) */
#define LATTICE_SAMPLE 1024

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The greatest common divisor of a, b > 0 to within tol (Euclid on
 * remainders; a remainder within tol of 0 or of the divisor is none) */
static double fgcd(double a, double b, double tol)
{
    while (b > tol) {
        double r = fmod(a, b);
        if (b - r <= tol)
            r = 0.0;
        a = b;
        b = r;
    }
    return a;
}

/* The grid step of the values v (n, sorted): the greatest common divisor
 * q of the gaps between distinct levels (a mesh coarser than its grid
 * leaves levels empty: blade.obj's rows along its length lie several
 * steps apart), when at least LATTICE_SHARE of the values lie on the
 * levels v[0] + k q; else 0. */
static double axis_step(const double *v, int n, double tol, double max_step)
{
    double q = 0.0;
    for (int i = 1; i < n; i++) {
        double g = v[i] - v[i - 1];
        if (g > tol)
            q = q > 0.0 ? fgcd(q, g, tol) : g;
    }
    if (!(q > 0.0 && q <= max_step) || q < 1000.0 * tol)
        return 0.0; /* one level, or a step no better resolved than tol */
    int on = 0;
    for (int i = 0; i < n; i++)
        on += fabs(v[i] - v[0] - nearbyint((v[i] - v[0]) / q) * q) <= tol;
    return on >= LATTICE_SHARE * n ? q : 0.0;
}

/* Coordinate d of every every-th vertex not fixed into v, sorted; their
 * count. */
static int axis_values(const double *X, int nv, const unsigned char *fixed, int d, int every, double *v)
{
    int n = 0, k = 0;
    for (int i = 0; i < nv; i++)
        if (!(fixed && fixed[i]) && k++ % every == 0)
            v[n++] = X[3 * (size_t)i + d];
    qsort(v, (size_t)n, sizeof(double), cmp_double);
    return n;
}

int mcf__lattice(const double *X, int nv, const unsigned char *fixed, double hbar, double step[3])
{
    step[0] = step[1] = step[2] = 0.0;
    int nfree = 0;
    for (int i = 0; i < nv; i++)
        nfree += !(fixed && fixed[i]);
    if (!(hbar > 0.0) || nfree < LATTICE_MIN_VERTICES)
        return 0;
    double *v = mcf__malloc((size_t)nv + 1, sizeof(double));
    if (!v)
        return -1;
    int found = 1, every = nfree > LATTICE_SAMPLE ? nfree / LATTICE_SAMPLE : 1;
    double tol = LATTICE_TOL * hbar;
    for (int d = 0; d < 3 && found; d++) {
        /* the sample first: its values lie on the grid when all do (their
         * gaps' divisor is a multiple of the grid's; its own may be
         * coarser) */
        int n = axis_values(X, nv, fixed, d, every, v);
        if (!(axis_step(v, n, tol, INFINITY) > 0.0))
            found = 0;
        else
            found = (step[d] = axis_step(v, axis_values(X, nv, fixed, d, 1, v), tol, LATTICE_MAX_STEP * hbar)) > 0.0;
    }
    free(v);
    if (!found)
        step[0] = step[1] = step[2] = 0.0;
    return found;
}

void mcf__lattice_clip(double *X, const double *Xin, int nv, const unsigned char *fixed, const double step[3])
{
    for (int i = 0; i < nv; i++) {
        if (fixed && fixed[i])
            continue;
        for (int d = 0; d < 3; d++) {
            size_t q = 3 * (size_t)i + (size_t)d;
            double h = 0.5 * step[d];
            X[q] = fmin(fmax(X[q], Xin[q] - h), Xin[q] + h);
        }
    }
}
