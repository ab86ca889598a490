/* SPDX-License-Identifier: MIT */
/*
 * quality_geom.h - what make quality measures a result with, besides
 * mcf_compare: faces flipped against the clean mesh, the clean mesh's own
 * creases (where flips are counted apart), and the symmetric RMS
 * point-to-surface distance. Every function exits the program with a line
 * on stderr when memory runs out (a lab program's policy).
 */
#ifndef QUALITY_GEOM_H
#define QUALITY_GEOM_H

#include <stdint.h>

#include "mcf.h"

/* The unnormalized normal (b - a) x (c - a) of triangle t of positions X
 * (length twice the area). */
void qg_face_normal(const double *X, const int32_t *t, double n[3]);

/* Faces of x (same connectivity as clean) whose normal points against the
 * clean mesh's normal of the same face: dot < 0 (zero-area faces never
 * count). The issue-31 flip count. */
int qg_flips(const mcf_mesh *x, const mcf_mesh *clean);

/* The clean mesh's near-reversals: a malloc'ed mask (nf) with 1 where a
 * face shares an edge with a face turned by more than 120 degrees, or has
 * an edge of more than two faces; *count of them. */
unsigned char *qg_crease_mask(const mcf_mesh *m, int *count);

/* qg_flips of x against target, leaving out the masked faces. */
int qg_inverted_off_crease(const mcf_mesh *x, const mcf_mesh *target, const unsigned char *mask);

/* A uniform grid over the triangles of a mesh: cell c holds the faces
 * whose bounding boxes overlap it (CSR: start[c] .. start[c + 1] of idx).
 * Borrows the mesh's arrays: the mesh outlives the grid. */
typedef struct {
    const double *X;
    const int32_t *F;
    double lo[3], cell;
    int n[3];
    int *start, *idx;
} qg_grid;

void qg_grid_build(qg_grid *g, const mcf_mesh *m);
void qg_grid_free(qg_grid *g);

/* The symmetric RMS surface distance between m and clean (gclean: the
 * clean mesh's grid): samples at the vertices (area/6 per face corner)
 * and face centroids (area/2) of one mesh to the nearest point of the
 * other's triangles, both ways. */
double qg_surface_error(const mcf_mesh *m, const mcf_mesh *clean, const qg_grid *gclean);

#endif
