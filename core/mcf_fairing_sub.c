/* SPDX-License-Identifier: MIT */
/*
 * mcf_fairing_sub.c - the default request's second look at its creases
 * (docs/fairing.md, "Creases"): the divergence SURE needs at the crease
 * vertices a run held, and the choice between holding them or not judged
 * on the submesh near them instead of two runs over the whole mesh.
 *
 * Why a submesh will do: the run holding the creases and the run with
 * none held are the same linear filter away from the creases (the same
 * input, probes and noise level); their displacements differ only where
 * the crease vertices' difference has spread, a few rings for the
 * Taubin passes SURE stops at, and SURE's pick sums the difference of the
 * two runs' terms over the vertices. Both runs are made again on the
 * vertices within SUB_RINGS rings of a crease vertex (the next ring fixed
 * at the input), and mcf__fair_pick_uncreased judges there; the request
 * then makes the winner's passes over the whole mesh alone. Where the
 * creases are so many that their submesh is most of the mesh (a scan
 * split twice: its original edges), the same is judged near a sample of
 * their chains, which decides only when its verdict is clear. Pure C11,
 * no globals.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_fairing_ctx.h"

/* the step of the divergence's finite difference, in noise levels: the
 * chains' smoothing is linear but for the move bound and the tangent's
 * direction, so a small step reads its slope */
#define CREASE_FD_STEP 0.01
/* The submesh: the vertices within SUB_RINGS rings of a crease vertex
 * move, the ring after it is fixed. Judged there only when the moving
 * vertices are at most SUB_MAX_SHARE of the mesh's (two runs on the
 * submesh then cost less than one more run over the whole). */
#define SUB_RINGS 8
#define SUB_MAX_SHARE 0.4
/* Past SUB_MAX_SHARE, the submesh near a sample of the chains (each chain
 * in or out whole, by a hash of its least vertex: the same sample on every
 * run and thread count), about SUB_SAMPLE_SHARE of the mesh's vertices
 * moving, at most twice that. The sample holds its chains and the other
 * crease vertices move in both runs: it judges "hold these chains or
 * none", and dense creases do not add up (holding all of them cuts the
 * surface into cells that a sample does not), so its z is not the whole
 * mesh's. Measured (2026-11-29, test_look_near_sample's level-4 icosphere
 * jittered and split twice, 40,962 vertices, 1,021-1,087 crease vertices
 * whose submesh is 48-49% of the mesh; eight samples, each another hash):
 * at 0.5 h the whole mesh takes none held and the samples read z -3.7 to
 * +0.9 (three of eight below -3); at 0.25 h it holds them and they read
 * -4.8 to -2.6. So a sample decides only when |z| >= SUB_SAMPLE_Z, over
 * twice the widest miss seen; else the whole mesh judges, both runs in
 * full, as before. The 7M scan (the dragon split twice, noise 0.25 h:
 * 624,479 crease vertices, their submesh 73% of the mesh) reads 93 on its
 * sample (1,474,101 vertices), 194 on the whole mesh: none held. */
#define SUB_SAMPLE_SHARE 0.1
#define SUB_SAMPLE_Z 10.0

/* Each probe's estimate of the divergence SURE needs at the crease
 * vertices of run c (held; n: the same filter with none): their output,
 * the input smoothed along its chains (mcf__creases) with moves bounded
 * by CREASE_MAX_MOVE noise levels, differentiated along the input's
 * normals by a finite difference of CREASE_FD_STEP noise levels with n's
 * probe on those vertices, weighted by n's weights, into kdiv. A fixed
 * value would not do: three Taubin passes along an endless chain have a
 * diagonal of 0.48, a chain's ends 1, and the bound cuts a long move; on
 * the box of test_creases_kept at noise 0.5 (seed 2) a divergence of 1
 * dropped its creases for 0.97x Taubin's oracle (0.93x held), one of 0.5
 * kept the false creases of bunny_npm_closed at 0.25 (error 1.06x the
 * dropped ones'). The chains are those found on the input (the step
 * would move a few edges across the detection's 40 degrees). 0 when out
 * of memory (the run keeps its creases). */
int mcf__fair_crease_divergence(const fair_ctx *c, const fair_ctx *n, const unsigned char *fixed,
                                double kdiv[NPROBE])
{
    size_t nv3 = 3 * (size_t)c->nv;
    double *Xp = mcf__malloc(2 * nv3, sizeof(double)), *ref = Xp + nv3, h = CREASE_FD_STEP * c->s;
    int ok = Xp != NULL;
    for (int q = 0; ok && q < c->nprobe; q++) {
        memcpy(Xp, c->Xin, nv3 * sizeof(double));
        for (int i = 0; i < c->nv; i++)
            if (c->crease[i] && n->fid[i] >= 0) /* fixed in n too: no probe */
                for (int e = 0; e < 3; e++)
                    Xp[3 * (size_t)i + e] += h * n->probe[(size_t)q * n->nfree + n->fid[i]] * n->n0[3 * (size_t)i + e];
        memcpy(ref, Xp, nv3 * sizeof(double));
        ok = mcf__creases_smooth(&c->g, c->nv, fixed, c->chains, Xp) == 0;
        mcf__fair_clamp_from(c, ref, Xp, CREASE_MAX_MOVE * c->s, c->crease);
        kdiv[q] = 0.0;
        for (int i = 0; ok && i < c->nv; i++)
            if (c->crease[i] && n->fid[i] >= 0) {
                double d[3], z = n->probe[(size_t)q * n->nfree + n->fid[i]];
                mcf__sub3(Xp + 3 * (size_t)i, c->X0 + 3 * (size_t)i, d);
                kdiv[q] += n->w[i] * z * mcf__dot3(d, n->n0 + 3 * (size_t)i) / h;
            }
    }
    free(Xp);
    return ok;
}

/* The submesh of c's mesh near its creases, in the mesh's vertex order. */
typedef struct {
    int n, nf;
    int *glob;             /* n: sub -> mesh vertex */
    int *sid;              /* nv: mesh -> sub vertex, -1 outside */
    mcf__graph g;          /* the moving vertices' whole rows; none for the fixed ring */
    int32_t *F;            /* 3*nf: the faces with every corner inside */
    unsigned char *fixed;  /* n: the request's fixed, and the last ring */
    unsigned char *crease; /* n */
    unsigned char *chains; /* g.ptr[n]: c's chain marks on the same edges */
    double *X, *X0;        /* 3*n: the run's input, c's (smoothed along the chains) */
    int *fid;              /* n: c's free index of each (the probes taken) */
} submesh;

static void sub_free(submesh *s)
{
    free(s->glob);
    free(s->sid);
    free(s->g.ptr);
    free(s->g.adj);
    free(s->F);
    free(s->fixed);
    free(s->crease);
    free(s->chains);
    free(s->X);
    free(s->X0);
    free(s->fid);
}

/* The rings around the crease vertices sel marks (c->crease or a sample
 * of them; breadth first on c's graph) into ring (nv, -1 beyond
 * SUB_RINGS + 1); the moving vertices' count. */
static int rings(const fair_ctx *c, const unsigned char *sel, int *ring, int *queue)
{
    int head = 0, tail = 0, moving = 0;
    for (int i = 0; i < c->nv; i++) {
        ring[i] = sel[i] ? 0 : -1;
        if (sel[i])
            queue[tail++] = i;
    }
    while (head < tail) {
        int i = queue[head++];
        moving += ring[i] <= SUB_RINGS;
        if (ring[i] > SUB_RINGS)
            continue;
        for (int e = c->g.ptr[i]; e < c->g.ptr[i + 1]; e++)
            if (ring[c->g.adj[e]] < 0) {
                ring[c->g.adj[e]] = ring[i] + 1;
                queue[tail++] = c->g.adj[e];
            }
    }
    return moving;
}

/* The chains' labels: lab[i] the least vertex of the chain (component of
 * c's chain edges) through crease vertex i, -1 off the creases. */
static void chain_labels(const fair_ctx *c, int *lab)
{
    const mcf__graph *g = &c->g;
    for (int i = 0; i < c->nv; i++)
        lab[i] = i;
    for (int a = 0; a < c->nv; a++)
        for (int t = g->ptr[a]; t < g->ptr[a + 1]; t++)
            if (c->chains[t]) {
                int ra = a, rb = g->adj[t];
                while (lab[ra] != ra)
                    ra = lab[ra] = lab[lab[ra]];
                while (lab[rb] != rb)
                    rb = lab[rb] = lab[lab[rb]];
                if (ra < rb) /* the least vertex stays the root */
                    lab[rb] = ra;
                else
                    lab[ra] = rb;
            }
    for (int i = 0; i < c->nv; i++) {
        int r = i;
        while (lab[r] != r)
            r = lab[r];
        lab[i] = r; /* roots precede: lab[r] is final when i reaches it */
    }
    for (int i = 0; i < c->nv; i++)
        if (!c->crease[i])
            lab[i] = -1;
}

/* A chain's draw in [0, 1): splitmix64 of its least vertex. */
static double chain_draw(int root)
{
    return (double)(mcf__mix64((uint64_t)root + UINT64_C(0x9e3779b97f4a7c15)) >> 11) * 0x1.0p-53;
}

/* The sample: the chains whose draw is below p, marked in sel, ring its
 * submesh; p halved until the moving vertices are at most twice
 * SUB_SAMPLE_SHARE of the mesh (from SUB_SAMPLE_SHARE over the whole
 * submesh's share). The sample's crease vertices, or 0. */
static int sample_chains(const fair_ctx *c, int moving, const int *lab, unsigned char *sel, int *ring, int *queue)
{
    double p = SUB_SAMPLE_SHARE * c->nv / moving;
    for (int round = 0; round < 20; round++, p *= 0.5) {
        int n = 0;
        for (int i = 0; i < c->nv; i++) {
            sel[i] = lab[i] >= 0 && chain_draw(lab[i]) < p;
            n += sel[i];
        }
        if (n == 0)
            return 0;
        if (rings(c, sel, ring, queue) <= 2.0 * SUB_SAMPLE_SHARE * c->nv)
            return n;
    }
    return 0;
}

/* The submesh of the vertices ring marks (its rows, faces, positions and
 * c's crease data on it: the crease vertices and chains sel marks, c's X0
 * on them, the input on the others). 0, or -1 when out of memory. */
static int sub_build(const fair_ctx *c, const int *ring, const unsigned char *sel, const double *X,
                     const unsigned char *fixed, submesh *s)
{
    const mcf__graph *g = &c->g;
    int nv = c->nv, n = 0, nadj = 0, nf = 0;
    for (int i = 0; i < nv; i++)
        if (ring[i] >= 0) {
            n++;
            nadj += ring[i] <= SUB_RINGS ? g->ptr[i + 1] - g->ptr[i] : 0;
        }
    for (int f = 0; f < c->nf; f++)
        nf += ring[c->F[3 * f]] >= 0 && ring[c->F[3 * f + 1]] >= 0 && ring[c->F[3 * f + 2]] >= 0;
    s->n = n;
    s->nf = nf;
    s->g.n = n;
    s->glob = mcf__malloc((size_t)n + 1, sizeof(int));
    s->sid = mcf__malloc((size_t)nv, sizeof(int));
    s->g.ptr = mcf__malloc((size_t)n + 1, sizeof(int));
    s->g.adj = mcf__malloc((size_t)nadj + 1, sizeof(int));
    s->F = mcf__malloc(3 * (size_t)nf + 1, sizeof(int32_t));
    s->fixed = mcf__malloc((size_t)n + 1, 1);
    s->crease = mcf__malloc((size_t)n + 1, 1);
    s->chains = mcf__malloc((size_t)nadj + 1, 1);
    s->X = mcf__malloc(3 * (size_t)n + 1, sizeof(double));
    s->X0 = mcf__malloc(3 * (size_t)n + 1, sizeof(double));
    s->fid = mcf__malloc((size_t)n + 1, sizeof(int));
    if (!s->glob || !s->sid || !s->g.ptr || !s->g.adj || !s->F || !s->fixed || !s->crease || !s->chains || !s->X ||
        !s->X0 || !s->fid)
        return -1;
    for (int i = 0, k = 0; i < nv; i++) {
        s->sid[i] = ring[i] >= 0 ? k : -1;
        if (ring[i] >= 0)
            s->glob[k++] = i;
    }
    /* the rows in the mesh's order, so each stays sorted; a moving
     * vertex's neighbours all lie within SUB_RINGS + 1 rings */
    s->g.ptr[0] = 0;
    for (int k = 0; k < n; k++) {
        int i = s->glob[k], e0 = s->g.ptr[k];
        if (ring[i] <= SUB_RINGS)
            for (int e = g->ptr[i]; e < g->ptr[i + 1]; e++) {
                s->g.adj[e0 + e - g->ptr[i]] = s->sid[g->adj[e]];
                s->chains[e0 + e - g->ptr[i]] = c->chains[e] && sel[i];
            }
        s->g.ptr[k + 1] = e0 + (ring[i] <= SUB_RINGS ? g->ptr[i + 1] - g->ptr[i] : 0);
        s->fixed[k] = fixed[i] || ring[i] > SUB_RINGS;
        s->crease[k] = sel[i];
        s->fid[k] = c->fid[i];
        memcpy(s->X + 3 * (size_t)k, X + 3 * (size_t)i, 3 * sizeof(double));
        memcpy(s->X0 + 3 * (size_t)k, (c->crease[i] && !sel[i] ? c->Xin : c->X0) + 3 * (size_t)i, 3 * sizeof(double));
    }
    for (int f = 0, m = 0; f < c->nf; f++) {
        const int32_t *t = c->F + 3 * (size_t)f;
        if (ring[t[0]] >= 0 && ring[t[1]] >= 0 && ring[t[2]] >= 0) {
            for (int e = 0; e < 3; e++)
                s->F[3 * (size_t)m + e] = s->sid[t[e]];
            m++;
        }
    }
    return 0;
}

mcf_status mcf__fair_judge_near_creases(const fair_ctx *c, const double *X, const unsigned char *fixed,
                                        mcf__step_hook hook, void *hook_ctx, int *judged, int *sampled,
                                        size_t *bytes, mcf_error *err)
{
    submesh s;
    fair_ctx h, u;
    mcf_flow_stats sh, su;
    mcf_status rc = MCF_OK;
    *judged = -1;
    *sampled = 0;
    *bytes = 0;
    int *ring = mcf__malloc((size_t)c->nv, sizeof(int)), *queue = mcf__malloc((size_t)c->nv, sizeof(int));
    unsigned char *sel = NULL;
    if (!ring || !queue) {
        free(ring);
        free(queue);
        return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d vertices)", c->nv);
    }
    int moving = rings(c, c->crease, ring, queue);
    if (moving > SUB_MAX_SHARE * c->nv) {
        /* judged near a sample of the chains */
        int *lab = mcf__malloc((size_t)c->nv, sizeof(int));
        sel = mcf__malloc((size_t)c->nv, 1);
        if (lab && sel) {
            chain_labels(c, lab);
            *sampled = sample_chains(c, moving, lab, sel, ring, queue) > 0;
        }
        free(lab);
        if (!*sampled) {
            free(sel);
            free(ring);
            free(queue);
            return MCF_OK;
        }
        *bytes = (size_t)c->nv * (sizeof(int) + 1);
    }
    free(queue);
    memset(&s, 0, sizeof s);
    int built = sub_build(c, ring, sel ? sel : c->crease, X, fixed, &s);
    free(ring);
    free(sel);
    if (built != 0) {
        sub_free(&s);
        return mcf__fail(err, MCF_ENOMEM, "fairing: out of memory (%d vertices)", c->nv);
    }
    /* the held run with c's creases, noise levels and probes; then the run
     * with none held, which takes the held run's probes as the request's
     * second look does */
    fair_share like = c->share;
    like.probe = c->probe;
    like.fid = s.fid;
    like.nfree = c->nfree;
    like.nprobe = c->nprobe;
    memset(&h, 0, sizeof h);
    memset(&u, 0, sizeof u);
    memset(&sh, 0, sizeof sh);
    memset(&su, 0, sizeof su);
    h.is_explicit = u.is_explicit = 1;
    h.quiet = u.quiet = 1;
    h.threads_cpu_s = u.threads_cpu_s = c->threads_cpu_s;
    h.exact = u.exact = c->exact;
    h.w0 = h.w1 = u.w0 = u.w1 = c->work_done;
    h.like = &like;
    h.given_crease = s.crease;
    h.given_chains = s.chains;
    h.given_X0 = s.X0;
    rc = mcf__fair_filter_run(&h, &s.g, s.X, s.F, s.nf, s.n, s.fixed, c->p, c->hbar, &sh, hook, hook_ctx, err);
    if (rc == MCF_OK) {
        h.share.probe = h.probe;
        h.share.fid = h.fid;
        h.share.nfree = h.nfree;
        h.share.nprobe = h.nprobe;
        u.like = &h.share;
        u.no_creases = 1;
        rc = mcf__fair_filter_run(&u, &s.g, s.X, s.F, s.nf, s.n, s.fixed, c->p, c->hbar, &su, hook, hook_ctx, err);
    }
    double kdiv[NPROBE], z = NAN;
    if (rc == MCF_OK)
        *judged = mcf__fair_crease_divergence(&h, &u, s.fixed, kdiv) && mcf__fair_pick_uncreased(&h, &u, kdiv, &z);
    if (rc == MCF_OK && *sampled) /* a sample decides only when clear */
        *judged = z >= SUB_SAMPLE_Z ? 1 : z <= -SUB_SAMPLE_Z ? 0 : -1;
    *bytes += h.bytes + u.bytes + (size_t)s.n * (4 * sizeof(int) + 3 + 6 * sizeof(double)) + sizeof(int) * (size_t)c->nv +
             (size_t)s.g.ptr[s.n] * (sizeof(int) + 1) + 3 * sizeof(int32_t) * (size_t)s.nf;
    free(sh.sure);
    free(su.sure);
    mcf__fair_free(&h);
    mcf__fair_free(&u);
    sub_free(&s);
    return rc;
}
