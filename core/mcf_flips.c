/* SPDX-License-Identifier: MIT */
/*
 * mcf_flips.c - faces the fairing filter gave an orientation the input did
 * not have, checked against the filtered normal field and taken back.
 *
 * A face degenerate in the filter's input (its normal below DEGENERATE
 * times its squared edges: three vertices on one point or one line) has
 * no orientation there; the output invents one. Quantized scans have such
 * faces by the thousand: a grid of step 0.5 mean edges puts 12,751 of
 * couplingdown_sub2's 29,696 vertices on a point another vertex also
 * rounds to, and 26,133 of its 59,424 faces have no area. The output moves
 * each vertex along its own filtered normal, so the members of such a
 * point part along different normals and their faces stand on edge, each
 * facing one way or the other at random: faces facing against the clean
 * mesh's went from the input's 115 to 8,159, all but none of them faces the
 * input had without area (measured 2026-11-28, make quality's quant model,
 * seed 1; the same on stanford-bunny 19 -> 104, 90 of the 94 new ones).
 *
 * Without the clean mesh the test is the filtered surface: such a face of
 * the output is kept when it faces along the filtered normal field, the
 * sum f of the unit normals of the filtered surface Y at its three
 * vertices, by at least TURN (cos(normal, f) >= TURN); a face the output
 * left without area (normal exactly 0) has no orientation and is kept.
 * Every other one is taken back: its vertices that the output moved halve
 * their displacement from the input (HALVINGS rounds), then take the
 * input's positions, where the face is as degenerate as it came. Rounds
 * end when no face is taken back, at most MAX_ROUNDS (each round after
 * the halvings puts at least one more vertex back where it was).
 *
 * On a quantized input (grid, mcf__lattice) the least cosine is
 * FLIPS_TURN_GRID. Faces the input had with an orientation are not judged
 * (the fold guard, mcf_folds.c, judges those against the input) but on a
 * quantized input: there a face of the input that faced along the field
 * and that the output turns against it (cos < 0) is taken back the same
 * way. The output moves a vertex by at most its rounding cell, so a face the
 * grid stood on edge (a sliver whose normal the rounding turned by up to
 * 90 degrees) turns over when one corner moves a fifth of its cell: the
 * fold guard does not see it (turned by less than 90 degrees against the
 * input, along its neighbours in the output). car.drc at quantization 0.5
 * mean edges (make quality's quant, seed 1): one such face, input area
 * 0.033 against 0.017 clean, facing 77 degrees from the clean face, 99
 * from it in the output; taken back, the faces facing against the clean
 * mesh go 54 -> 53 (the input's 53). A mesh without degenerate faces,
 * and not on a grid, comes back unchanged.
 *
 * On a grid an invented orientation must also face within FLIPS_WIDE_GRID of the
 * input's own broad normal there: the input's face normals (area-
 * weighted) summed over the vertices within RINGS rings of the face's
 * corners, each once (none to follow when that sum is 0). Where the grid
 * turns a plate into a staircase that the held creases keep, the
 * filtered field follows the riser, not the plate: blade.obj at
 * quantization 0.5 mean edges (make quality's quant, seed 1) kept two
 * faces of a column the grid collapsed beside the fixed boundary, facing
 * within 25 degrees of the field there and 95 degrees from the clean
 * face (the field 75-80 degrees from it); the input's 3-ring normal is
 * 29 degrees from the clean face and 65-66 degrees from theirs.
 *
 * Pure C11; allocation in mcf__flips_repair and rings_init only.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_internal.h"

/* a face's normal below DEGENERATE times its two squared edges (from its
 * first corner): no orientation (mcf_folds.c's test) */
#define DEGENERATE 1e-10
/* the least cosine between an invented orientation and the filtered
 * normal field: 60 degrees (measured below in mcf__flips_repair) */
#ifndef FLIPS_TURN
#define FLIPS_TURN 0.5
#endif
#define TURN FLIPS_TURN
/* ... on a quantized input (grid): 41 degrees (cosine 0.75). The rim of
 * a thin part, where the surface turns over within a fraction of an edge,
 * collapses onto neighbouring grid levels, and its faces' clean normals
 * lie 44 degrees off the filtered field there: blade.obj rounded to 0.5
 * mean edges (every vertex, offset a third of the step; test_core_lattice)
 * came back with 111 faces facing against the clean mesh (input 0), all
 * of them degenerate in the input and given orientations 46-48 degrees
 * off the field, on the other side of it; now 2 (error 0.714 -> 0.718 of
 * the input's). At 0.7 (45.6 degrees) 2 as well, but make quality's
 * blade.obj at 0.5 h keeps 6 (4 at 0.75); at 0.8 none, but spot.obj at
 * 0.5 h pays 1.3% of error for it (0.6% at 0.75; numpy on the repair's
 * inputs, 2026-11-29) */
#ifndef FLIPS_TURN_GRID
#define FLIPS_TURN_GRID 0.75
#endif
/* ... and on a grid, the least cosine between it and the input's normal
 * summed over RINGS rings: 63 degrees (cosine 0.45). blade.obj's two
 * faces lie at 0.398 and 0.419 in the output before the repair; at 0.4
 * the repair catches the first and the halvings of its corner fix both,
 * at 0.45 both. Measured on the repair's inputs (numpy, make quality's
 * quant at 0.1/0.25/0.5 h on 8 meshes and 0.5 h on 5 more, 2026-11-29):
 * at 0.45 blade.obj 0.5 h 4 -> 2 faces facing against the clean mesh;
 * 0.5 and 0.55 cost blade 3-4 times as much error as 0.45; 2 rings pass
 * them (the riser's own faces), 4 cost bunny_npm_closed 0.5 h as much as
 * spot. A thin part's two sides fall within 3 rings (blade's rim: the sum
 * cancels to 1-17% of its terms' lengths) and a curved one turns within
 * them (spot's: 60-80 degrees off the clean faces): both pay there.
 * bench_quality against main d37d689 (docs/fairing.md, "Quantized
 * positions"): blade 0.5 h 4 -> 2 faces, error 0.7259 -> 0.7264 of the
 * input's; spot 0.5 h 0.6209 -> 0.6213; snowden 0.5 h 0.8139 -> 0.8148
 * (863 -> 847 faces); 19 of the 29 quant cases unchanged */
#ifndef FLIPS_WIDE_GRID
#define FLIPS_WIDE_GRID 0.45
#endif
enum { HALVINGS = 6, MAX_ROUNDS = 64, RINGS = 3 };

/* 1 when triangle t of X has no orientation: its normal n below
 * DEGENERATE times its squared edges. */
static int no_area(const double *X, const int32_t *t, double *n)
{
    double e1[3], e2[3];
    mcf__sub3(X + 3 * (size_t)t[1], X + 3 * (size_t)t[0], e1);
    mcf__sub3(X + 3 * (size_t)t[2], X + 3 * (size_t)t[0], e2);
    mcf__cross3(e1, e2, n);
    double s = DEGENERATE * (mcf__dot3(e1, e1) + mcf__dot3(e2, e2));
    return mcf__dot3(n, n) <= s * s;
}

/* 1 when face t, degenerate in the input, has an orientation in X that
 * does not face along the field (unit vertex normals) by TURN, or does
 * not face along the input's own faces around it (Nin: the input's
 * summed face normals per vertex; none: nothing to follow), or (wide,
 * on a grid: the input's normal over RINGS rings) not within FLIPS_WIDE_GRID
 * of wide (0: nothing to follow). */
static int invented(const double *X, const double *field, const double *Nin, const double *wide, const int32_t *t,
                    double turn)
{
    double n[3], f[3] = {0, 0, 0}, g[3] = {0, 0, 0};
    no_area(X, t, n);
    double nn = mcf__dot3(n, n);
    if (nn == 0.0)
        return 0;
    for (int k = 0; k < 3; k++)
        for (int d = 0; d < 3; d++) {
            f[d] += field[3 * (size_t)t[k] + d];
            g[d] += Nin[3 * (size_t)t[k] + d];
        }
    double ff = mcf__dot3(f, f);
    if (!(mcf__dot3(n, f) >= turn * sqrt(nn * ff)) || !(mcf__dot3(n, g) > 0.0))
        return 1;
    double ww = wide ? mcf__dot3(wide, wide) : 0.0;
    return ww > 0.0 && !(mcf__dot3(n, wide) >= FLIPS_WIDE_GRID * sqrt(nn * ww));
}

/* The faces around each vertex (mcf__vertex_faces' CSR: off[nv + 2],
 * fa[3 nf]) for wide_normal's walk. */
typedef struct {
    int *off, *fa, *stamp, *queue;
} rings;

static int rings_init(rings *r, const int32_t *F, int nf, int nv)
{
    r->off = mcf__calloc((size_t)nv + 2, sizeof(int));
    r->fa = mcf__malloc(3 * (size_t)nf + 1, sizeof(int));
    r->stamp = mcf__calloc((size_t)nv + 1, sizeof(int));
    r->queue = mcf__malloc((size_t)nv + 1, sizeof(int));
    if (!r->off || !r->fa || !r->stamp || !r->queue)
        return 0;
    mcf__vertex_faces(F, nf, nv, r->off, r->fa);
    return 1;
}

static void rings_free(rings *r)
{
    free(r->off);
    free(r->fa);
    free(r->stamp);
    free(r->queue);
}

/* w = the sum of Nin over the vertices within RINGS rings of face t's
 * corners (a vertex sharing a face with one within k - 1 rings is within
 * k), each vertex once; mark is this walk's stamp (unique per call, > 0). */
static void wide_normal(rings *r, const int32_t *F, const double *Nin, const int32_t *t, int mark, double *w)
{
    int head = 0, tail = 0;
    w[0] = w[1] = w[2] = 0.0;
    for (int k = 0; k < 3; k++)
        if (r->stamp[t[k]] != mark) {
            r->stamp[t[k]] = mark;
            r->queue[tail++] = t[k];
        }
    for (int ring = 0; ring < RINGS; ring++) {
        int end = tail;
        for (; head < end; head++) {
            int v = r->queue[head];
            for (int q = r->off[v]; q < r->off[v + 1]; q++)
                for (int k = 0; k < 3; k++) {
                    int u = F[3 * (size_t)r->fa[q] + k];
                    if (r->stamp[u] != mark) {
                        r->stamp[u] = mark;
                        r->queue[tail++] = u;
                    }
                }
        }
    }
    for (int q = 0; q < tail; q++)
        for (int d = 0; d < 3; d++)
            w[d] += Nin[3 * (size_t)r->queue[q] + d];
}

/* 1 when face t faced along the field (unit vertex normals) in X_in and
 * faces against it in X (without area: not against). */
static int turned_over(const double *X, const double *X_in, const double *field, const int32_t *t)
{
    double n[3], nin[3], f[3] = {0, 0, 0};
    no_area(X, t, n);
    no_area(X_in, t, nin);
    for (int k = 0; k < 3; k++)
        for (int d = 0; d < 3; d++)
            f[d] += field[3 * (size_t)t[k] + d];
    return mcf__dot3(nin, f) > 0.0 && mcf__dot3(n, f) < 0.0;
}

/* 1 when the three vertices of t are where the input had them, to the
 * bit: the face is the input's. */
static int at_input(const double *X, const double *X_in, const int32_t *t)
{
    for (int k = 0; k < 3; k++)
        if (memcmp(X + 3 * (size_t)t[k], X_in + 3 * (size_t)t[k], 3 * sizeof(double)) != 0)
            return 0;
    return 1;
}

mcf_status mcf__flips_repair(double *X, const double *X_in, const double *field, const int32_t *F, int nf,
                             int nv, int grid, int *repaired, int *moves, mcf_error *err)
{
    mcf_status rc = MCF_OK;
    *repaired = *moves = 0;
    unsigned char *mark = mcf__calloc((size_t)nv + 1, 1);
    int *list = mcf__malloc((size_t)nf + 1, sizeof(int));
    double *Nin = mcf__calloc(3 * (size_t)nv + 1, sizeof(double));
    /* on a grid, each degenerate face's wide normal (wide_normal), made
     * when the face is first judged with an orientation along the rest */
    rings rg = {0};
    double *wide = NULL;
    unsigned char *has_wide = NULL;
    if (!mark || !list || !Nin)
        goto nomem;
    /* the faces to judge: degenerate in the input (list[0, nw)), then,
     * on a grid, those with an orientation there (list[nw, nl)) */
    int nw = 0, nl;
    for (int f = 0; f < nf; f++) {
        double n[3];
        if (no_area(X_in, F + 3 * (size_t)f, n))
            list[nw++] = f;
    }
    nl = nw;
    if (grid && nw > 0) {
        wide = mcf__malloc(3 * (size_t)nw, sizeof(double));
        has_wide = mcf__calloc((size_t)nw, 1);
        if (!wide || !has_wide || !rings_init(&rg, F, nf, nv))
            goto nomem;
    }
    for (int f = 0; f < nf && grid; f++) {
        double n[3];
        if (!no_area(X_in, F + 3 * (size_t)f, n))
            list[nl++] = f;
    }
    for (int f = 0; f < nf; f++) {
        double n[3];
        no_area(X_in, F + 3 * (size_t)f, n);
        for (int k = 0; k < 3; k++)
            for (int d = 0; d < 3; d++)
                Nin[3 * (size_t)F[3 * f + k] + d] += n[d];
    }
    double turn = grid ? FLIPS_TURN_GRID : TURN;
    for (int round = 0; round < MAX_ROUNDS; round++) {
        int bad = 0, moved = 0;
        for (int q = 0; q < nl; q++) {
            const int32_t *t = F + 3 * (size_t)list[q];
            if (at_input(X, X_in, t))
                continue;
            if (q < nw && wide && !has_wide[q] && !invented(X, field, Nin, NULL, t, turn)) {
                wide_normal(&rg, F, Nin, t, q + 1, wide + 3 * (size_t)q);
                has_wide[q] = 1;
            }
            const double *w = q < nw && wide && has_wide[q] ? wide + 3 * (size_t)q : NULL;
            if (q < nw ? invented(X, field, Nin, w, t, turn) : turned_over(X, X_in, field, t)) {
                bad++;
                for (int k = 0; k < 3; k++)
                    mark[t[k]] = 1;
            }
        }
        if (round == 0)
            *repaired = bad;
        if (bad == 0)
            break;
        for (int i = 0; i < nv; i++) {
            if (!mark[i])
                continue;
            mark[i] = 0;
            double *x = X + 3 * (size_t)i, to[3];
            const double *x0 = X_in + 3 * (size_t)i;
            for (int d = 0; d < 3; d++)
                to[d] = round < HALVINGS ? x0[d] + 0.5 * (x[d] - x0[d]) : x0[d];
            /* a vertex at the input stays (-0.0 + 0.0 would change its bits) */
            if (memcmp(x, x0, sizeof to) != 0 && memcmp(x, to, sizeof to) != 0) {
                memcpy(x, to, sizeof to);
                moved++;
            }
        }
        *moves += moved;
        if (moved == 0)
            break;
    }
    goto done;
nomem:
    rc = mcf__fail(err, MCF_ENOMEM, "flips: out of memory (%d faces)", nf);
done:
    rings_free(&rg);
    free(wide);
    free(has_wide);
    free(Nin);
    free(mark);
    free(list);
    return rc;
}
