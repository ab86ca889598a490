/* SPDX-License-Identifier: MIT */
/*
 * mcf_flow.c - the driver of a mean curvature flow run (mcf_flow_run):
 * working units, the fixed set, the amount and the step plan, the step
 * loop with adaptive step control and the explicit schemes' growth check,
 * rescaling, the step log and the result's warnings; the fairing filters
 * run through it too (mcf_fairing.c). The steps themselves are
 * mcf_steps.c's, their operators and solves mcf_flow_ops.c's.
 *
 * All schemes work on positions normalized to unit area about the area
 * centroid (unless normalize is off), so dt and time are dimensionless;
 * the result is mapped back to input units at the end.
 *
 * Workload: meshes up to a few million vertices, tens to thousands of
 * steps; per step the cost is one pass over the faces plus the
 * factorization. No I/O, no globals; one flow_ctx per call.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_flow_ctx.h"

/* ---------------------------------------------------------- driver */

static void ctx_free(flow_ctx *c)
{
    free(c->fixed); free(c->w); free(c->area); free(c->mass);
    free(c->w2); free(c->area2); free(c->mass2);
    free(c->V); free(c->V2); free(c->B); free(c->T1); free(c->T2);
    free(c->Xold); free(c->Xprev); free(c->Xprev2); free(c->fn); free(c->fn2);
    free(c->zero_idx);
    free(c->zero_col);
    mcf__pattern_free(&c->pat);
    free(c->Ax);
    mcf__chol_free(c->chol);
}

/* 1 when some edge may lie on an odd number of faces (a boundary edge
 * lies on one), 0 when none does, -1 when out of memory: every vertex
 * XORs a bijective 64-bit mix of each neighbour once per face side they
 * share, so even multiplicities cancel. A manifold boundary vertex keeps
 * two distinct mixed values, whose XOR is never zero; only three or more
 * odd edges at every odd vertex could cancel, by a 2^-64 chance. Lets
 * explicit schemes skip the pattern on closed meshes. */
static int odd_edges(const flow_ctx *c)
{
    uint64_t *acc = mcf__calloc((size_t)c->nv, sizeof *acc);
    if (!acc)
        return -1;
    for (size_t k = 0; k < 3 * (size_t)c->nf; k += 3)
        for (int e = 0; e < 3; e++) {
            uint64_t a = (uint64_t)c->F[k + e], b = (uint64_t)c->F[k + (e + 1) % 3];
            if (a != b) {
                acc[a] ^= mcf__mix64(b);
                acc[b] ^= mcf__mix64(a);
            }
        }
    int odd = 0;
    for (int i = 0; i < c->nv && !odd; i++)
        odd = acc[i] != 0;
    free(acc);
    return odd;
}

/* Boundary vertices: endpoints of edges used by exactly one face. */
static void mark_boundary(const mcf__pattern *p, unsigned char *fixed)
{
    for (int j = 0; j < p->n; j++)
        for (int t = p->colptr[j]; t < p->colptr[j + 1]; t++)
            if (p->mult[t] == 1)
                fixed[j] = fixed[p->rowind[t]] = 1;
}

/* Adds the vertices no face uses to fixed[] (nv, 0/1 entries). */
static void mark_unreferenced(const int32_t *F, int nf, int nv, unsigned char *fixed)
{
    for (size_t k = 0; k < 3 * (size_t)nf; k++)
        fixed[F[k]] |= 2; /* referenced */
    for (int i = 0; i < nv; i++)
        fixed[i] = fixed[i] != 2; /* fixed already, or unreferenced */
}

/* Marks in fixed[] (nv, zeroed by the caller) what a run with p holds in
 * place: p's list, the boundary vertices with boundary=fixed and the
 * vertices no face uses. ENOMEM only. */
static mcf_status fixed_set(const mcf_mesh *m, const mcf_flow_params *p, unsigned char *fixed,
                            mcf_error *err)
{
    for (int i = 0; i < p->nfixed; i++)
        fixed[p->fixed[i]] = 1;
    if (p->boundary == MCF_BOUNDARY_FIXED) {
        mcf__pattern pat;
        mcf_status rc = mcf__pattern_build(m->F, m->nf, m->nv, 0, &pat, err);
        if (rc != MCF_OK)
            return rc;
        mark_boundary(&pat, fixed);
        mcf__pattern_free(&pat);
    }
    mark_unreferenced(m->F, m->nf, m->nv, fixed);
    return MCF_OK;
}

mcf_status mcf_flow_add_noise(mcf_mesh *m, const mcf_flow_params *p, double rho, uint64_t seed,
                              mcf_error *err)
{
    mcf_status rc;
    if (!m || !p)
        return mcf__fail(err, MCF_EINVAL, "mcf_flow_add_noise: NULL argument");
    if ((rc = mcf_flow_params_check(p, m->nv, err)) != MCF_OK)
        return rc;
    unsigned char *fixed = mcf__calloc((size_t)m->nv, 1);
    double *keep = mcf__malloc(3 * (size_t)m->nv, sizeof(double));
    if (!fixed || !keep) {
        rc = mcf__fail(err, MCF_ENOMEM, "noise: out of memory (%d vertices)", m->nv);
        goto done;
    }
    if ((rc = fixed_set(m, p, fixed, err)) != MCF_OK)
        goto done;
    memcpy(keep, m->X, 3 * sizeof(double) * (size_t)m->nv);
    if ((rc = mcf_mesh_add_noise(m, rho, seed, err)) != MCF_OK)
        goto done;
    for (int i = 0; i < m->nv; i++)
        if (fixed[i])
            memcpy(m->X + 3 * (size_t)i, keep + 3 * (size_t)i, 3 * sizeof(double));
done:
    free(fixed);
    free(keep);
    return rc;
}

mcf_status mcf_noise_estimate(const mcf_mesh *m, const mcf_flow_params *p, double *sigma,
                              mcf_error *err)
{
    mcf_status rc;
    if (!m || !p || !sigma)
        return mcf__fail(err, MCF_EINVAL, "mcf_noise_estimate: NULL argument");
    if ((rc = mcf_flow_params_check(p, m->nv, err)) != MCF_OK)
        return rc;
    unsigned char *fixed = mcf__calloc((size_t)m->nv, 1);
    if (!fixed)
        return mcf__fail(err, MCF_ENOMEM, "noise estimate: out of memory (%d vertices)", m->nv);
    double s = 0.0;
    if ((rc = fixed_set(m, p, fixed, err)) == MCF_OK &&
        (rc = mcf__noise_level(m->X, m->F, m->nf, m->nv, fixed, &s, err)) == MCF_OK)
        *sigma = s;
    free(fixed);
    return rc;
}

/* The log's area and volume are in input units, and the volume is
 * volume0/volume1's (mcf_mesh_volume's): about the input's origin, from
 * the positions mapped back as the run's end maps them. (The working
 * positions are centred on the input's area centroid, and on an open
 * mesh the signed volume depends on that choice.) P: those positions,
 * X / scale + cen, already mapped (the same values: one division per
 * coordinate instead of one per face corner), or NULL. */
static void log_step(flow_ctx *c, const double *X, int k, double t, double h, int rejected,
                     double scale, const double cen[3], double maxdisp, const double *P)
{
    mcf_flow_stats *st = c->st;
    if (!c->p->log_steps || !st->log)
        return;
    mcf_step_log *L = &st->log[k];
    L->t = t;
    L->dt = h;
    double A = 0.0, V = 0.0;
    for (int f = 0; f < c->nf; f++) {
        double p[3][3], e1[3], e2[3], n[3], bd[3];
        for (int q = 0; q < 3; q++)
            for (int d = 0; d < 3; d++) {
                size_t i = 3 * (size_t)c->F[3 * f + q] + (size_t)d;
                p[q][d] = P ? P[i] : X[i] / scale + cen[d];
            }
        mcf__sub3(p[1], p[0], e1);
        mcf__sub3(p[2], p[0], e2);
        mcf__cross3(e1, e2, n);
        A += 0.5 * sqrt(mcf__dot3(n, n));
        mcf__cross3(p[1], p[2], bd);
        V += mcf__dot3(p[0], bd);
    }
    L->area = A;
    L->volume = V / 6.0;
    L->max_disp = maxdisp / scale;
    L->solve_s = c->step_solve_s;
    L->rejected = rejected;
    st->nlog = k + 1;
}

/* The failure of a fixed-step run whose step `step` (1-based) left
 * non-finite positions (grown == 0) or an area grown by `grown`. */
static mcf_status unstable(const flow_ctx *c, mcf_error *err, int step, double h, double grown)
{
    char why[64];
    if (grown > 0.0)
        snprintf(why, sizeof why, "an area %.3g times the initial one", grown);
    else
        snprintf(why, sizeof why, "non-finite positions");
    return mcf__fail(err, MCF_ENUMERIC, "step %d of '%s' at dt %g produced %s%s", step, c->si->name, h, why,
                     c->si->is_explicit ? " (explicit scheme beyond its stability limit: try dt=auto)" : "");
}

/* The warnings of a finished run (result X, input X_in, both in input
 * units). Thresholds, measured on the shared scans with 0.1-0.5 mean
 * edges of injected noise (lab/results/amount.md):
 *  - folds: faces the run folded (mcf__folds_against the input: turned
 *    by more than 90 degrees and lying backwards in their neighbourhood
 *    of the result), over 0.1% of the faces (and at least 3); at useful
 *    amounts a flow folds none to a handful on clean meshes. Counted
 *    face by face: a run that unfolds the noise's folds here and folds
 *    others there is not let off (the count of faces lying backwards,
 *    before and after, netted those out: the fairing guard's Y positions
 *    folded 333 of dragon_vrip_res2's faces at noise 0.1 while that
 *    count fell by 241).
 *  - edge_collapse: the shortest edge shrank more than 1000x; smoothing
 *    noise evens edges out, it never needs to collapse one.
 *  - area_loss: more than 40% of the area lost with rescale off. Noise
 *    inflates the area: removing noise of half a mean edge at the best
 *    amount loses 30-38% of it (snowden 0.62, stanford bunny 0.68).
 *  - little_smoothing: less than 0.1 mean edges of diffusion (t < 0.01
 *    h^2): the result is indistinguishable from the input. */
static void flow_warnings(const flow_ctx *c, const double *X_in, mcf_flow_stats *st)
{
    const mcf_flow_params *p = c->p;
    double me0 = mcf__flow_min_edge(X_in, c->F, c->nf), me1 = mcf__flow_min_edge(c->X, c->F, c->nf);
    int folds = mcf__folds_against(c->X, X_in, c->F, c->nf, c->nv);
    st->folded_faces = folds < 0 ? 0 : folds;
    st->min_edge_ratio = me0 > 0.0 ? me1 / me0 : 1.0;
    st->area_ratio = st->area0 > 0.0 ? st->area1 / st->area0 : 1.0;
    st->strength = st->mean_edge > 0.0 && !mcf__is_fairing(p->scheme) ? sqrt(st->t_final) / st->mean_edge : 0.0;
    if (st->folded_faces >= 3 && st->folded_faces > 1e-3 * c->nf)
        st->warnings |= MCF_WARN_FOLDS;
    if (st->min_edge_ratio < 1e-3)
        st->warnings |= MCF_WARN_EDGE_COLLAPSE;
    if (p->rescale == MCF_RESCALE_NONE && st->area_ratio < 0.6)
        st->warnings |= MCF_WARN_AREA_LOSS;
    /* an automatic amount or a fairing filter that found little noise:
     * the finding, not a warning */
    if (!mcf__is_fairing(p->scheme) && p->scheme != MCF_TAUBIN && !p->strength_auto && st->strength < 0.1)
        st->warnings |= MCF_WARN_LITTLE_SMOOTHING;
}

/* The fairing filter's view of the run (mcf__step_hook): the cancel flag
 * before a step; the step log, the progress callback (t = the step
 * count, dt = 1, energy the log's area, NaN without it) after it. */
typedef struct {
    flow_ctx *c;
    double scale;
    const double *cen;
    double *prev;   /* 3*nv: the positions after the last step */
    double *units;  /* 3*nv: this step's in input units (the log's) */
} fair_hook;

static int fairing_hook(void *ctx, int k, const double *X)
{
    fair_hook *h = ctx;
    flow_ctx *c = h->c;
    const mcf_flow_params *p = c->p;
    if (!X)
        return mcf__cancel_set(p->cancel);
    int logged = p->log_steps && c->st->log && k <= c->st->t_target;
    if (logged) {
        /* one sweep: the largest move, the positions kept for the next
         * step's, and mapped to input units for the log's sums */
        double maxd = 0.0;
        for (size_t i = 0; i < (size_t)c->nv; i++) {
            double d[3];
            mcf__sub3(X + 3 * i, h->prev + 3 * i, d);
            maxd = fmax(maxd, mcf__dot3(d, d));
            for (int e = 0; e < 3; e++) {
                h->prev[3 * i + e] = X[3 * i + e];
                h->units[3 * i + e] = X[3 * i + e] / h->scale + h->cen[e];
            }
        }
        log_step(c, X, k - 1, k, 1.0, 0, h->scale, h->cen, sqrt(maxd), h->units);
    }
    if (!p->progress)
        return 0;
    /* the energy: the log's area (input units) when it has this step; no
     * sweep of its own (mcf_progress_fn) */
    return p->progress(p->progress_ctx, k, k, 1.0, logged ? c->st->log[k - 1].area : NAN);
}

/* mcf_flow_run for the fairing filters, from the normalized positions on:
 * the fixed set, the log, the filter. */
static mcf_status run_fairing(flow_ctx *c, const mcf_mesh *m, double scale, const double cen[3],
                              mcf_error *err)
{
    const mcf_flow_params *p = c->p;
    mcf_flow_stats *st = c->st;
    fair_hook h = {c, scale, cen, NULL, NULL};
    mcf_status rc = fixed_set(m, p, c->fixed, err);
    if (rc != MCF_OK)
        return rc;
    double hbar = mcf__mean_edge(c->X, c->F, c->nf);
    st->mean_edge = hbar;
    if (p->log_steps) {
        int cap = p->iterations > 0 ? p->iterations
                  : p->scheme == MCF_FAIRING ? MCF_FAIRING_MAX_STEPS : MCF_FAIRING_MAX_PASSES;
        if (cap > p->max_steps && p->iterations <= 0)
            cap = p->max_steps;
        st->log = mcf__calloc((size_t)cap, sizeof *st->log);
        h.prev = mcf__malloc(3 * (size_t)c->nv, sizeof(double));
        h.units = mcf__malloc(3 * (size_t)c->nv, sizeof(double));
        if (!st->log || !h.prev || !h.units) {
            free(h.prev);
            free(h.units);
            return mcf__fail(err, MCF_ENOMEM, "flow: out of memory for the step log");
        }
        memcpy(h.prev, c->X, 3 * sizeof(double) * (size_t)c->nv);
    }
    rc = mcf__fairing(c->X, c->F, c->nf, c->nv, c->fixed, p, hbar, st, fairing_hook, &h, err);
    c->bytes += st->peak_bytes;
    free(h.prev);
    free(h.units);
    return rc;
}

/* One MCF run's plan and progress, beside its flow_ctx. */
typedef struct {
    double cen[3], scale;   /* working units: (x - cen) * scale */
    double area_in;         /* the input's area, input units */
    double area0, vol0;     /* the rescale targets, working units */
    double *X_in;           /* the input's positions, exact */
    double h, T;            /* the next step, the total time */
    int nsteps;             /* fixed-step runs: the step count */
    int check_inv;          /* adaptive: steps are judged by folds */
    int fold_budget, folds_total;
    int in_step;            /* c->Xold holds the last accepted state */
    double t;
    int k, rejected_here;
    double last_ratio, last_h; /* the estimate's rejection at this t: est/allowed, h */
    double overspent;       /* the share of the budget stiff events took */
    double last_rms, last_max; /* that rejection's RMS and max parts of est/allowed */
    double waived_max;      /* the largest max part of est/allowed waived since the last step whose max met its allowance, else 0 */
    history hist;
} run_plan;

/* The run's allocations, the step log, the fixed set (the user's list,
 * the fixed boundary, vertices without mass), the pattern of the
 * implicit schemes' matrix and their solver, the input's operators for
 * cmcf and linear. */
static mcf_status prepare(flow_ctx *c, run_plan *r, mcf_error *err)
{
    const mcf_flow_params *p = c->p;
    size_t n3 = 3 * (size_t)c->nv, nv = (size_t)c->nv, nf = (size_t)c->nf;
    mcf_status rc;
    c->w = mcf__flow_alloc(c, 3 * nf); c->area = mcf__flow_alloc(c, nf); c->mass = mcf__flow_alloc(c, nv);
    c->w2 = mcf__flow_alloc(c, 3 * nf); c->area2 = mcf__flow_alloc(c, nf); c->mass2 = mcf__flow_alloc(c, nv);
    c->V = mcf__flow_alloc(c, n3); c->V2 = mcf__flow_alloc(c, n3); c->B = mcf__flow_alloc(c, n3);
    /* T1 has nv more: mcf__flow_folded_faces's scratch */
    c->T1 = mcf__flow_alloc(c, n3 + nv); c->T2 = mcf__flow_alloc(c, n3); c->Xold = mcf__flow_alloc(c, n3);
    c->Xprev = mcf__flow_alloc(c, n3); c->Xprev2 = mcf__flow_alloc(c, n3);
    /* adaptive runs reject steps that fold too many faces (see
     * mcf__flow_folded_faces). Not every fold proves a step too large: even a stable
     * explicit step (dt = 0.25 / lambda_max on a noisy scan) folds the odd
     * sliver through the flow's own nonlinearity, and on a scan full of
     * needles (snowden) every step folds 1-20 of 109k faces at any size
     * down to 1e-9; past strength 1 the flow itself crumples ears at a
     * rate proportional to the time covered (armadillo, t = 1e-4: about
     * 2e8 folds per unit time). Rejecting those made dt collapse and the
     * run crawl (dt 1e-11 after 22k steps). So a step is rejected for
     * folds only past fold_budget (0.1% of the faces, the FOLDS warning's
     * threshold) AND past 4x what the run's own fold rate predicts for
     * its size: folds that grow with the step faster than linearly are a
     * step too large; the flow's own are reported by the FOLDS warning. */
    r->check_inv = p->adaptive;
    r->fold_budget = c->nf / 1000;
    if (r->check_inv) {
        c->fn = mcf__flow_alloc(c, 3 * nf);
        c->fn2 = mcf__flow_alloc(c, 3 * nf);
    }
    if (!c->w || !c->area || !c->mass || !c->w2 || !c->area2 || !c->mass2 || !c->V ||
        !c->V2 || !c->B || !c->T1 || !c->T2 || !c->Xold || !c->Xprev || !c->Xprev2 ||
        (r->check_inv && (!c->fn || !c->fn2)))
        return mcf__fail(err, MCF_ENOMEM, "flow: out of memory (%d vertices, %d faces)", c->nv, c->nf);
    if (p->log_steps) {
        size_t cap = p->adaptive ? (size_t)p->max_steps : (size_t)(p->time > 0 ? 0 : p->iterations);
        c->st->log = NULL;
        if (cap > 0 && !(c->st->log = mcf__calloc(cap, sizeof *c->st->log)))
            return mcf__fail(err, MCF_ENOMEM, "flow: out of memory for the step log");
    }

    /* Dirichlet vertices: user list, fixed boundary, unreferenced */
    for (int i = 0; i < p->nfixed; i++)
        c->fixed[p->fixed[i]] = 1;
    /* the pattern: the implicit schemes' matrix, and the edge
     * multiplicities that find the boundary (an explicit scheme on a mesh
     * without boundary needs neither) */
    int fix_boundary = p->boundary == MCF_BOUNDARY_FIXED;
    int odd = c->si->is_explicit && fix_boundary ? odd_edges(c) : 0;
    if (odd < 0 || (p->rescale == MCF_RESCALE_VOLUME && !odd && (odd = odd_edges(c)) < 0))
        return mcf__fail(err, MCF_ENOMEM, "flow: out of memory (%d vertices)", c->nv);
    if (p->rescale == MCF_RESCALE_VOLUME && odd)
        /* an open surface encloses no volume: its "volume" depends on
         * where the origin is, and restoring it moved a holed bunny's
         * free vertices the wrong way (2.6x worse, 1% off its target) */
        return mcf__fail(err, MCF_EINVAL,
                         "rescale: volume needs a closed mesh, this one has boundary (or odd non-manifold) edges: use rescale=area");
    if (!c->si->is_explicit || odd) {
        if ((rc = mcf__pattern_build(c->F, c->nf, c->nv, !c->si->is_explicit, &c->pat, err)) != MCF_OK)
            return rc;
        c->bytes += sizeof(int) * (2 * (size_t)c->pat.nnz + 2 * nv + (c->pat.tri ? 3 * nf : 0));
        if (fix_boundary)
            mark_boundary(&c->pat, c->fixed);
    }
    c->st->mean_edge = mcf__mean_edge(c->X, c->F, c->nf);
    c->delta = MCF_MOLLIFY * c->st->mean_edge;
    /* vertices without mass stay put: the unreferenced ones (every
     * referenced vertex has barycentric mass, the mollified areas being
     * positive) and, with the Voronoi mass, any other */
    if (p->mass == MCF_MASS_BARYCENTRIC) {
        mark_unreferenced(c->F, c->nf, c->nv, c->fixed);
    } else {
        mcf__flow_ops_at(c, c->X, c->w, c->area, c->mass);
        for (size_t i = 0; i < nv; i++)
            if (!(c->mass[i] > 0.0))
                c->fixed[i] = 1;
    }
    if (!c->si->is_explicit && (rc = mcf__flow_solver_init(c, err)) != MCF_OK)
        return rc;
    if (p->scheme == MCF_CMCF || p->scheme == MCF_LINEAR)
        mcf__flow_ops_at(c, c->X, c->w2, c->area2, c->mass2); /* L_0 (and M_0) from the input */
    return MCF_OK;
}

/* The amount and the steps (mcf.h, "The amount of smoothing"): r->T, r->h
 * and r->nsteps from the parameters, dt=auto's lambda_max, Taubin's or the
 * MCF schemes' automatic amount; the step log of a fixed-step run. */
static mcf_status plan_steps(flow_ctx *c, run_plan *r, mcf_error *err)
{
    const mcf_flow_params *p = c->p;
    mcf_flow_stats *st = c->st;
    double hbar = st->mean_edge, h = p->dt, T = p->time, sigma;
    int dt_set = p->dt_auto || p->dt > 0.0;
    int nsteps = p->iterations > 0 ? p->iterations : MCF_DEFAULT_STEPS;
    mcf_status rc;
    if (p->dt_auto) {
        mcf_mesh tmp = {c->nv, c->nf, c->X, (int32_t *)(uintptr_t)c->F};
        if ((rc = mcf_lambda_max(&tmp, p->laplacian, p->mass, &st->lambda_max, err)) != MCF_OK)
            return rc;
        /* 0.9/lambda_max for euler-like schemes (0.45 for neumann2): the
         * top mode then decays without changing sign, so no sliver flips;
         * 10% margin for the power iteration's underestimate */
        h = 0.45 * c->si->stability / st->lambda_max;
    }
    if (p->scheme == MCF_TAUBIN) {
        h = T = 0.0; /* passes, no time */
        if (p->strength_auto && p->iterations <= 0) {
            if ((rc = mcf__auto_passes(c->X, c->F, c->nf, c->nv, c->fixed, p->laplacian, hbar, &nsteps, &sigma,
                                       err)) != MCF_OK)
                return rc;
            if (nsteps > p->max_steps)
                nsteps = p->max_steps;
            st->noise = sigma / hbar;
            st->noise_kind = MCF_NOISE_NORMAL;
        }
    } else if (T <= 0.0 && p->iterations > 0 && dt_set) {
        T = p->iterations * h;
    } else if (T <= 0.0 && p->strength_auto) {
        /* an implicit scheme lends its solver: one symbolic analysis */
        if ((rc = mcf__auto_time(c->X, c->F, c->nf, c->nv, c->fixed, p->laplacian, p->mass,
                                 p->scheme != MCF_LINEAR, hbar, nsteps, c->chol,
                                 &T, &sigma, err)) != MCF_OK)
            return rc;
        st->noise = sigma / hbar;
        st->noise_kind = MCF_NOISE_NORMAL;
        if (!(T > 0.0))
            nsteps = 0; /* no noise to remove: the mesh comes back as it came */
    } else if (T <= 0.0) {
        T = p->strength * p->strength * hbar * hbar;
    }
    st->t_target = T;
    if (p->scheme != MCF_TAUBIN && !dt_set) {
        h = nsteps > 0 ? T / nsteps : 0.0;
    } else if (p->scheme != MCF_TAUBIN && !p->adaptive) {
        double k = ceil(T / h * (1.0 - 1e-12));
        /* a step count the caller gave (iterations with dt) is the
         * caller's; max_steps bounds the counts derived from a time */
        if (k > (double)p->max_steps && !(p->iterations > 0 && p->time <= 0.0))
            return mcf__fail(err, MCF_ELIMIT, "time %g at dt %g needs %.0f steps, over max_steps %d%s", T, h, k, p->max_steps,
                             p->dt_auto ? " (dt=auto is set by the stiffest triangle: use an implicit scheme such as desbrun2)" : "");
        nsteps = k < 1 ? 1 : (int)k;
        h = T / nsteps;
    }
    /* adaptive: the step given (dt, or T / iterations), else the whole
     * time: the estimate shrinks it (from T / 10, the growth limit held
     * tol 1e-3 and 1e-4 to the same 5-6 steps: issue 30) */
    if (p->adaptive)
        h = !dt_set && p->iterations <= 0 ? T : fmin(h, T);
    if (p->log_steps && !st->log && !p->adaptive && nsteps > 0 &&
        !(st->log = mcf__calloc((size_t)nsteps, sizeof *st->log)))
        return mcf__fail(err, MCF_ENOMEM, "flow: out of memory for the step log");
    st->dt_first = h;
    st->dt_min = INFINITY;
    st->dt_max = 0.0;
    r->h = h;
    r->T = T;
    r->nsteps = nsteps;
    return MCF_OK;
}

/* The share of tol the local errors of a run may add up to. The sum of
 * the estimates bounds the error at T only as well as each estimate
 * bounds its step's error; on scans with slivers the last steps leave
 * errors in stiff modes that follow the slow ones (an O(h) lag the
 * third difference does not see), and the error at T came out 1.8-2.9
 * tol with the whole tol (spot, strength 0.5, tol 1e-5 and 1e-6). With
 * 0.3, measured on the repository's meshes and spot (docs/numerics.md,
 * "What tol means"). */
#define ADAPT_SAFETY 0.3
/* The max over the vertices may carry ADAPT_MAX times the RMS's share
 * (issue 30's bar: the max within 20 tol at T; desbrun2 on armadillo,
 * strength 0.5, tol 1e-5 and 1e-6: 39 and 128 tol without it, 9.9 and
 * 9.8 with it, at 112 and 513 factorizations against 34 and 87). ros2
 * gives no max: with it, at every 2x growth its stiff modes' offset,
 * which depends on h (order reduction), moved, its max estimate jumped
 * 650x (spot, tol 1e-5: 2,725 attempts against 384), and growing by
 * 1.2 instead left 2.7 tol on the noisy sphere of test_core_flow. */
#define ADAPT_MAX 20.0
/* The share of that budget stiff events may take beyond it (adapt). */
#define ADAPT_EVENTS 0.1
/* The share of it desbrun2's first step may take, however short. The
 * start is a first-order desbrun step whose filtered estimate falls only
 * like h^1.3 on a scan (spot, tol 1e-4: est/allowed per unit step 4.0,
 * 3.0, 2.3, 1.8, 1.5, 1.2, 1.0, 0.94 as h fell from T to T/190, 7
 * rejections at 3 factorizations each), while the BDF2 steps that follow
 * meet the budget per unit step at twice that size. Below ADAPT_START
 * T the start is controlled per step against that share of the budget,
 * so it no longer shrinks below what the second-order steps need. */
#define ADAPT_START 0.1

/* Why an adaptive run that gives up (step size underflow, max_steps)
 * may have had to: the shortest edge of the state reached (c->X) against
 * the input's, into why (empty when over 1/SINGULAR_EDGE). A small part
 * collapsing to a point (car.drc at strength 0.5: four pieces of 24-49
 * vertices, 0.1% of the area each, whose curvature grows without bound
 * before T) is a singularity of the flow itself, where no step size meets
 * a tol; smoothing less, or without those parts, is the way out. */
#define SINGULAR_EDGE 10.0
static void singular_note(const flow_ctx *c, const run_plan *r, char *why, size_t n)
{
    double e0 = mcf__flow_min_edge(r->X_in, c->F, c->nf) * r->scale, e1 = mcf__flow_min_edge(c->X, c->F, c->nf);
    why[0] = '\0';
    if (e0 > 0.0 && e1 * SINGULAR_EDGE < e0)
        snprintf(why, n, "; the shortest edge is %.2g of the input's: the flow nears a singularity (a part "
                 "collapsing), where no step meets a tol: smooth less", e1 / e0);
}

/* The adaptive verdict on the step just taken (rc, its estimate est, the
 * faces it folded): 1 accepted, with *h_next; 0 rejected, c->X restored
 * and r->h shrunk (try again); -1 the run fails (*rc says why). */
static int adapt(flow_ctx *c, run_plan *r, mcf_status *rc, step_est est, int finite, int inv,
                 double *h_next, mcf_error *err)
{
    const mcf_flow_params *p = c->p;
    double h = r->h, T = r->T;
    if (*rc == MCF_ENOMEM || *rc == MCF_ECANCELED)
        return -1;
    /* Error per unit step (desbrun2): a step may carry ADAPT_SAFETY *
     * tol * h / T, so the local errors add up to about tol at T (the
     * flow contracts errors: a mode's local error reaches T damped by
     * exp(-lambda (T - t))). desbrun2 estimates its own error from the
     * third divided difference of the last four states (Milne's device,
     * from its third step on; q = 2) plus the defect of its extrapolated
     * operator (mcf_steps.c step_bdf2); its first step uses step doubling
     * seen through the step's resolvent (q = 1), which overstates a
     * second-order result's error: conservative at the start only. Its
     * second step has no estimate and repeats the first step's size
     * (BDF2 starts at ratio 1). est ~ h^(q+1), so est/h ~ h^q: the
     * exponent is 1/q.
     * ros2 does the same from its third step on, with Milne's device
     * and its own error constant (mcf_steps.c); its first two steps are
     * controlled as desbrun2's start, with its embedded first-order
     * solution, filtered. Controlled per step with that companion (est
     * <= tol), the error at T grew to 4.8 tol on spot at tol 1e-6 and 10x
     * tighter bought 2-5x: the filtered companion misses the
     * order-reduced error of the stiff modes (issue 30).
     * richardson and desbrun keep their first-order estimates (the
     * desbrun solutions' difference, step doubling), filtered, per step
     * (est <= tol, exponent 1/2): richardson's Milne estimate missed a
     * noisy sphere's transient (tests/test_core_flow.c test_adaptive, tol
     * 1e-5: 12 tol in 329 steps where 128 fixed steps are as accurate);
     * desbrun per unit step needs ~1/tol steps. */
    int second_order = p->scheme == MCF_DESBRUN2 || p->scheme == MCF_ROS2;
    int start = second_order && (p->scheme == MCF_DESBRUN2 ? r->hist.nhist == 0 : r->hist.nhist < 2);
    int per_unit = second_order && !start;
    int milne = per_unit && r->hist.nhist >= 2;
    int q = milne ? 2 : 1;
    int need_est = !(p->scheme == MCF_DESBRUN2 && r->hist.nhist == 1);
    double allowed = per_unit ? ADAPT_SAFETY * p->tol * h / T
                              : start ? ADAPT_SAFETY * p->tol * fmax(h / T, ADAPT_START) : p->tol;
    /* e: the estimate against what the step may carry, the larger of
     * the RMS's and the max's (ADAPT_MAX times the RMS's allowance) */
    double e_rms = need_est ? est.rms / allowed : 0.0, e_max = need_est ? est.max / (ADAPT_MAX * allowed) : 0.0;
    double e = fmax(e_rms, e_max);
    double ratio = e > 0.0 ? 1.0 / e : 1e3;
    /* est/allowed ~ h^a with a = q per unit step, q + 1 per step */
    double a = per_unit ? q : q + 1;
    /* After a rejection at this t the fall measured between the two
     * tries replaces the assumed one when it is slower (a step of the
     * scheme's own estimate, between 1/4 and the assumed order): the
     * first step's estimate falls like h^1.3 on spot, where h^2 took
     * 4-7 rejections */
    if (r->rejected_here > 0 && r->last_ratio > 0.0 && h < r->last_h && e > 0.0) {
        double seen = log(r->last_ratio / e) / log(r->last_h / h);
        if (isfinite(seen))
            a = fmin(a, fmax(0.25, seen));
    }
    double fac = 0.9 * pow(ratio, 1.0 / a);
    double fold_rate = r->t > 0.0 ? r->folds_total / r->t : 0.0;
    int folds = inv > r->fold_budget && inv > 4.0 * fold_rate * h;
    int over = e_rms > 1.0, over_max = e_max > 1.0, waived = 0;
    /* A stiff event (a small feature collapsing fast: spot at t = 0.19 T)
     * gives an estimate that does not fall with the step until h lambda
     * < 1 (spot, tol 1e-4: est/allowed 5.4, 3.9, 3.0, ... 1.5, 1.0 over
     * 19 rejections as h fell 500x). Shrinking there buys nothing: a
     * Milne estimate that fell by less than the geometric mean of no
     * change and the h^q it should (after a rejection at this t) is
     * accepted, while the events' excess, (est/allowed - 1) h/T, adds
     * up to at most ADAPT_EVENTS of the budget. */
    int event = milne && r->rejected_here > 0 && r->last_ratio > 0.0 && h < r->last_h;
    double fall = event ? pow(h / r->last_h, 0.5 * q) : 0.0;
    if (over && event) {
        double excess = (e_rms - 1.0) * h / T;
        if (e_rms > r->last_rms * fall && r->overspent + excess <= ADAPT_EVENTS) {
            r->overspent += excess;
            over = 0;
        }
    }
    /* The max through such an event gets no budget: a feature pinching
     * on a noisy scan (bunny.drc, noise 0.25, time 1e-4: ears and noise
     * folds, one after another from t = 0.3 T) puts a vertex's estimate
     * in a regime where it grows as h falls, and rejecting on it took h
     * to 1e-11 T again and again (not done in 15 minutes; 60 steps with
     * the RMS alone). Where the max does not fall as it should after a
     * rejection at this t, the step is accepted on its RMS: the max
     * bounds the asymptotic error, not a local singularity's, where no
     * step size meets it (docs/numerics.md, "What tol means").
     * Only a max that did not fall at all: armadillo's fingers
     * (strength 0.5, tol 1e-5 and 1e-6) gave one that fell 1-20% as h
     * shrank 0.5-0.8x and was waived at almost every step, 23 and 32
     * tol at T; a pinching one holds level or grows. */
    if (over_max && event && e_max >= r->last_max) {
        over_max = 0;
        waived = 1;
    }
    /* That level is remembered: a max that was waived stays waived up to
     * the largest level waived since the last step whose max met its
     * allowance. Without it every step through such a stretch paid a
     * rejection first (fertility, strength 0.5, tol 1e-5: from t =
     * 0.71 T every step was rejected once and waived at the next try,
     * 8 rejections in the last 9 steps); the RMS still sizes the step,
     * and the max is never accepted above a level already waived. */
    if (over_max && r->waived_max > 0.0 && e_max <= r->waived_max && r->rejected_here == 0) {
        over_max = 0;
        waived = 1;
    }
    if (!finite || folds || over || over_max) {
        if (over || over_max) {
            r->last_ratio = e;
            r->last_rms = e_rms;
            r->last_max = e_max;
            r->last_h = h;
        }
        memcpy(c->X, c->Xold, 3 * (size_t)c->nv * sizeof(double));
        r->in_step = 0;
        c->st->rejected++;
        r->rejected_here++;
        r->h *= (!finite || folds) ? 0.25 : fmax(0.2, fac);
        if (r->h < 1e-14 * T) {
            char why[160];
            singular_note(c, r, why, sizeof why);
            *rc = mcf__fail(err, MCF_ENUMERIC, "adaptive: step size underflow at t = %g of %g (%s)%s", r->t, T,
                            !finite ? "non-finite positions" : folds ? "folded faces" : "error estimate", why);
            return -1;
        }
        return 0;
    }
    *rc = MCF_OK;
    r->last_ratio = 0.0;
    r->waived_max = waived ? fmax(r->waived_max, e_max) : 0.0;
    r->folds_total += inv;
    /* desbrun2's second step reuses h: BDF2 starts at ratio 1 */
    c->st->error_estimate += need_est ? est.rms : 0.0;
    /* no growth right after a rejection (Hairer and Wanner's facmax = 1):
     * where the estimate grows faster than h^q, as on a stiff transient,
     * growing again at once rejected every other step (ros2 on spot,
     * tol 1e-5: 232 rejections in 251 steps) */
    double grow = r->rejected_here ? 1.0 : 2.0;
    if (waived) { /* the rejection was the max's: the RMS sizes the next step */
        grow = 2.0;
        fac = e_rms > 0.0 ? 0.9 * pow(1.0 / e_rms, 1.0 / q) : 2.0;
    }
    *h_next = p->scheme == MCF_DESBRUN2 && r->hist.nhist == 0 ? h : h * fmin(grow, fmax(0.2, fac));
    return 1;
}

/* An accepted step of size r->h: the history shifts (rotating buffers:
 * Xold is rewritten at the start of every step), the statistics, the
 * rescale, the step log; the next step is h_next. */
static void accept_step(flow_ctx *c, run_plan *r, double h_next)
{
    const mcf_flow_params *p = c->p;
    mcf_flow_stats *st = c->st;
    double *spare = c->Xprev2;
    c->Xprev2 = c->Xprev;
    c->Xprev = c->Xold;
    c->Xold = spare;
    if (r->check_inv) {
        spare = c->fn; /* a rescale keeps normal directions */
        c->fn = c->fn2;
        c->fn2 = spare;
    }
    r->hist.h2 = r->hist.h1;
    r->hist.h1 = r->h;
    r->hist.nhist++;
    r->t += r->h;
    st->dt_min = fmin(st->dt_min, r->h);
    st->dt_max = fmax(st->dt_max, r->h);
    r->h = h_next;
    if (p->rescale != MCF_RESCALE_NONE)
        mcf__flow_rescale(c, r->area0, r->vol0);
    if (p->log_steps && st->log && (p->adaptive || r->k < r->nsteps)) {
        double maxd = 0.0;
        for (size_t i = 0; i < (size_t)c->nv; i++) {
            double d[3];
            mcf__sub3(c->X + 3 * i, c->Xprev + 3 * i, d);
            maxd = fmax(maxd, mcf__dot3(d, d));
        }
        log_step(c, c->X, r->k, r->t, r->hist.h1, r->rejected_here, r->scale, r->cen, sqrt(maxd), NULL);
    }
    r->rejected_here = 0;
    r->in_step = 0;
    r->k++;
    st->steps = r->k;
    st->t_final = r->t;
}

/* linear: the couplings to fixed vertices never change; their
 * right-hand-side share -sum A_ij x_j is kept in T2 before the first
 * factorization. */
static void linear_couplings(flow_ctx *c, double h)
{
    mcf__flow_system_fill(c, 1.0, h, c->w2, c->mass2);
    memset(c->T2, 0, 3 * (size_t)c->nv * sizeof(double));
    mcf__flow_rhs_dirichlet(c, c->X, c->T2);
    for (size_t i = 0; i < (size_t)c->nv; i++)
        if (c->fixed[i])
            c->T2[3 * i] = c->T2[3 * i + 1] = c->T2[3 * i + 2] = 0.0;
}

/* The step loop: to r->T (adaptive) or r->nsteps steps, with cancel,
 * progress, the adaptive verdict or the explicit schemes' growth check. */
static mcf_status run_steps(flow_ctx *c, run_plan *r, mcf_error *err)
{
    const mcf_flow_params *p = c->p;
    size_t n3 = 3 * (size_t)c->nv;
    int attempts = 0;
    mcf_status rc;
    if (r->check_inv)
        mcf__face_normals(c->X, c->F, c->nf, c->fn);
    for (;;) {
        if (p->adaptive ? !(r->t < r->T * (1.0 - 1e-12)) : r->k >= r->nsteps)
            return MCF_OK;
        if (mcf__cancel_set(p->cancel))
            return mcf__fail(err, MCF_ECANCELED, "canceled at step %d (t = %g)", r->k, r->t);
        if (p->adaptive) {
            if (++attempts > p->max_steps) {
                char why[160];
                singular_note(c, r, why, sizeof why);
                return mcf__fail(err, MCF_ELIMIT, "adaptive: max_steps (%d attempts, %d accepted) reached at t = %g of %g; raise max_steps or tol%s",
                                 p->max_steps, r->k, r->t, r->T, why);
            }
            /* a step that would leave less than a tenth of itself
             * takes the rest: 10% more than the controller asked adds at
             * most 1.1^2 x 0.9^2 = 0.98 of the allowed error, where a
             * last sliver of a step costs a factorization (spot, tol
             * 1e-4: a last step of 0.0017 T after one of 0.156 T) */
            if (r->t + r->h > r->T || r->T - (r->t + r->h) < 0.1 * r->h)
                r->h = r->T - r->t;
        }
        c->step_solve_s = 0.0;
        step_est est = {0.0, 0.0};
        double h_next = r->h;
        if (p->scheme == MCF_LINEAR && !c->factor_valid)
            linear_couplings(c, r->h);
        r->in_step = 1;
        rc = mcf__flow_step(c, r->h, &r->hist, p->adaptive ? &est : NULL, err);
        int finite = rc == MCF_OK && mcf__flow_all_finite(c->X, n3);
        int inv = finite && r->check_inv ? mcf__flow_folded_faces(c->X, c->F, c->nf, c->nv, c->fn, c->fn2, c->T1) : 0;
        if (p->adaptive) {
            int verdict = adapt(c, r, &rc, est, finite, inv, &h_next, err);
            if (verdict < 0)
                return rc;
            if (verdict == 0)
                continue;
        } else {
            if (rc != MCF_OK)
                return rc;
            /* An explicit scheme past its limit need not overflow: lambda
             * falls like 1/size^2 as the mesh crumples, so the result can
             * stay finite. MCF never increases the area, the instability
             * does, fast: more than 1.5x the starting area is taken as it
             * (a stable step may flip slivers, so folds prove nothing).
             * The step's own pass over the faces (mcf__flow_LX) left the
             * area of the state before it: no extra geometry pass; the
             * last state is checked after the loop. */
            double grown = finite && c->si->is_explicit && p->scheme != MCF_TAUBIN ? c->area_sum / r->area0 : 0.0;
            if (!finite || grown > 1.5)
                return unstable(c, err, !finite ? r->k + 1 : r->k, r->h, !finite ? 0.0 : grown);
        }
        accept_step(c, r, h_next);
        /* the energy: the log's area of this step when it has it (input
         * units), else NaN (mcf_progress_fn) */
        if (p->progress &&
            p->progress(p->progress_ctx, r->k, r->t, r->hist.h1,
                        c->st->log && c->st->nlog >= r->k ? c->st->log[r->k - 1].area : NAN))
            return mcf__fail(err, MCF_ECANCELED, "canceled by the progress callback at step %d", r->k);
        if (p->work)
            p->work(p->progress_ctx, "steps", r->T > 0.0 ? fmin(1.0, r->t / r->T) : 0.0);
    }
}

/* The result into m's positions in input units: the last accepted state
 * (the state before a failed step, or the untouched input when no step
 * was accepted), fixed vertices to the bit; then the final statistics,
 * the growth check of a fixed explicit run's last state and the
 * warnings. Returns rc, or the growth check's failure. */
static mcf_status finish(flow_ctx *c, run_plan *r, const mcf_mesh *m, mcf_status rc, mcf_error *err)
{
    const mcf_flow_params *p = c->p;
    mcf_flow_stats *st = c->st;
    size_t n3 = 3 * (size_t)c->nv;
    if (rc != MCF_OK && r->in_step && c->Xold)
        memcpy(c->X, c->Xold, n3 * sizeof(double));
    if (rc != MCF_OK && st->steps == 0) {
        memcpy(c->X, r->X_in, n3 * sizeof(double));
    } else if (p->normalize) {
        /* the input plus the run's displacement, not x/s + c: a vertex the
         * run did not move comes back to the bit (through x/s + c an
         * unchanged input came back with 3,003 of blade.obj's 8,231
         * vertices an ulp off, and vertices the input had at one point,
         * which a quantized scan has by the thousand, apart: faces of
         * rounding-sized area and random orientation, 495 of
         * couplingdown_sub2's faces against the clean mesh's at
         * quantization 0.5). The working position of x_in is recomputed
         * as normalize() computed it, bit for bit. */
        for (size_t i = 0; i < (size_t)c->nv; i++)
            for (int d = 0; d < 3; d++) {
                double x0 = r->X_in[3 * i + d];
                c->X[3 * i + d] = x0 + (c->X[3 * i + d] - (x0 - r->cen[d]) * r->scale) / r->scale;
            }
        /* fixed vertices come back to the bit (a rescaled run moves them
         * in working units) */
        for (size_t i = 0; c->fixed && i < (size_t)c->nv; i++)
            if (c->fixed[i])
                memcpy(c->X + 3 * i, r->X_in + 3 * i, 3 * sizeof(double));
    }
    st->area1 = mcf__area_volume(m->X, m->F, m->nf, NULL, &st->volume1);
    /* the growth check of a fixed explicit run's last state (the loop
     * checked every state before it) */
    if (rc == MCF_OK && !p->adaptive && c->si->is_explicit && p->scheme != MCF_TAUBIN &&
        !mcf__is_fairing(p->scheme) && st->steps > 0 && st->area1 > 1.5 * r->area_in)
        rc = unstable(c, err, st->steps, st->dt_max, st->area1 / r->area_in);
    if (st->dt_min == INFINITY || st->steps == 0)
        st->dt_min = 0.0;
    if (rc == MCF_OK)
        flow_warnings(c, r->X_in, st);
    st->peak_bytes = c->bytes + mcf__chol_bytes(c->chol);
    return rc;
}

/* Working units: centred on the area centroid and scaled to unit area
 * (normalize), with an exact copy of the input kept for restoring.
 * Fails on an area that overflows or vanishes. */
static mcf_status normalize(flow_ctx *c, run_plan *r, const mcf_mesh *m, mcf_error *err)
{
    const mcf_flow_params *p = c->p;
    size_t n3 = 3 * (size_t)c->nv;
    r->scale = 1.0;
    r->area_in = mcf__area_volume(m->X, m->F, m->nf, r->cen, &c->st->volume0);
    c->st->area0 = r->area_in;
    if (!isfinite(r->area_in))
        return mcf__fail(err, MCF_EMESH, "the mesh's area overflows double precision "
                         "(coordinates too large: keep them below about 1e150); scale it down");
    if (p->normalize) {
        if (!(r->area_in > 0.0))
            return mcf__fail(err, MCF_EMESH, "normalize: the mesh has zero total area");
        r->scale = 1.0 / sqrt(r->area_in);
    } else {
        r->cen[0] = r->cen[1] = r->cen[2] = 0.0;
    }
    double *X_in = mcf__malloc(n3, sizeof(double));
    if (!X_in)
        return mcf__fail(err, MCF_ENOMEM, "flow: out of memory (%d vertices)", c->nv);
    memcpy(X_in, m->X, n3 * sizeof(double));
    r->X_in = X_in;
    c->bytes += n3 * sizeof(double);
    if (p->normalize)
        for (size_t i = 0; i < (size_t)c->nv; i++)
            for (int d = 0; d < 3; d++)
                c->X[3 * i + d] = (c->X[3 * i + d] - r->cen[d]) * r->scale;
    /* the rescale targets, in working units (exact: a scaling maps area
     * by scale^2 and volume by scale^3, a translation keeps both) */
    r->area0 = r->area_in * r->scale * r->scale;
    r->vol0 = c->st->volume0 * r->scale * r->scale * r->scale;
    return MCF_OK;
}

mcf_status mcf_flow_run(mcf_mesh *m, const mcf_flow_params *p,
                        mcf_flow_stats *stats, mcf_error *err)
{
    flow_ctx c;
    run_plan r;
    mcf_flow_stats st_local;
    mcf_status rc;
    double t_start = mcf_now();
    memset(&c, 0, sizeof c);
    memset(&r, 0, sizeof r);
    memset(&st_local, 0, sizeof st_local);
    if (!m || !p)
        return mcf__fail(err, MCF_EINVAL, "mcf_flow_run: NULL argument");
    if ((rc = mcf_flow_params_check(p, m->nv, err)) != MCF_OK)
        return rc;
    mcf_flow_stats *st = stats ? stats : &st_local;
    memset(st, 0, sizeof *st);
    st->filter = p->scheme;
    c.p = p;
    c.si = mcf_scheme_get(p->scheme);
    c.st = st;
    c.nv = m->nv;
    c.nf = m->nf;
    c.F = m->F;
    c.X = m->X;
    if ((rc = normalize(&c, &r, m, err)) != MCF_OK)
        return rc;
    c.fixed = mcf__calloc((size_t)c.nv, 1);
    if (!c.fixed)
        rc = mcf__fail(err, MCF_ENOMEM, "flow: out of memory (%d vertices)", c.nv);
    else if (mcf__is_fairing(p->scheme))
        rc = run_fairing(&c, m, r.scale, r.cen, err);
    else if ((rc = prepare(&c, &r, err)) == MCF_OK && (rc = plan_steps(&c, &r, err)) == MCF_OK)
        rc = run_steps(&c, &r, err);
    rc = finish(&c, &r, m, rc, err);
    st->time_total = mcf_now() - t_start;
    free(r.X_in);
    ctx_free(&c);
    if (!stats)
        mcf_flow_stats_free(&st_local);
    return rc;
}

void mcf_flow_stats_free(mcf_flow_stats *s)
{
    if (!s)
        return;
    free(s->log);
    free(s->sure);
    memset(s, 0, sizeof *s);
}
