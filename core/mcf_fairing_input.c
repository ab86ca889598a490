/* SPDX-License-Identifier: MIT */
/*
 * mcf_fairing_input.c - what the default request reads of its input
 * before any filter runs (mcf_fairing.c): whether the positions are
 * exact (a CAD part's flat faces: FLAT_SHARE), whether they sit on a
 * grid whose rounding explains the noise (mcf__lattice:
 * LATTICE_EXPLAINS), and, on neither, its spikes repaired in a copy
 * (mcf_spikes.c). docs/fairing.md, "Outliers" and "Quantized positions".
 *
 * Pure C11; no globals.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_fairing_ctx.h"

/* The positions are exact, no noise to read (the filter's plan reads
 * none, as past WHITE_GAP in mcf_fairing.c), when at least FLAT_SHARE of
 * the free vertices have their 1-ring exactly in the plane through them (every neighbour within FLAT_TOL mean
 * edges of it along the vertex normal): noise leaves no vertex there, an
 * exact model (a CAD part's flat faces) or a grid (quantized positions)
 * leaves many. Measured (2026-11-28, make quality's noise, seed 1, share
 * at 1e-6 h): the clean couplingdown_sub2.obj 0.505, whose high-pass gap
 * (0.057) passed WHITE_GAP and which the default moved by 0.269 of the
 * error of 0.1 h noise (the feature stage reading 0.049 h); blade.obj
 * 0.149, car.drc 0.010 (the default leaves both within 0.02); Gaussian
 * noise of 0.1 h along the normals 0 on every CAD part; the organic
 * meshes clean or quantized 0-0.6% (knot1 at quant 0.5: 3.3%). Quantized
 * CAD parts pass it too (couplingdown_sub2 at 0.1/0.25/0.5 h: 0.36, 0.51,
 * 0.68; car 0.23-0.70, blade 0.86-0.97): they came back as they came,
 * where the default had returned 0.93-1.00 of their error (car and
 * blade 1.00) and, on couplingdown_sub2, faces turned against the clean
 * mesh; their grid is now read first (LATTICE_EXPLAINS). The spike
 * stage leaves such a mesh alone too (it had repaired 6 "spikes" of
 * couplingdown_sub2 quantized to 0.25 h, turning a face). */
#define FLAT_SHARE 0.25
#define FLAT_TOL 1e-6
/* Quantized positions: when the free vertices' coordinates sit on a grid
 * of steps q (mcf__lattice, read off the positions alone) and the
 * high-pass reads at most LATTICE_EXPLAINS times the grid's own noise,
 * that noise is the noise: rounding to a grid of step q leaves an error
 * uniform on [-q/2, q/2] per coordinate, deviation q / sqrt(12) along
 * any direction (the normal, each tangent) and known, where FLAT_SHARE
 * and WHITE_GAP had read none (couplingdown_sub2.obj, blade.obj, car.drc
 * quantized: the input came back). The output is then clipped into each
 * vertex's cell (mcf__lattice_clip). A grid under noise of another
 * kind reads far above its own (a scan stored with 4 decimals: q
 * 1e-4 units), and is left alone. Measured (2026-11-29, make quality's
 * quant, seed 1, clean mean edges, median reading over q / sqrt(12)):
 * 0.5-1.2 on spot, couplingdown_sub2, car.drc at 0.25 and 0.5 h, 2.2 on
 * car.drc at 0.1 h (its own high-pass 0.055 h), blade.obj 0.003 (its
 * plates on the grid's planes); clean blade.obj (coordinates written to
 * 0.01: q 0.0077 h) 1.3 */
#define LATTICE_EXPLAINS 3.0

/* The noise of rounding to the grid of steps q along any direction:
 * q_d / sqrt(12) per axis, their RMS over the axes (one level for the
 * normals and the tangents, whichever way they point) */
double mcf__fair_grid_level(const double q[3])
{
    return sqrt((q[0] * q[0] + q[1] * q[1] + q[2] * q[2]) / 36.0);
}

/* The steps of the grid X's free vertices sit on (mcf__lattice) into
 * grid, when the high-pass reads at most LATTICE_EXPLAINS times its noise
 * (grid_level); else zeros. ENOMEM only. */
static mcf_status read_grid(const mcf__graph *g, const double *X, const int32_t *F, int nf, int nv,
                            const unsigned char *fixed, double hbar, double grid[3], mcf_error *err)
{
    double s_est = 0.0;
    mcf_status rc;
    int found = mcf__lattice(X, nv, fixed, hbar, grid);
    if (found < 0)
        return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d vertices)", nv);
    if (found && (rc = mcf__noise_levels(g, X, F, nf, nv, fixed, &s_est, NULL, NULL, NULL, err)) != MCF_OK)
        return rc;
    if (found && !(s_est <= LATTICE_EXPLAINS * mcf__fair_grid_level(grid)))
        grid[0] = grid[1] = grid[2] = 0.0;
    return MCF_OK;
}

/* Whether X's positions are exact (FLAT_SHARE) into *exact; if not, and
 * they are not on a grid (grid), the spikes of X repaired in a copy (*Xs;
 * NULL when there are none), their count into st->spikes_repaired.
 * ENOMEM only. */
static mcf_status repair_spikes(const mcf__graph *g, const double *X, const int32_t *F, int nf, int nv,
                                const unsigned char *fixed, double hbar, int grid, mcf_flow_stats *st, double **Xs,
                                int *exact, mcf_error *err)
{
    double *Y = mcf__malloc(3 * (size_t)nv, sizeof(double));
    int n = -1;
    if (Y) {
        mcf__vertex_normals(X, F, nf, nv, Y);
        *exact = mcf__flat_share(g, X, Y, fixed, FLAT_TOL * hbar) >= FLAT_SHARE;
        memcpy(Y, X, 3 * sizeof(double) * (size_t)nv);
        n = *exact || grid ? 0 : mcf__spikes(g, F, nf, fixed, hbar, Y);
    }
    if (n < 0) {
        free(Y);
        return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d vertices)", nv);
    }
    st->spikes_repaired = n;
    if (n == 0)
        free(Y);
    *Xs = n > 0 ? Y : NULL;
    return MCF_OK;
}

mcf_status mcf__fair_read_input(const mcf__graph *g, const double *X, const int32_t *F, int nf, int nv,
                                const unsigned char *fixed, double hbar, double grid[3], int *exact,
                                mcf_flow_stats *st, double **Xs, mcf_error *err)
{
    mcf_status rc = read_grid(g, X, F, nf, nv, fixed, hbar, grid, err);
    if (rc != MCF_OK)
        return rc;
    return repair_spikes(g, X, F, nf, nv, fixed, hbar, grid[0] > 0.0, st, Xs, exact, err);
}
