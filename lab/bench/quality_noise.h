/* SPDX-License-Identifier: MIT */
/*
 * quality_noise.h - the noise models of make quality (issue 31): what a
 * scanner does to a clean mesh, each seeded and reproducible. Definitions
 * in quality_noise.c's header comment; h is the clean mesh's mean edge
 * (mcf_mesh_inspect), sigma = rho h, and only the vertices a default run
 * moves get noise (the interior: not the boundary, not unreferenced
 * vertices).
 */
#ifndef QUALITY_NOISE_H
#define QUALITY_NOISE_H

#include "mcf.h"

typedef enum {
    QN_NORMAL, /* Gaussian along the vertex normals (mcf_flow_add_noise) */
    QN_ISO,    /* isotropic Gaussian, sigma rho h per coordinate */
    QN_VIEW,   /* Gaussian along one unit vector drawn from the seed */
    QN_CORR,   /* correlated over ~3 edges, along the normals */
    QN_OUT,    /* QN_NORMAL plus 1% spikes of 3-5 h along the normals */
    QN_QUANT,  /* positions rounded to a grid of step rho h */
    QN_CLEAN,  /* no noise (rho 0): what the filter does to a clean mesh */
    QN_COUNT
} qn_model;

/* "normal", "iso", "view", "corr", "out", "quant", "clean". */
const char *qn_name(qn_model k);
/* The model named s, or -1. */
int qn_parse(const char *s);

/* A noisy copy of clean under model k at level rho (mean edges) from the
 * seed; *outliers (when not NULL) receives the spikes QN_OUT placed (0 for
 * the other models). NULL with err filled on a bad argument (rho < 0 or
 * not finite; rho 0 with quant) or out of memory. */
mcf_mesh *qn_make(const mcf_mesh *clean, qn_model k, double rho, int seed, int *outliers,
                  mcf_error *err);

/* moved[i] = 1 for the vertices the models move (nv bytes, caller's):
 * those mcf_flow_add_noise moves with the default parameters, i.e. not the
 * boundary nor unreferenced vertices, nor a vertex whose area-weighted
 * normal is zero. Returns the count, or -1 with err filled. */
int qn_moved(const mcf_mesh *clean, unsigned char *moved, mcf_error *err);

#endif
