/* SPDX-License-Identifier: MIT */
/*
 * mcf_fairing_ctx.h - private to the files of one fairing run
 * (mcf_fairing.c, the explicit engine and the driver;
 * mcf_fairing_implicit.c, the implicit engine; mcf_fairing_sure.c, Stein's
 * estimate, the combination of iterates and the pick between the
 * filters; mcf_fairing_output.c, the result along the normals, its
 * tangential relaxation, the bounds on a move and the fold guard's
 * positions): the run's state and what those files call across. Never
 * included outside core/; the contract is mcf.h, docs/fairing.md the math.
 */
#ifndef MCF_FAIRING_CTX_H
#define MCF_FAIRING_CTX_H

#include "mcf_internal.h"

enum { NPROBE = 6 };
/* Above PROBES_FEW_ABOVE free vertices the run carries NPROBE_FEW probes
 * (c->nprobe; NPROBE, the most, otherwise): the passes then move 6 columns
 * instead of 9. A probe's estimate of the trace varies as 2 |W T^K|_F^2
 * (off the diagonal), about n / K for a local smoother, while the trace
 * grows as n: its relative deviation falls as 1 / sqrt(n). The variance
 * accepted, measured on the 1.74M subdivided dragon (noise 0.25, K* 40,
 * trace 1.77e5 of sum w 1.74e6): the mean's relative standard error (the
 * probes' spread) 0.14% with six probes, 0.17% with three; times 2 s^2,
 * 0.17% and 0.21% of SURE at K*. The output's error moved from 0.32399 to
 * 0.32398 of the input's, for 29% less CPU (31.6 -> 22.5 s user). Two
 * probes there (2026-11-28, the same mesh, `mcf smooth --threads 1`,
 * interleaved): the same K* (40) and kept iterates, combination weights
 * moved by up to 4%, error 0.32419 -> 0.32448 of the input's (+0.09%),
 * task-clock 24.16 -> 23.49 s (-2.8%): not taken, the passes' cost is
 * mostly their 3 position columns and the graph, not the probes'. */
#define PROBES_FEW_ABOVE 1000000
enum { NPROBE_FEW = 3 };
/* the least gain of SURE over the input, in its standard errors
 * (sure_of), for a step to count: one-sided, 2 leaves about 2% of the
 * steps that gain nothing; the gain's error is small on a scan (one step
 * count of the 180 `make quality` cases changed, by one), of the gain's size on
 * a coarse mesh (car.drc: 300 free vertices, a few 15x the mean area) */
#define SURE_MIN_GAIN 2.0
/* The combination (combine): the iterates after the last COMB_J powers
 * of two of steps, e.g. 2, 4, 8 and 16 for a run that stops at 21.
 * Measured in numpy (normal noise 0.1 and 0.25, seed 1, against the
 * product's cotan Taubin at its best pass count; the filter alone, without
 * the creases, bounds and guard): 4 iterates 0.72-1.03 (spot 0.25 0.846
 * -> 0.796, knot1 0.1 0.874 -> 0.721, armadillo 0.1 0.943 -> 0.898,
 * fertility 0.25 0.719 -> 0.727, the one worse case of 16); 2 iterates
 * gain half as much, 3 nearly as much; every power of two and every
 * k = 2^a, 3 2^a up to the stop the same within 1%; coefficients of the
 * powers of two stay within +-11 (consecutive k: up to +-35). */
#define COMB_J MCF_FAIRING_COMB

/* The probe traces of both engines by Lanczos quadrature
 * (mcf_fairing_trace.c). */
typedef struct mcf__fair_lz mcf__fair_lz;

/* What a run hands to a second run on the same input so that both SUREs
 * estimate the same risk with correlated probes (mcf__fair_pick_uncreased):
 * its noise levels, and its probes by vertex (fid: vertex -> free index
 * into probe, nprobe x nfree). */
typedef struct {
    double s, s_t, s2_rel;
    const double *probe;
    const int *fid;
    int nfree, nprobe;         /* nprobe probes of nfree each: a run that
                                  takes them carries at most as many */
} fair_share;

typedef struct fair_ctx {
    const mcf_flow_params *p;
    int nv, nf, nfree;
    const int32_t *F;
    double *X0;                /* a copy of the input, working units
                                  (crease vertices smoothed along) */
    double *Xin;               /* the input itself where X0 differs
                                  (creases), else NULL */
    const double *fn_orig;     /* 3*nf: the request's input's face normals
                                  when the spike stage repaired it (the
                                  guard's second reference), else NULL */
    unsigned char *crease;     /* nv: on a kept crease */
    unsigned char *chains;     /* g.ptr[nv]: the creases' edges (mcf__creases) */
    unsigned char *fx;         /* nv: fixed, or no edge */
    mcf__graph g;              /* mcf__fairing's, lent to every run */
    int *vert;                 /* nfree: free index -> vertex */
    int *fid;                  /* nv: vertex -> free index, -1 fixed */
    double *sq;                /* nfree: sqrt(D) */
    double *w;                 /* nv: area weights (0 on fixed) */
    double *n0;                /* 3*nv: normals of X0 */
    double *probe;             /* nprobe * nfree: the Rademacher probes */
    int nprobe;                /* NPROBE, or NPROBE_FEW on a large mesh */
    int ncol;                  /* 3, or 3 + nprobe: the explicit passes
                                  carry the probes unless lz reads them */
    int is_explicit;
    int no_creases;            /* the default request's second look: no
                                  creases held (mcf__fair_pick_uncreased) */
    const fair_share *like;    /* a first run's noise levels and probes,
                                  taken, not read or drawn again */
    /* a run on the submesh near a first run's creases
     * (mcf_fairing_sub.c): that run's crease vertices, their chains'
     * edges (in this run's graph) and its input smoothed along them,
     * taken instead of found; NULL otherwise */
    const unsigned char *given_crease, *given_chains;
    const double *given_X0;
    /* the default request's explicit run after its implicit run (the
     * same input, fixed set and graph, and like = &setup_from->share):
     * that run's set-up (creases, free set, degrees, weights, normals,
     * X0 already clamped at the same noise level) copied, not found
     * again; NULL otherwise */
    const struct fair_ctx *setup_from;
    int exact;                 /* the default request: the positions are
                                  exact (mcf_fairing_input.c, FLAT_SHARE): no
                                  noise to read */
    double grid[3];            /* the default request: the steps of the
                                  grid the positions are quantized to
                                  (mcf__lattice), when it explains the
                                  noise read (mcf_fairing_input.c);
                                  0: none */
    int quiet;                 /* the hook sees no steps (cancel only) */
    double w0, w1;             /* its share of the run's work (mcf_fairing.c, work()) */
    double work_done;          /* the last share reported: never less */
    /* explicit: Z (nv x ncol, row-major), tmp the same */
    double *Z, *tmp;
    /* implicit */
    mcf__pattern apat;         /* I + N N' (upper triangle) */
    double *ax;                /* its values */
    mcf__chol *chol;
    double *Yc;                /* nfree x ncol, column-major: y */
    mcf__fair_lz *lz;          /* with SURE, implicit, or explicit after
                                  the implicit run (lz_from): the probes'
                                  traces */
    struct fair_ctx *lz_from;  /* a run on the same free vertices and
                                  probes whose lz this run takes
                                  (mcf__fair_lz_fits), else NULL */
    double *b;                 /* 3 * nfree: N u, column-major */
    size_t bytes;
    mcf_flow_stats *st;
    double *threads_cpu_s;     /* the caller's mcf_flow_stats.threads_cpu_s
                                  (the pick's explicit run too, whose st is
                                  its own), grown as the passes run */
    /* the run (mcf__fairing's phases) */
    double hbar;               /* the mean edge */
    int sure;                  /* the amount by SURE (else iterations) */
    int cap;                   /* the most steps */
    double s, s_t;             /* the noise levels, normal and tangential */
    double *Y, *Ybest, *Yt;    /* 3*nv: the last step, SURE's best (normal,
                                  tangential) */
    int kbest, kbest_t;        /* their steps */
    double risk;               /* SURE at kbest (sum w units) */
    double trbest[NPROBE];     /* its probes' weighted traces */
    float *dk[COMB_J];         /* 3*nfree: Y_k - X0 on the free vertices
                                  after the last powers of two k, oldest
                                  first */
    int kk[COMB_J], nk;        /* their k, how many */
    double trq[COMB_J][NPROBE]; /* their probes' weighted traces */
    fair_share share;          /* what a second run takes from this one */
    double sumw2;              /* sum_F w^2 (sum_F w = nfree) */
    double s2_rel;             /* relative standard error of s^2 */
} fair_ctx;

/* the creases' smoothing along them moves a vertex by at most one noise
 * level: on car.drc's coarse chains (hubs of 11-12 edges) it took shape
 * away at 2 (normal noise 0.25, seeds 1-3: 0.959, 0.853, 0.973 of the
 * input's error; 1: 0.852, 0.831, 0.900); the box of test_creases_kept
 * and the shared scans change by less than 1% */
#define CREASE_MAX_MOVE 1.0

/* mcf_fairing.c */
/* n doubles (at least one) counted in c->bytes; NULL when out of memory. */
double *mcf__fair_alloc(fair_ctx *c, size_t n);
/* One filter's whole run on X (3*nv) up to its result along the normals
 * (c->Ybest, c->risk) and its tangential iterate; c->is_explicit,
 * c->quiet, c->like, c->no_creases, c->given_* set by the caller; g the
 * graph of F (borrowed). */
mcf_status mcf__fair_filter_run(fair_ctx *c, const mcf__graph *g, const double *X, const int32_t *F, int nf, int nv,
                                const unsigned char *fixed, const mcf_flow_params *p, double hbar,
                                mcf_flow_stats *st, mcf__step_hook hook, void *hook_ctx, mcf_error *err);
/* c's arrays freed (not its graph, which is lent). */
void mcf__fair_free(fair_ctx *c);

/* mcf_fairing_sub.c */
/* Each probe's estimate of the divergence SURE needs at the crease
 * vertices of run c (held; n: the same filter with none held), into kdiv;
 * 0 when out of memory (the run keeps its creases). */
int mcf__fair_crease_divergence(const fair_ctx *c, const fair_ctx *n, const unsigned char *fixed,
                                double kdiv[NPROBE]);
/* The default request's second look judged near the creases: c, a run
 * prepared up to its probes (its passes not made) that holds its crease
 * vertices, is made again, held and with none held, on the submesh of
 * the vertices within SUB_RINGS rings of them (the rest fixed), and
 * mcf__fair_pick_uncreased judges there; where that submesh is more
 * than SUB_MAX_SHARE of the mesh, on the submesh near a sample of its
 * chains (SUB_SAMPLE_SHARE), which decides only when its z is beyond
 * SUB_SAMPLE_Z either way. *judged: 1 none held, 0 held, -1 not judged
 * (judge on the whole, both runs in full); *sampled 1 when a sample
 * judged; *bytes the judgement's bytes at most. X the run's input
 * (3*nv). ENOMEM, ECANCELED. */
mcf_status mcf__fair_judge_near_creases(const fair_ctx *c, const double *X, const unsigned char *fixed,
                                        mcf__step_hook hook, void *hook_ctx, int *judged, int *sampled,
                                        size_t *bytes, mcf_error *err);

/* mcf_fairing_implicit.c */
/* The implicit engine's system assembled and factored, its right-hand
 * side and first columns (y0 = D^1/2 x0, then the probes) set: ENOMEM,
 * ELIMIT, or the factorization's failure. */
mcf_status mcf__fair_implicit_init(fair_ctx *c, mcf_error *err);
/* One implicit step: every column of c->Yc solved through A. */
mcf_status mcf__fair_implicit_step(fair_ctx *c, mcf_error *err);

/* mcf_fairing_trace.c */
/* The Lanczos runs' state for c's probes (c->lz; c->probe, c->sq, c->w,
 * c->vert, c->fid set): ENOMEM. */
mcf_status mcf__fair_lz_new(fair_ctx *c, mcf_error *err);
void mcf__fair_lz_free(mcf__fair_lz *lz);
/* Whether from's Lanczos runs serve c: the same graph, free vertices,
 * degrees, weights and probes (the default request's explicit run after
 * its implicit one). */
int mcf__fair_lz_fits(const fair_ctx *c, const fair_ctx *from);
/* Each probe's z' W f_k(N) z into est, f_k(l) = (1 + l^2)^-k (the
 * implicit step's R^k, R = (I + N N')^-1) or, c->is_explicit, P(l)^k (k
 * lambda|mu passes), settled to 1e-12 nfree (more Lanczos steps made when
 * needed): ENOMEM. */
mcf_status mcf__fair_lz_trace(fair_ctx *c, int k, double est[NPROBE], mcf_error *err);

/* mcf_fairing_input.c: the default request's reading of its input X
 * before the filter: the grid's steps into grid when its rounding
 * explains the noise read (else zeros), whether the positions are exact
 * into *exact, and, on neither, X's spikes repaired in a copy *Xs (the
 * caller's to free; NULL when none), their count into
 * st->spikes_repaired. ENOMEM only. */
mcf_status mcf__fair_read_input(const mcf__graph *g, const double *X, const int32_t *F, int nf, int nv,
                                const unsigned char *fixed, double hbar, double grid[3], int *exact,
                                mcf_flow_stats *st, double **Xs, mcf_error *err);
/* the noise of rounding to a grid of steps q, along any direction */
double mcf__fair_grid_level(const double q[3]);

/* mcf_fairing_sure.c */
/* A step's probe estimates of sum_i w_i (T^K)_ii when the explicit
 * passes carry the probes (est; c->ncol > 3) and SURE's moments of the
 * displacement Y - X0 (m), in one sweep; the explicit engine's positions
 * are written into Y's free rows on the way (its other rows must hold
 * X0), the implicit engine's read from Y. */
void mcf__fair_step_moments(const fair_ctx *c, double *Y, double est[NPROBE], double m[6]);
/* The mean of the nprobe probes' estimates est, and the variance of that
 * mean (*var). */
double mcf__fair_mean_trace(const double *est, int nprobe, double *var);
/* SURE(K) and its gain over the input in standard errors (*z). */
double mcf__fair_sure_of(const fair_ctx *c, int dim, double sig, const double *mo, double tr, double vtr,
                         double *z);
/* Keeps Y - X0 after k steps as the newest of the last COMB_J iterates. */
void mcf__fair_keep_iterate(fair_ctx *c, int k, const double *Y, const double est[NPROBE]);
/* SURE's best combination of the kept iterates into c->Ybest when it
 * passes its tests. */
void mcf__fair_combine(fair_ctx *c);
/* Whether the explicit run e replaces the implicit run i. */
int mcf__fair_pick_explicit(const fair_ctx *i, const fair_ctx *e);
/* Whether the run n, the same filter on the same input with no creases
 * held, replaces the run c, which held its crease vertices: SURE over
 * n's free vertices (c's and its creases), c's crease vertices counted
 * with their displacement (the smoothing along their chains) and kdiv,
 * each probe's estimate of their divergence weighted by n's weights
 * (mcf__fair_crease_divergence); the gain must pass
 * UNCREASE_MIN_GAIN of its standard error. z (may be NULL): the gain in
 * its standard errors, NaN when it was not judged (n took no step). */
int mcf__fair_pick_uncreased(const fair_ctx *c, const fair_ctx *n, const double kdiv[NPROBE], double *z);
/* The default request runs the feature-aware stage when the creases the
 * linear fairing holds (mcf__creases) are at least FEATURE_CREASE_SHARE of
 * the vertices it moves and at most FEATURE_CREASE_MAX. Measured with
 * normal noise 0.1-0.5 h, seed 1 (make quality, 2026-11-28): the CAD parts
 * blade.obj 5.4% (0.1 h), 12.6% (0.25 h), 30% (0.5 h) and
 * couplingdown_sub2.obj 22-31%; the shared organic meshes 0-4.1%
 * (bunny_npm_closed.obj at 0.5 h), except snowden.obj, a 54k-vertex scan
 * with real sharp edges, 7.3-9.4%, where the stage cost 8x the linear
 * fairing (27-31 s of CPU against 3.5 s) for the same error (taken at 0.1 h:
 * 0.534 of the input's against 0.533). So blade.obj at 0.1 h goes without
 * (0.197 of the input's error against 0.159 with the stage). The margins
 * are thin (9.4% below, 12.6% above): a wrong gate costs time, or the
 * stage's gain, never more than that (SURE still compares the results).
 * Past the upper bound nearly every vertex is on a crease (car.drc, 920
 * vertices: 72-82%), a tessellation as coarse as its features, where the
 * stage's own noise reading (mcf_feature.c) takes the filter's bias for
 * noise (0.19 h for 0.1 h) and the result it took was 1.48 of the input's
 * error (the linear fairing's 0.93). */
#define FEATURE_CREASE_SHARE 0.10
#define FEATURE_CREASE_MAX 0.5
/* What the feature-aware stage is compared with: the input (the named
 * `fairing_feature`, or c found nothing: SURE_MIN_GAIN); c's result
 * (the default request's choice, PICK_MIN_GAIN, as the choice between the
 * implicit steps and the passes); or c's result with its creases held,
 * before the run with none held, which it then replaces (the default
 * request: FEATURE_HELD_GAIN, mcf_fairing_sure.c). */
enum { FEAT_VS_INPUT, FEAT_VS_LINEAR, FEAT_VS_HELD };
/* The feature-aware stage (mcf_feature.c) on the input, X its output when
 * SURE takes it (*taken), compared as vs (FEAT_VS_*) says; the same
 * weights, noise level and probes as c's SURE; fixed: the vertices the
 * run holds (not the creases). ENOMEM, ELIMIT. */
mcf_status mcf__fair_feature(fair_ctx *c, int vs, const unsigned char *fixed, double *X, int *taken, mcf_error *err);

/* mcf_fairing_output.c */
/* Moves from the input (c->Xin) longer than rmax taken back, on the
 * vertices marked in only (NULL: all). */
void mcf__fair_clamp_moves(const fair_ctx *c, double *X, double rmax, const unsigned char *only);
/* The same from the positions ref instead of the input. */
void mcf__fair_clamp_from(const fair_ctx *c, const double *ref, double *X, double rmax, const unsigned char *only);
/* The output into X: along the normals of the filtered surface, relaxed
 * in its tangent planes, clamped, guarded. */
mcf_status mcf__fair_output(fair_ctx *c, double *X, mcf_error *err);
/* The feature stage's result Yf as the output into X: mcf__feature_output
 * with moves bounded by MAX_MOVE noise levels sf (the stage's reading);
 * the flips repair's (the default request) and the guard's counts into c->st. */
mcf_status mcf__fair_feature_output(fair_ctx *c, const double *Yf, const unsigned char *fixed, double sf, double *X,
                                    mcf_error *err);

#endif
