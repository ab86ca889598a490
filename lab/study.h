/* SPDX-License-Identifier: MIT */
/*
 * study.h - the flow studies of `mcflab` (the article's experiments done
 * properly, docs/MATH.md "Measuring order and error"): their options, one
 * run of the flow with what it measured, the CSV rows every study writes,
 * and each study's entry point (study_*.c).
 *
 *   dt-sweep   a clean target, a noisy copy (Gaussian along the normals,
 *              sigma = rho * mean edge, seeded), every chosen scheme over a
 *              log-spaced dt range, a fixed number of iterations (10, as
 *              the article) or a fixed final time.
 *   stability  per scheme, the largest dt whose run ends without failure,
 *              NaN or a face folded in a step and with an error under a
 *              threshold, next to the theory.
 *   order      the error at a fixed final time against a fine reference
 *              run, and the fitted slope per scheme.
 *   sphere     R(t) and V(t) of each scheme against sqrt(R0^2 - 4t).
 *
 * Units: a mesh read from a file is centred on its area centroid and
 * scaled to unit area once, up front (what `mcf smooth` does by default),
 * and every run then flows with normalize off. So dt, time, lambda_max and
 * the errors share the unit-area units of `mcf smooth --dt`, and
 * dt * lambda_max reads directly against the explicit bounds. An icosphere
 * (--sphere LEVEL) keeps its radius (default 1): the radius law is stated
 * in those units. A run of the flow that fails (ENUMERIC, ENOCONV, ELIMIT,
 * ...) is a data point, written with its status; only I/O, memory and
 * usage errors end a study.
 */
#ifndef STUDY_H
#define STUDY_H

#include <stdint.h>
#include <stdio.h>

#include "lab.h"

#define MAX_DT 512          /* points of a dt grid */
#define MAX_LIST 24         /* entries of a --steps list */

typedef enum { ST_DTSWEEP, ST_STABILITY, ST_ORDER, ST_SPHERE } study_kind;

typedef struct {
    study_kind study;
    const char *study_name;
    const char *mesh_path;      /* NULL: an icosphere */
    int level;                  /* icosphere level */
    double radius;              /* icosphere radius */
    char name[128];             /* prefix of every output file */
    const char *out;
    mcf_scheme schemes[MCF_NSCHEMES];
    int nschemes;
    double rho;
    uint64_t seed;
    double dt_min, dt_max;      /* absolute, or multiples of 1/lambda */
    int dt_min_lam, dt_max_lam; /* 1: the value is a multiple of 1/lambda */
    int per_decade;
    int iterations;
    double time;                /* > 0: fixed final time */
    double threshold;           /* stability: largest acceptable rms_rel */
    int bisect;
    mcf_boundary boundary;
    int steps[MAX_LIST];
    int nsteps;
    mcf_scheme ref_scheme;
    int ref_factor;
    double presmooth;           /* order: time of a desbrun2 pre-smoothing */
    int picard_maxit;
    int max_steps;
    int quiet;
    lab_plot plot;              /* the figures: in out, header "NAME: mcflab STUDY" */
    char plot_header[200];
    const char *units;          /* how dt and time are measured, for labels */
} xopts;

/* The usage lines of the studies, for `mcflab --help`. */
extern const char study_usage[];

/* A filter (taubin, the fairing filters): no dt, no stability limit, no
 * order; the dt sweep runs it once for its passes. */
int is_filter(mcf_scheme s);

/* Parses argv[1..] (argv[1] the study) into o with the per-study
 * defaults of what was not given. 0, or the exit status after lab_fail. */
int study_parse(int argc, char **argv, xopts *o);

/* Progress lines on stderr, unless --quiet. */
void note(const xopts *o, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

/* One run of the flow and what it measured. */
typedef struct {
    mcf_scheme scheme;
    double dt;                /* the step taken (dt_first) */
    double dt_req;            /* the step asked for */
    int iterations;           /* asked for (0: fixed time) */
    mcf_status status;
    char msg[MCF_ERRMSG_SIZE];
    int steps;
    double t_final;
    mcf_compare_result cmp;   /* against the target (zero without one) */
    int flipped;              /* faces turned > 90 degrees from the start;
                                 smoothing also unfolds faces the noise
                                 folded, so this is not a defect count */
    int folded, folded_steps; /* faces folded in a step, steps that folded */
    int nonfinite;            /* non-finite coordinates in the result */
    double area_drift, volume_drift; /* relative to the run's start */
    double wall;
    int solves, factorizations, picard;
} xrun;

/* Runs scheme s from a copy of start, with iters steps of dt or (T > 0)
 * to time T; compares the result with target (may be NULL). The flow's
 * failure is recorded in r. *out (may be NULL) receives the final mesh,
 * stats (may be NULL) the flow statistics (caller frees them). Returns 0,
 * or 1 after an error line when memory runs out. */
int run_flow(const xopts *o, const mcf_mesh *start, const mcf_mesh *target, mcf_scheme s, double dt, int iters,
             double T, int log_steps, xrun *r, mcf_mesh **out, mcf_flow_stats *stats);
/* The run finished with finite positions. */
int run_ok(const xrun *r);
/* Its progress line. */
void run_note(const xopts *o, const xrun *r);

/* The CSV columns of a run, and one row of them (without the line end:
 * run_csv_fields; with it: run_csv_row); lam is lambda_max for dt_lambda. */
extern const char run_csv_header[];
void run_csv_fields(FILE *f, const xopts *o, const xrun *r, double lam);
void run_csv_row(FILE *f, const xopts *o, const xrun *r, double lam);

/* OUT/NAME-suffix opened for writing (its path into path), or NULL after
 * lab_fail. */
FILE *study_csv_open(const xopts *o, const char *suffix, char *path, size_t size);

/* The study's clean mesh: the file at unit area, or the icosphere. 0, or 1
 * after lab_fail. */
int study_mesh(const xopts *o, mcf_mesh **out);
/* The mesh of a dt study: the study mesh (*target), a copy of it with the
 * noise of o->rho and o->seed (*noisy), their comparison (*c0) and the
 * noisy mesh's lambda_max (*lam). Returns 0, or 1 after lab_fail; on
 * failure *target and *noisy may still hold meshes: the caller frees both. */
int noisy_study_mesh(const xopts *o, mcf_mesh **target, mcf_mesh **noisy, mcf_compare_result *c0, double *lam);
/* The dt range [*lo, *hi] of o in time units: --dt-min and --dt-max given
 * as multiples of 1/lambda_max are divided by lam. Returns 0, or 1 after
 * lab_fail(LAB_EXIT_USAGE) when the range is empty: hi < lo, or hi == lo
 * unless one_point (a single dt is then a valid range). */
int dt_range(const xopts *o, double lam, int one_point, double *lo, double *hi);

/* Least-squares slope of log y against log x over the n points with both
 * positive and finite; NAN when fewer than two. */
double fit_loglog(const double *x, const double *y, int n, int *used);

/* Figures: a scheme's line style (one colour per scheme in every figure;
 * explicit dashed, implicit solid), a plot line "$block using ... with
 * ... title ..." in it, and the rendering of OUT/NAME-suffix.png and .svg. */
void gp_style(api_buf *b, mcf_scheme s, int points);
void gp_series(api_buf *b, int *first, const char *block, const char *using, const char *with, mcf_scheme s,
               const char *title);
int gp_render(xopts *o, const char *suffix, const api_buf *body);

/* The studies: 0, or the exit status after lab_fail. */
int study_dt_sweep(xopts *o);
int study_stability(xopts *o);
int study_order(xopts *o);
int study_sphere(xopts *o);
/* `mcflab adaptive` (study_adaptive.c) parses its own options: the error
 * of adaptive runs against tol (issue 30). 0, or the exit status. */
int study_adaptive(int argc, char **argv);

#endif /* STUDY_H */
