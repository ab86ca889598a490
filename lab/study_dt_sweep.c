/* SPDX-License-Identifier: MIT */
/*
 * study_dt_sweep.c - `mcflab dt-sweep`: the article's experiment done
 * properly. A clean target, a noisy copy, every chosen scheme over a
 * log-spaced dt range for a fixed number of steps (10, as the article) or
 * to a fixed final time. Per run: M-weighted RMS, Frobenius, normal angle
 * error, volume and area drift, folds, NaN, status, wall time, solves;
 * per scheme the best dt and the slope of the error's rising branch; the
 * error and the wall time against dt as figures.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "study.h"

typedef struct {
    int best;          /* index into the scheme's runs, -1: none OK */
    double slope;      /* log-log slope right of the minimum */
    int slope_points;
    int ok, failed;
    double largest_ok_dt;
} sweep_summary;

static void summarize_sweep(const xrun *rs, int n, sweep_summary *s)
{
    double x[MAX_DT], y[MAX_DT];
    int k = 0;
    memset(s, 0, sizeof *s);
    s->best = -1;
    s->slope = NAN;
    for (int i = 0; i < n; i++) {
        if (!run_ok(&rs[i])) {
            s->failed++;
            continue;
        }
        s->ok++;
        if (rs[i].dt > s->largest_ok_dt)
            s->largest_ok_dt = rs[i].dt;
        if (s->best < 0 || rs[i].cmp.rms_rel < rs[s->best].cmp.rms_rel)
            s->best = i;
    }
    if (s->best < 0)
        return;
    /* the rising branch: from the best dt on, until the error reaches half
     * of the largest one (past it the mesh has collapsed: it saturates) */
    double emax = 0;
    for (int i = 0; i < n; i++)
        if (run_ok(&rs[i]) && rs[i].cmp.rms_rel > emax)
            emax = rs[i].cmp.rms_rel;
    for (int i = s->best; i < n; i++)
        if (run_ok(&rs[i])) {
            x[k] = rs[i].dt;
            y[k] = rs[i].cmp.rms_rel;
            k++;
            if (rs[i].cmp.rms_rel >= 0.5 * emax)
                break;
        }
    if (k >= 3)
        s->slope = fit_loglog(x, y, k, &s->slope_points);
}

int study_dt_sweep(xopts *o)
{
    mcf_mesh *target = NULL, *noisy = NULL;
    xrun *runs = NULL;
    int *first = NULL, *count = NULL;
    double dts[MAX_DT], lam = 0;
    int ndt = 0, nruns = 0, rc = 1;
    mcf_compare_result c0;
    api_buf b;
    FILE *f = NULL;
    char path[4096];

    api_buf_init(&b, 64u << 20);
    if (noisy_study_mesh(o, &target, &noisy, &c0, &lam) != 0)
        goto done;
    double lo, hi;
    if (dt_range(o, lam, 1, &lo, &hi) != 0) {
        rc = LAB_EXIT_USAGE;
        goto done;
    }
    for (ndt = 0; ndt < MAX_DT - 1; ndt++) {
        double dt = lo * pow(10.0, (double)ndt / o->per_decade);
        if (dt > hi * (1 + 1e-9))
            break;
        dts[ndt] = dt;
    }
    /* the end of the range is always a point (at a fixed time: one step) */
    if (dts[ndt - 1] < hi * (1 - 1e-9))
        dts[ndt++] = hi;
    note(o, "%s: %d vertices, noise rho %g seed %llu: rms_rel %.4g; lambda_max %.6g (2/lambda %.4g); %d dt values "
            "%.3g..%.3g, %s %g\n",
         o->name, mcf_mesh_nvertices(target), o->rho, (unsigned long long)o->seed, c0.rms_rel, lam, 2 / lam, ndt,
         dts[0], dts[ndt - 1], o->time > 0 ? "time" : "iterations", o->time > 0 ? o->time : (double)o->iterations);

    runs = calloc((size_t)o->nschemes * (size_t)ndt, sizeof *runs);
    first = calloc((size_t)o->nschemes, sizeof *first);
    count = calloc((size_t)o->nschemes, sizeof *count);
    if (!runs || !first || !count) {
        lab_fail(1, "out of memory");
        goto done;
    }
    for (int k = 0; k < o->nschemes; k++) {
        mcf_scheme s = o->schemes[k];
        first[k] = nruns;
        if (is_filter(s)) {
            /* a filter: no dt, a number of passes; at a fixed time it has
             * no equivalent and is left out */
            if (o->time > 0)
                continue;
            if (run_flow(o, noisy, target, s, 0, o->iterations, 0, 0, &runs[nruns], NULL, NULL) != 0)
                goto done;
            runs[nruns].dt = runs[nruns].dt_req = runs[nruns].t_final = NAN;
            run_note(o, &runs[nruns]);
            nruns++;
        } else {
            for (int i = 0; i < ndt; i++) {
                if (run_flow(o, noisy, target, s, dts[i], o->iterations, o->time, 0, &runs[nruns], NULL, NULL) != 0)
                    goto done;
                run_note(o, &runs[nruns]);
                nruns++;
            }
        }
        count[k] = nruns - first[k];
    }

    /* the runs */
    if (!(f = study_csv_open(o, "dt-sweep.csv", path, sizeof path)))
        goto done;
    fprintf(f, "%s\n", run_csv_header);
    for (int i = 0; i < nruns; i++)
        run_csv_row(f, o, &runs[i], lam);
    if (lab_csv_close(f, path) != 0) {
        f = NULL;
        goto done;
    }
    /* per scheme: the best dt, its time and the slope right of it */
    if (!(f = study_csv_open(o, "dt-sweep-summary.csv", path, sizeof path)))
        goto done;
    fprintf(f, "mesh,scheme,lambda_max,noise_rho,seed,noisy_rms_rel,noisy_frobenius,noisy_normal_angle_deg,"
               "noisy_inverted_faces,"
               "iterations,time,best_dt,best_dt_lambda,best_time,best_rms_rel,best_frobenius,"
               "best_normal_angle_deg,rising_slope,slope_points,largest_ok_dt,ok_runs,failed_runs\n");
    sweep_summary *sum = calloc((size_t)o->nschemes, sizeof *sum);
    if (!sum) {
        fclose(f);
        f = NULL;
        lab_fail(1, "out of memory");
        goto done;
    }
    for (int k = 0; k < o->nschemes; k++) {
        const xrun *rs = runs + first[k];
        summarize_sweep(rs, count[k], &sum[k]);
        if (count[k] == 0)
            continue;
        const xrun *bst = sum[k].best >= 0 ? &rs[sum[k].best] : NULL;
        fprintf(f, "%s,%s,%.9g,%g,%llu,%.9g,%.9g,%.9g,%d,%d,%.9g,%.9g,%.6g,%.9g,%.9g,%.9g,%.9g,%.4f,%d,%.9g,%d,%d\n",
                o->name, mcf_scheme_get(o->schemes[k])->name, lam, o->rho, (unsigned long long)o->seed, c0.rms_rel,
                c0.frobenius, c0.normal_angle_deg, c0.inverted_faces, o->time > 0 ? 0 : o->iterations, o->time,
                bst ? bst->dt : NAN, bst ? bst->dt * lam : NAN, bst ? bst->t_final : NAN,
                bst ? bst->cmp.rms_rel : NAN, bst ? bst->cmp.frobenius : NAN, bst ? bst->cmp.normal_angle_deg : NAN,
                sum[k].slope, sum[k].slope_points, sum[k].largest_ok_dt, sum[k].ok, sum[k].failed);
    }
    if (lab_csv_close(f, path) != 0) {
        f = NULL;
        free(sum);
        goto done;
    }
    f = NULL;

    /* error against dt, and wall time against dt (not when no run of a
     * flow succeeded: nothing to draw) */
    int drawable = 0;
    for (int k = 0; k < o->nschemes; k++)
        drawable += !is_filter(o->schemes[k]) && sum[k].ok > 0;
    if (!drawable)
        note(o, "%s: no successful run of a flow: no dt-sweep plots\n", o->name);
    for (int fig = 0; fig < 2 && drawable; fig++) {
        char title[512], blk[32], leg[160];
        int plot_first = 1;
        b.len = 0;
        char what[96];
        if (o->time > 0)
            snprintf(what, sizeof what, "after a fixed time T = %g", o->time);
        else
            snprintf(what, sizeof what, "after %d steps of dt", o->iterations);
        snprintf(title, sizeof title,
                 "%s: %s %s\n{/*0.85 %d vertices; noise %g × mean edge (seed %llu): error %.3g; λ_{max} = %.4g}",
                 o->name, fig == 0 ? "error" : "wall time", what, mcf_mesh_nvertices(target), o->rho,
                 (unsigned long long)o->seed, c0.rms_rel, lam);
        char xl[160];
        snprintf(xl, sizeof xl, o->time > 0 ? "time step dt (%s)" : "time step dt (%s; total time = iterations × dt)",
                 o->units);
        lab_gp_axes(&b, title, xl,
                fig == 0 ? "error vs clean target: M-weighted RMS / sqrt(area)" : "wall time per run (s)", 1, 1);
        api_buf_printf(&b, "set xrange [%.9g:%.9g]\nset x2range [%.9g:%.9g]\nset logscale x2\n"
                           "set x2tics\nset x2label \"dt × λ_{max}\" offset 0,-0.4\nset tmargin 6.5\n"
                           "set format x2 \"10^{%%L}\"\n",
                       dts[0] / 1.5, dts[ndt - 1] * 1.5, dts[0] / 1.5 * lam, dts[ndt - 1] * 1.5 * lam);
        api_buf_printf(&b, "set arrow from %.9g, graph 0 to %.9g, graph 1 nohead lc rgb \"#555555\" dt 3 lw 1.5\n"
                           "set label \"2/λ_{max}\" at %.9g, graph 0.04 offset 0.5,0 textcolor rgb \"#555555\"\n",
                       2 / lam, 2 / lam, 2 / lam);
        for (int k = 0; k < o->nschemes; k++) {
            const xrun *rs = runs + first[k];
            int any = 0;
            if (is_filter(o->schemes[k]))
                continue;
            snprintf(blk, sizeof blk, "s%d", k);
            lab_gp_block_begin(&b, blk);
            for (int i = 0; i < count[k]; i++)
                if (run_ok(&rs[i])) {
                    api_buf_printf(&b, "%.9g %.9g\n", rs[i].dt, fig == 0 ? rs[i].cmp.rms_rel : rs[i].wall);
                    any = 1;
                }
            lab_gp_block_end(&b);
            if (!any)
                api_buf_printf(&b, "$%s << EOD\nNaN NaN\nEOD\n", blk);
        }
        for (int k = 0; k < o->nschemes; k++) {
            mcf_scheme s = o->schemes[k];
            const char *nm = mcf_scheme_get(s)->name;
            const xrun *rs = runs + first[k];
            if (is_filter(s)) {
                if (count[k] == 0 || !run_ok(&rs[0]))
                    continue;
                snprintf(leg, sizeof leg, "%s (a filter, no dt): %d passes", nm, o->iterations);
                api_buf_printf(&b, "%s %.9g with lines ", plot_first ? "plot" : ", \\\n    ",
                               fig == 0 ? rs[0].cmp.rms_rel : rs[0].wall);
                gp_style(&b, s, 0);
                api_buf_printf(&b, " title ");
                lab_gp_str(&b, leg);
                plot_first = 0;
                continue;
            }
            snprintf(blk, sizeof blk, "s%d", k);
            if (sum[k].ok == 0)
                snprintf(leg, sizeof leg, "%s: every run failed", nm);
            else if (fig == 0 && isfinite(sum[k].slope))
                snprintf(leg, sizeof leg, "%s (rising slope %.2f)", nm, sum[k].slope);
            else
                snprintf(leg, sizeof leg, "%s", nm);
            gp_series(&b, &plot_first, blk, "1:2", "linespoints", s, leg);
        }
        if (fig == 0) {
            api_buf_printf(&b, ", \\\n    %.9g with lines lc rgb \"#000000\" dt 3 lw 2 title \"noisy input\"",
                           c0.rms_rel);
        }
        api_buf_printf(&b, "\n");
        if (gp_render(o, fig == 0 ? "dt-sweep-error" : "dt-sweep-runtime", &b) != 0) {
            free(sum);
            goto done;
        }
    }
    free(sum);
    rc = 0;
done:
    if (f)
        fclose(f);
    api_buf_free(&b);
    free(runs);
    free(first);
    free(count);
    mcf_mesh_free(target);
    mcf_mesh_free(noisy);
    return rc;
}
