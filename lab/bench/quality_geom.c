/* SPDX-License-Identifier: MIT */
/*
 * quality_geom.c - the geometry make quality measures results with
 * (quality_geom.h): the clean mesh's creases, faces turned against the
 * clean mesh, and the symmetric RMS point-to-surface distance on a
 * uniform grid of triangles.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "quality_geom.h"

/* The clean mesh's own near-reversals: mask[f] = 1 when face f shares an
 * edge with a face whose normal is turned by more than 120 degrees from
 * its own, or has an edge with more than two faces. Models like snowden
 * (thin fins, fold-overs) and the crudely decimated dragon have thousands;
 * any smoothing flattens them, which turns such faces by over 90 degrees
 * against the clean normals, so the folds there are counted apart. */
typedef struct {
    int a, b, f;
} edge_ref;

static int cmp_edge(const void *x, const void *y)
{
    const edge_ref *p = x, *q = y;
    return p->a != q->a ? (p->a > q->a) - (p->a < q->a) : (p->b > q->b) - (p->b < q->b);
}

void qg_face_normal(const double *X, const int32_t *t, double n[3])
{
    const double *p = X + 3 * (size_t)t[0], *q = X + 3 * (size_t)t[1], *r = X + 3 * (size_t)t[2];
    double u[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]}, v[3] = {r[0] - p[0], r[1] - p[1], r[2] - p[2]};
    n[0] = u[1] * v[2] - u[2] * v[1];
    n[1] = u[2] * v[0] - u[0] * v[2];
    n[2] = u[0] * v[1] - u[1] * v[0];
}

unsigned char *qg_crease_mask(const mcf_mesh *m, int *count)
{
    int nf = mcf_mesh_nfaces(m);
    const int32_t *F = mcf_mesh_faces(m);
    const double *X = mcf_mesh_positions(m);
    edge_ref *E = malloc(3 * (size_t)nf * sizeof *E);
    unsigned char *mask = calloc((size_t)nf, 1);
    if (!E || !mask) {
        fprintf(stderr, "quality: out of memory\n");
        exit(1);
    }
    for (int f = 0; f < nf; f++)
        for (int k = 0; k < 3; k++) {
            int a = F[3 * f + k], b = F[3 * f + (k + 1) % 3];
            E[3 * f + k] = (edge_ref){a < b ? a : b, a < b ? b : a, f};
        }
    qsort(E, 3 * (size_t)nf, sizeof *E, cmp_edge);
    for (size_t i = 0, j; i < 3 * (size_t)nf; i = j) {
        for (j = i + 1; j < 3 * (size_t)nf && E[j].a == E[i].a && E[j].b == E[i].b; j++)
            ;
        if (j - i > 2)
            for (size_t k = i; k < j; k++)
                mask[E[k].f] = 1;
        else if (j - i == 2) {
            double n1[3], n2[3];
            qg_face_normal(X, F + 3 * E[i].f, n1);
            qg_face_normal(X, F + 3 * E[i + 1].f, n2);
            double d = n1[0] * n2[0] + n1[1] * n2[1] + n1[2] * n2[2];
            double l = sqrt((n1[0] * n1[0] + n1[1] * n1[1] + n1[2] * n1[2]) *
                            (n2[0] * n2[0] + n2[1] * n2[1] + n2[2] * n2[2]));
            if (l > 0 && d < -0.5 * l)
                mask[E[i].f] = mask[E[i + 1].f] = 1;
        }
    }
    free(E);
    *count = 0;
    for (int f = 0; f < nf; f++)
        *count += mask[f];
    return mask;
}

/* Faces of x inverted against target (normals more than 90 degrees apart,
 * as mcf_compare counts them) that are not in the crease mask. */
int qg_inverted_off_crease(const mcf_mesh *x, const mcf_mesh *target, const unsigned char *mask)
{
    int nf = mcf_mesh_nfaces(x), n = 0;
    const int32_t *F = mcf_mesh_faces(x);
    for (int f = 0; f < nf; f++) {
        double a[3], b[3];
        if (mask[f])
            continue;
        qg_face_normal(mcf_mesh_positions(x), F + 3 * f, a);
        qg_face_normal(mcf_mesh_positions(target), F + 3 * f, b);
        double la = a[0] * a[0] + a[1] * a[1] + a[2] * a[2], lb = b[0] * b[0] + b[1] * b[1] + b[2] * b[2];
        if (la > 0 && lb > 0 && a[0] * b[0] + a[1] * b[1] + a[2] * b[2] < 0)
            n++;
    }
    return n;
}


/* ------------------------------------------------- surface distance */


static int clampi(int v, int lo, int hi)
{
    return v < lo ? lo : v > hi ? hi : v;
}

void qg_grid_build(qg_grid *g, const mcf_mesh *m)
{
    int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m);
    double hi[3] = {-INFINITY, -INFINITY, -INFINITY}, edge = 0.0;
    g->X = mcf_mesh_positions(m);
    g->F = mcf_mesh_faces(m);
    for (int d = 0; d < 3; d++)
        g->lo[d] = INFINITY;
    for (int i = 0; i < nv; i++)
        for (int d = 0; d < 3; d++) {
            g->lo[d] = fmin(g->lo[d], g->X[3 * i + d]);
            hi[d] = fmax(hi[d], g->X[3 * i + d]);
        }
    for (int f = 0; f < nf; f++) {
        const double *a = g->X + 3 * (size_t)g->F[3 * f], *b = g->X + 3 * (size_t)g->F[3 * f + 1];
        edge += sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
    }
    /* cells of about a mean edge (a few triangles each), at most 2^22 */
    g->cell = fmax(edge / (nf > 0 ? nf : 1), 1e-12);
    for (;;) {
        double cells = 1;
        for (int d = 0; d < 3; d++) {
            g->n[d] = (int)((hi[d] - g->lo[d]) / g->cell) + 1;
            cells *= g->n[d];
        }
        if (cells <= 4194304)
            break;
        g->cell *= 1.5;
    }
    size_t nc = (size_t)g->n[0] * g->n[1] * g->n[2];
    g->start = calloc(nc + 1, sizeof(int));
    int *cnt = NULL;
    for (int pass = 0; pass < 2; pass++) {
        for (int f = 0; f < nf; f++) {
            int b0[3], b1[3];
            for (int d = 0; d < 3; d++) {
                double mn = INFINITY, mx = -INFINITY;
                for (int k = 0; k < 3; k++) {
                    double v = g->X[3 * (size_t)g->F[3 * f + k] + d];
                    mn = fmin(mn, v);
                    mx = fmax(mx, v);
                }
                b0[d] = clampi((int)((mn - g->lo[d]) / g->cell), 0, g->n[d] - 1);
                b1[d] = clampi((int)((mx - g->lo[d]) / g->cell), 0, g->n[d] - 1);
            }
            for (int x = b0[0]; x <= b1[0]; x++)
                for (int y = b0[1]; y <= b1[1]; y++)
                    for (int z = b0[2]; z <= b1[2]; z++) {
                        size_t c = ((size_t)x * g->n[1] + y) * g->n[2] + z;
                        if (pass == 0)
                            g->start[c + 1]++;
                        else
                            g->idx[cnt[c]++] = f;
                    }
        }
        if (pass == 0) {
            for (size_t c = 0; c < nc; c++)
                g->start[c + 1] += g->start[c];
            g->idx = malloc(sizeof(int) * (size_t)(g->start[nc] > 0 ? g->start[nc] : 1));
            cnt = malloc(sizeof(int) * nc);
            if (!g->idx || !cnt) {
                fprintf(stderr, "quality: out of memory (grid)\n");
                exit(1);
            }
            memcpy(cnt, g->start, sizeof(int) * nc);
        }
    }
    free(cnt);
}

void qg_grid_free(qg_grid *g)
{
    free(g->start);
    free(g->idx);
}

/* |a + t e - p|^2 */
static double along2(const double *a, const double *e, double t, const double *p)
{
    double q[3] = {a[0] + t * e[0] - p[0], a[1] + t * e[1] - p[1], a[2] + t * e[2] - p[2]};
    return q[0] * q[0] + q[1] * q[1] + q[2] * q[2];
}

/* Squared distance from p to triangle abc (Ericson, Real-Time Collision
 * Detection, 5.1.5: the closest point by Voronoi regions). */
static double tri_dist2(const double *p, const double *a, const double *b, const double *c)
{
    double ab[3], ac[3], ap[3], q[3];
    for (int d = 0; d < 3; d++) {
        ab[d] = b[d] - a[d];
        ac[d] = c[d] - a[d];
        ap[d] = p[d] - a[d];
    }
#define DOT(u, v) ((u)[0] * (v)[0] + (u)[1] * (v)[1] + (u)[2] * (v)[2])
    double d1 = DOT(ab, ap), d2 = DOT(ac, ap);
    if (d1 <= 0 && d2 <= 0)
        return DOT(ap, ap);
    double bp[3] = {p[0] - b[0], p[1] - b[1], p[2] - b[2]};
    double d3 = DOT(ab, bp), d4 = DOT(ac, bp);
    if (d3 >= 0 && d4 <= d3)
        return DOT(bp, bp);
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0)
        return along2(a, ab, d1 / (d1 - d3), p);
    double cp[3] = {p[0] - c[0], p[1] - c[1], p[2] - c[2]};
    double d5 = DOT(ab, cp), d6 = DOT(ac, cp);
    if (d6 >= 0 && d5 <= d6)
        return DOT(cp, cp);
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0)
        return along2(a, ac, d2 / (d2 - d6), p);
    double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
        double bc[3] = {c[0] - b[0], c[1] - b[1], c[2] - b[2]};
        return along2(b, bc, (d4 - d3) / ((d4 - d3) + (d5 - d6)), p);
    }
    double den = 1.0 / (va + vb + vc), v = vb * den, w = vc * den;
    for (int d = 0; d < 3; d++)
        q[d] = a[d] + ab[d] * v + ac[d] * w - p[d];
    return DOT(q, q);
#undef DOT
}

/* Squared distance from p to the nearest triangle of g: shells of cells
 * around p's cell until the shell lies farther than the best so far. */
static double grid_dist2(const qg_grid *g, const double *p)
{
    int c0[3];
    double margin = INFINITY; /* p's distance to its own cell's nearest face */
    for (int d = 0; d < 3; d++) {
        double u = (p[d] - g->lo[d]) / g->cell;
        c0[d] = clampi((int)floor(u), 0, g->n[d] - 1);
        double fr = u - c0[d];
        margin = fmin(margin, fr < 0 || fr > 1 ? 0.0 : fmin(fr, 1.0 - fr));
    }
    double best = INFINITY;
    int rmax = g->n[0] + g->n[1] + g->n[2];
    for (int r = 0; r <= rmax; r++) {
        /* every cell of shell r lies at least (r - 1 + margin) cells from p */
        double near = (r - 1 + margin) * g->cell;
        if (r > 0 && near > 0 && near * near >= best)
            break;
        for (int x = c0[0] - r; x <= c0[0] + r; x++)
            for (int y = c0[1] - r; y <= c0[1] + r; y++)
                for (int z = c0[2] - r; z <= c0[2] + r; z++) {
                    int dx = abs(x - c0[0]), dy = abs(y - c0[1]), dz = abs(z - c0[2]);
                    int cheb = dx > dy ? (dx > dz ? dx : dz) : (dy > dz ? dy : dz);
                    if (cheb != r || x < 0 || y < 0 || z < 0 || x >= g->n[0] || y >= g->n[1] || z >= g->n[2])
                        continue;
                    size_t c = ((size_t)x * g->n[1] + y) * g->n[2] + z;
                    for (int k = g->start[c]; k < g->start[c + 1]; k++) {
                        const int32_t *t = g->F + 3 * (size_t)g->idx[k];
                        double d2 = tri_dist2(p, g->X + 3 * (size_t)t[0], g->X + 3 * (size_t)t[1],
                                              g->X + 3 * (size_t)t[2]);
                        if (d2 < best)
                            best = d2;
                    }
                }
    }
    return best;
}

/* Area-weighted mean squared distance from the samples of m (vertices,
 * weight area/6 per face corner, and face centroids, area/2) to g's
 * surface. */
static double sampled_ms(const mcf_mesh *m, const qg_grid *g)
{
    const double *X = mcf_mesh_positions(m);
    const int32_t *F = mcf_mesh_faces(m);
    int nf = mcf_mesh_nfaces(m), nv = mcf_mesh_nvertices(m);
    double *w = calloc((size_t)nv, sizeof(double)), s = 0.0, ws = 0.0;
    for (int f = 0; f < nf; f++) {
        const double *a = X + 3 * (size_t)F[3 * f], *b = X + 3 * (size_t)F[3 * f + 1], *c = X + 3 * (size_t)F[3 * f + 2];
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
        double A = 0.5 * sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        double p[3] = {(a[0] + b[0] + c[0]) / 3, (a[1] + b[1] + c[1]) / 3, (a[2] + b[2] + c[2]) / 3};
        s += 0.5 * A * grid_dist2(g, p);
        ws += 0.5 * A;
        for (int k = 0; k < 3; k++)
            w[F[3 * f + k]] += A / 6;
    }
    for (int i = 0; i < nv; i++)
        if (w[i] > 0) {
            s += w[i] * grid_dist2(g, X + 3 * (size_t)i);
            ws += w[i];
        }
    free(w);
    return ws > 0 ? s / ws : 0.0;
}

/* The symmetric RMS surface distance between m and the clean mesh (whose
 * grid is given). */
double qg_surface_error(const mcf_mesh *m, const mcf_mesh *clean, const qg_grid *gclean)
{
    qg_grid gm;
    qg_grid_build(&gm, m);
    double a = sampled_ms(m, gclean), b = sampled_ms(clean, &gm);
    qg_grid_free(&gm);
    return sqrt(0.5 * (a + b));
}


int qg_flips(const mcf_mesh *x, const mcf_mesh *clean)
{
    int nf = mcf_mesh_nfaces(x), n = 0;
    const int32_t *F = mcf_mesh_faces(x);
    for (int f = 0; f < nf; f++) {
        double a[3], b[3];
        qg_face_normal(mcf_mesh_positions(x), F + 3 * f, a);
        qg_face_normal(mcf_mesh_positions(clean), F + 3 * f, b);
        n += a[0] * b[0] + a[1] * b[1] + a[2] * b[2] < 0;
    }
    return n;
}
