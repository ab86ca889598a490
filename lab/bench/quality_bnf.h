/* SPDX-License-Identifier: MIT */
/*
 * quality_bnf.h - bilateral normal filtering (Zheng, Fu, Au, Tai 2011,
 * "Bilateral Normal Filtering for Mesh Denoising", its local iterative
 * scheme) with the vertex update of Sun, Rosin, Martin, Langbein 2007
 * ("Fast and effective feature-preserving mesh denoising"): a reference
 * anchor of make quality, outside the product. Definitions in
 * quality_bnf.c's header comment; checked against an independent numpy
 * implementation by lab/tests/test_quality.c.
 */
#ifndef QUALITY_BNF_H
#define QUALITY_BNF_H

#include "mcf.h"

typedef struct {
    double sigma_r;   /* the range kernel's width on |n_i - n_j| */
    int normal_iters; /* iterations of the normal filter */
    int vertex_iters; /* iterations of the vertex update */
} bnf_params;

/* The oracle's grid (quality_bnf.c): every sigma_r x normal_iters x
 * vertex_iters below. */
#define BNF_NSIGMA 5
#define BNF_NNORMAL 8
#define BNF_NVERTEX 2
extern const double bnf_grid_sigma_r[BNF_NSIGMA];
extern const int bnf_grid_normal[BNF_NNORMAL];
extern const int bnf_grid_vertex[BNF_NVERTEX];

/* Filters m in place with p. movable[i] = 0 keeps vertex i where it is
 * (NULL: every vertex moves). 0, or -1 when memory runs out. */
int bnf_filter(mcf_mesh *m, const unsigned char *movable, const bnf_params *p);

/* The grid point whose result comes closest to clean (mcf_compare's
 * area-weighted RMS vertex error): its parameters in *best and, when out
 * is not NULL, its result in *out (the caller frees it). Each sigma_r's
 * normal iterations run cumulatively and stop once the error is 1.1x that
 * sigma_r's best. 0, or -1 when memory runs out or mcf_compare fails. */
int bnf_oracle(const mcf_mesh *noisy, const mcf_mesh *clean, const unsigned char *movable,
               bnf_params *best, mcf_mesh **out);

#endif
