/* SPDX-License-Identifier: MIT */
/*
 * study_adaptive.c - `mcflab adaptive`: does adaptive stepping keep its
 * promise (issue 30)? On one mesh at one amount, per scheme and tol: the
 * adaptive run's steps, rejections, solves, factorizations and CPU time,
 * its error against a converged fixed-step reference (RMS in tol's norm
 * and the max over the vertices), the run's own estimate, and the work of
 * the cheapest fixed-step run of the same scheme at least as accurate.
 *
 *   mcflab adaptive --mesh FILE --out DIR [--strength S] [--noise RHO]
 *                   [--schemes S1,S2] [--tols T1,T2] [--ref-steps N]
 *
 * Norms (docs/MATH.md, "Error norm"): tol is relative to the unit-area
 * size, so every error here is divided by sqrt(area of the input): RMS is
 * the mass-weighted RMS (the reference's lumped mass) and max the largest
 * vertex distance. The reference is desbrun2 with --ref-steps equal steps
 * (1600); it is shown converged by its distance to a run with a quarter of
 * the steps, printed first. The fixed-step runs take 1, 2, 3, 4, 6, 8, ...
 * (about sqrt 2 apart) steps up to a quarter of the reference's.
 */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "study.h"

#define MAX_TOLS 8
#define MAX_FIXED 40

typedef struct {
    const char *mesh, *out;
    double strength, rho;
    mcf_scheme schemes[MCF_NSCHEMES];
    int nschemes;
    double tols[MAX_TOLS];
    int ntols, ref_steps, quiet;
} aopts;

typedef struct {
    int ok, steps, rejected, solves, factorizations;
    double cpu, rms, max, est;
    char msg[MCF_ERRMSG_SIZE];
} arun;

static double cpu_now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* Runs scheme s on a copy of m0 to time T: adaptive with tol (tol > 0) or
 * n equal steps; the result against ref (may be NULL) into r, the mesh
 * into *out (may be NULL). 0, or 1 when memory runs out. */
static int arun_flow(const mcf_mesh *m0, const mcf_mesh *ref, mcf_scheme s, double T, double tol, int n,
                     double size, arun *r, mcf_mesh **out)
{
    mcf_mesh *m = mcf_mesh_dup(m0, NULL);
    mcf_flow_params p;
    mcf_flow_stats st;
    mcf_error err = {MCF_OK, ""};
    memset(r, 0, sizeof *r);
    if (!m)
        return lab_fail(1, "out of memory");
    mcf_flow_params_init(&p);
    p.scheme = s;
    p.time = T;
    if (tol > 0.0) {
        p.adaptive = 1;
        p.tol = tol;
        p.max_steps = 200000;
    } else {
        p.iterations = n;
    }
    double t0 = cpu_now();
    r->ok = mcf_flow_run(m, &p, &st, &err) == MCF_OK;
    r->cpu = cpu_now() - t0;
    snprintf(r->msg, sizeof r->msg, "%s", r->ok ? "" : err.msg);
    r->steps = st.steps;
    r->rejected = st.rejected;
    r->solves = st.solves;
    r->factorizations = st.factorizations;
    r->est = st.error_estimate;
    mcf_flow_stats_free(&st);
    if (ref) {
        mcf_compare_result c;
        if (mcf_compare(m, ref, &c, &err) != MCF_OK) {
            mcf_mesh_free(m);
            return lab_fail(1, "%s", err.msg);
        }
        r->rms = c.rms_m / size;
        r->max = c.max_err / size;
    }
    if (out)
        *out = m;
    else
        mcf_mesh_free(m);
    return 0;
}

static int parse_list(const char *flag, const char *v, double *out, int cap, int *n)
{
    const char *p = v;
    *n = 0;
    while (*p) {
        char *end;
        errno = 0;
        double x = strtod(p, &end);
        if (end == p || errno || !(x > 0.0 && x <= 1.0) || (*end != ',' && *end) || *n == cap)
            return lab_fail(LAB_EXIT_USAGE, "--%s: expected up to %d numbers in (0, 1] separated by commas, got '%s'",
                            flag, cap, v);
        out[(*n)++] = x;
        p = *end ? end + 1 : end;
    }
    return *n ? 0 : lab_fail(LAB_EXIT_USAGE, "--%s: empty list", flag);
}

static int parse(int argc, char **argv, aopts *o)
{
    memset(o, 0, sizeof *o);
    o->strength = 0.5;
    o->ref_steps = 1600;
    o->schemes[0] = MCF_DESBRUN2;
    o->schemes[1] = MCF_ROS2;
    o->schemes[2] = MCF_RICHARDSON;
    o->nschemes = 3;
    static const double tols[4] = {1e-3, 1e-4, 1e-5, 1e-6};
    memcpy(o->tols, tols, sizeof tols);
    o->ntols = 4;
    for (int i = 2; i < argc; i++) {
        const char *f = argv[i];
        if (!strcmp(f, "--quiet")) {
            o->quiet = 1;
            continue;
        }
        if (i + 1 >= argc)
            return lab_fail(LAB_EXIT_USAGE, "%s needs a value", f);
        const char *v = argv[++i];
        char *end;
        if (!strcmp(f, "--mesh")) {
            o->mesh = v;
        } else if (!strcmp(f, "--out")) {
            o->out = v;
        } else if (!strcmp(f, "--strength") || !strcmp(f, "--noise")) {
            double x = strtod(v, &end);
            if (end == v || *end || !isfinite(x) || x < 0.0 || (x == 0.0 && f[2] == 's'))
                return lab_fail(LAB_EXIT_USAGE, "%s: expected a number (> 0 for --strength), got '%s'", f, v);
            *(f[2] == 's' ? &o->strength : &o->rho) = x;
        } else if (!strcmp(f, "--ref-steps")) {
            long x = strtol(v, &end, 10);
            if (end == v || *end || x < 16 || x > 1000000)
                return lab_fail(LAB_EXIT_USAGE, "--ref-steps: expected an integer in [16, 1000000], got '%s'", v);
            o->ref_steps = (int)x;
        } else if (!strcmp(f, "--tols")) {
            if (parse_list("tols", v, o->tols, MAX_TOLS, &o->ntols))
                return LAB_EXIT_USAGE;
        } else if (!strcmp(f, "--schemes")) {
            o->nschemes = 0;
            for (const char *p = v; *p;) {
                char name[32];
                size_t n = strcspn(p, ",");
                mcf_scheme s;
                if (n == 0 || n >= sizeof name || o->nschemes == MCF_NSCHEMES)
                    return lab_fail(LAB_EXIT_USAGE, "--schemes: bad list '%s'", v);
                memcpy(name, p, n);
                name[n] = '\0';
                if (mcf_scheme_from_name(name, &s) != MCF_OK || !mcf_scheme_get(s)->has_estimate)
                    return lab_fail(LAB_EXIT_USAGE, "--schemes: '%s' is no scheme with an error estimate", name);
                o->schemes[o->nschemes++] = s;
                p += n + (p[n] == ',');
            }
        } else {
            return lab_fail(LAB_EXIT_USAGE, "adaptive: unknown option '%s'", f);
        }
    }
    if (!o->mesh || !o->out)
        return lab_fail(LAB_EXIT_USAGE, "adaptive needs --mesh FILE and --out DIR");
    return 0;
}

int study_adaptive(int argc, char **argv)
{
    aopts o;
    mcf_mesh *m0 = NULL, *ref = NULL, *ref4 = NULL;
    mcf_error err = {MCF_OK, ""};
    FILE *f = NULL;
    char path[4096];
    int rc;
    if ((rc = parse(argc, argv, &o)) != 0)
        return rc;
    if ((rc = lab_mkdir_p(o.out)) != 0 || (rc = lab_load_mesh(o.mesh, &m0)) != 0)
        return rc;
    rc = 1;
    if (o.rho > 0.0) {
        mcf_flow_params p;
        mcf_flow_params_init(&p);
        if (mcf_flow_add_noise(m0, &p, o.rho, 1, &err) != MCF_OK) {
            lab_fail(1, "%s", err.msg);
            goto done;
        }
    }
    /* the time of the amount: what a run at this strength covers */
    double size = sqrt(mcf_mesh_area(m0)), T;
    {
        mcf_mesh *m = mcf_mesh_dup(m0, NULL);
        mcf_flow_params p;
        mcf_flow_stats st;
        mcf_flow_params_init(&p);
        p.strength = o.strength;
        p.iterations = 1;
        if (!m || mcf_flow_run(m, &p, &st, &err) != MCF_OK) {
            mcf_mesh_free(m);
            lab_fail(1, "the amount: %s", m ? err.msg : "out of memory");
            goto done;
        }
        T = st.t_final;
        mcf_flow_stats_free(&st);
        mcf_mesh_free(m);
    }
    arun rr, r4;
    if (arun_flow(m0, NULL, MCF_DESBRUN2, T, 0.0, o.ref_steps, size, &rr, &ref) ||
        arun_flow(m0, ref, MCF_DESBRUN2, T, 0.0, o.ref_steps / 4, size, &r4, NULL))
        goto done;
    if (!rr.ok || !r4.ok) {
        lab_fail(1, "the reference failed: %s", rr.ok ? r4.msg : rr.msg);
        goto done;
    }
    snprintf(path, sizeof path, "%s/%s-adaptive.csv", o.out, strrchr(o.mesh, '/') ? strrchr(o.mesh, '/') + 1 : o.mesh);
    if (!(f = lab_csv_open(path)))
        goto done;
    fprintf(f, "mesh,vertices,noise,strength,T,scheme,tol,steps,rejected,solves,factorizations,cpu_s,rms,max,estimate,"
               "fixed_steps,fixed_solves,fixed_factorizations,fixed_cpu_s,fixed_rms,fixed_max,message\n");
    printf("%s: %d vertices, noise %g, strength %g (T = %.3e in unit-area time); reference desbrun2 %d steps, "
           "its distance to %d steps: RMS %.1e, max %.1e (relative to sqrt(area))\n\n",
           o.mesh, mcf_mesh_nvertices(m0), o.rho, o.strength, T, o.ref_steps, o.ref_steps / 4, r4.rms, r4.max);
    printf("| scheme | tol | steps (+rej) | factorizations | CPU s | RMS | RMS/tol | max/tol | estimate/tol | "
           "fixed steps as accurate | their factorizations | CPU s | factorizations as accurate in RMS and max |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (int k = 0; k < o.nschemes; k++) {
        mcf_scheme s = o.schemes[k];
        arun fx[MAX_FIXED];
        int nfx = 0, nmax = o.ref_steps / 4;
        /* fixed steps about sqrt 2 apart */
        for (double n = 1; (int)n <= nmax && nfx < MAX_FIXED; n = fmax(n + 1, floor(n * 1.41421356237))) {
            if (arun_flow(m0, ref, s, T, 0.0, (int)n, size, &fx[nfx], NULL))
                goto done;
            fx[nfx++].steps = (int)n;
            note(&(xopts){.quiet = o.quiet}, "%s fixed %d: rms %.2e\n", mcf_scheme_get(s)->name, (int)n, fx[nfx - 1].rms);
        }
        for (int j = 0; j < o.ntols; j++) {
            arun a;
            if (arun_flow(m0, ref, s, T, o.tols[j], 0, size, &a, NULL))
                goto done;
            /* as accurate: in RMS (best), in RMS and max (both) */
            const arun *best = NULL, *both = NULL;
            for (int i = 0; i < nfx && !best; i++)
                if (fx[i].ok && fx[i].rms <= a.rms)
                    best = &fx[i];
            for (int i = 0; i < nfx && !both; i++)
                if (fx[i].ok && fx[i].rms <= a.rms && fx[i].max <= a.max)
                    both = &fx[i];
            fprintf(f, "%s,%d,%g,%g,%.6e,%s,%g,%d,%d,%d,%d,%.4f,%.4e,%.4e,%.4e,", o.mesh, mcf_mesh_nvertices(m0), o.rho,
                    o.strength, T, mcf_scheme_get(s)->name, o.tols[j], a.steps, a.rejected, a.solves, a.factorizations,
                    a.cpu, a.rms, a.max, a.est);
            if (best)
                fprintf(f, "%d,%d,%d,%.4f,%.4e,%.4e,", best->steps, best->solves, best->factorizations, best->cpu,
                        best->rms, best->max);
            else
                fprintf(f, ",,,,,,");
            char msg[MCF_ERRMSG_SIZE];
            lab_csv_clean(a.msg, msg, sizeof msg);
            fprintf(f, "%s\n", msg);
            if (!a.ok) {
                printf("| %s | %g | failed: %s |\n", mcf_scheme_get(s)->name, o.tols[j], a.msg);
                continue;
            }
            printf("| %s | %g | %d (+%d) | %d | %.2f | %.2e | %.2f | %.1f | %.2f | ", mcf_scheme_get(s)->name, o.tols[j],
                   a.steps, a.rejected, a.factorizations, a.cpu, a.rms, a.rms / o.tols[j], a.max / o.tols[j],
                   a.est / o.tols[j]);
            if (best)
                printf("%d | %d | %.2f | ", best->steps, best->factorizations, best->cpu);
            else
                printf("> %d | - | - | ", nmax);
            if (both)
                printf("%d |\n", both->factorizations);
            else
                printf("> %d steps |\n", nmax);
        }
    }
    rc = lab_csv_close(f, path);
    f = NULL;
done:
    if (f)
        fclose(f);
    mcf_mesh_free(m0);
    mcf_mesh_free(ref);
    mcf_mesh_free(ref4);
    return rc;
}
