/* SPDX-License-Identifier: MIT */
/*
 * study_sphere.c - `mcflab sphere`: each scheme on an icosphere against the
 * sphere law R(t) = sqrt(R0^2 - 4t) (and its volume), the implicit schemes
 * in a given number of steps, the explicit ones at half their bound at the
 * final radius; the series as CSV and three figures.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "study.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define SERIES_POINTS 120   /* rows kept per scheme (CSV and plot) */

static double r_of_volume(double v)
{
    return cbrt(3.0 * v / (4.0 * M_PI));
}

int study_sphere(xopts *o)
{
    mcf_mesh *start = NULL;
    mcf_error err = {MCF_OK, ""};
    mcf_flow_stats *st = NULL;
    xrun *runs = NULL;
    double lam = 0;
    int rc = 1;
    api_buf b;
    FILE *f = NULL;
    char path[4096];

    api_buf_init(&b, 32u << 20);
    if (study_mesh(o, &start) != 0)
        goto done;
    if (mcf_lambda_max(start, MCF_LAPLACIAN_COTAN, MCF_MASS_BARYCENTRIC, &lam, &err) != MCF_OK) {
        lab_fail(1, "%s", err.msg);
        goto done;
    }
    double V0 = mcf_mesh_volume(start), R0 = r_of_volume(V0), T = o->time;
    double RT2 = R0 * R0 - 4 * T;
    if (!(RT2 > 0)) {
        lab_fail(LAB_EXIT_USAGE, "sphere: T = %g is past the extinction of the discrete sphere (R0 %.6g)", T, R0);
        rc = LAB_EXIT_USAGE;
        goto done;
    }
    /* lambda grows like 1/R^2: explicit schemes take half their bound at
     * the final radius */
    double lam_end = lam * R0 * R0 / RT2;
    note(o, "%s: %d vertices, R0 (volume) %.6f, T %g, R(T) exact %.6f, lambda_max %.6g -> %.6g at T\n", o->name,
         mcf_mesh_nvertices(start), R0, T, sqrt(RT2), lam, lam_end);
    runs = calloc((size_t)o->nschemes, sizeof *runs);
    st = calloc((size_t)o->nschemes, sizeof *st);
    if (!runs || !st) {
        lab_fail(1, "out of memory");
        goto done;
    }
    for (int k = 0; k < o->nschemes; k++) {
        const mcf_scheme_info *si = mcf_scheme_get(o->schemes[k]);
        int steps = o->steps[0];
        if (si->is_explicit)
            steps = (int)ceil(T / (0.5 * si->stability / lam_end));
        if (run_flow(o, start, NULL, o->schemes[k], T / steps, steps, 0, 1, &runs[k], NULL, &st[k]) != 0)
            goto done;
        note(o, "%s %-10s steps %-6d R(T) %.6f %s %.2f s\n", o->name, si->name, runs[k].steps,
             st[k].nlog > 0 ? r_of_volume(st[k].log[st[k].nlog - 1].volume) : NAN, mcf_status_name(runs[k].status),
             runs[k].wall);
    }

    if (!(f = study_csv_open(o, "sphere.csv", path, sizeof path)))
        goto done;
    fprintf(f, "mesh,scheme,step,t,area,volume,r_volume,r_area,r_exact,v_exact,r_rel_error,v_rel_error\n");
    for (int k = 0; k < o->nschemes; k++) {
        const mcf_flow_stats *s = &st[k];
        int stride = s->nlog > SERIES_POINTS ? (s->nlog + SERIES_POINTS - 1) / SERIES_POINTS : 1;
        fprintf(f, "%s,%s,0,0,%.12g,%.12g,%.12g,%.12g,%.12g,%.12g,0,0\n", o->name,
                mcf_scheme_get(o->schemes[k])->name, s->area0, V0, R0, sqrt(s->area0 / (4 * M_PI)), R0, V0);
        for (int i = 0; i < s->nlog; i++) {
            if ((i + 1) % stride != 0 && i != s->nlog - 1)
                continue;
            const mcf_step_log *lg = &s->log[i];
            double re = sqrt(fmax(R0 * R0 - 4 * lg->t, 0)), ve = 4.0 / 3.0 * M_PI * re * re * re;
            double rv = r_of_volume(lg->volume);
            fprintf(f, "%s,%s,%d,%.12g,%.12g,%.12g,%.12g,%.12g,%.12g,%.12g,%.6g,%.6g\n", o->name,
                    mcf_scheme_get(o->schemes[k])->name, i + 1, lg->t, lg->area, lg->volume, rv,
                    sqrt(lg->area / (4 * M_PI)), re, ve, fabs(rv - re) / re, fabs(lg->volume - ve) / ve);
        }
    }
    if (lab_csv_close(f, path) != 0) {
        f = NULL;
        goto done;
    }
    f = NULL;
    if (!(f = study_csv_open(o, "sphere-summary.csv", path, sizeof path)))
        goto done;
    fprintf(f, "mesh,scheme,explicit,status,steps,dt,dt_lambda0,T,r0,r_final,r_exact,r_rel_error,v_final,v_exact,"
               "v_rel_error,max_r_rel_error,wall_s,solves,factorizations\n");
    for (int k = 0; k < o->nschemes; k++) {
        const mcf_flow_stats *s = &st[k];
        const mcf_scheme_info *si = mcf_scheme_get(o->schemes[k]);
        double rf = NAN, vf = NAN, re = NAN, ve = NAN, maxe = 0;
        for (int i = 0; i < s->nlog; i++) {
            double r = r_of_volume(s->log[i].volume), x = sqrt(fmax(R0 * R0 - 4 * s->log[i].t, 0));
            maxe = fmax(maxe, fabs(r - x) / x);
        }
        if (s->nlog > 0) {
            vf = s->log[s->nlog - 1].volume;
            rf = r_of_volume(vf);
            re = sqrt(fmax(R0 * R0 - 4 * s->log[s->nlog - 1].t, 0));
            ve = 4.0 / 3.0 * M_PI * re * re * re;
        }
        fprintf(f, "%s,%s,%d,%s,%d,%.9g,%.6g,%.9g,%.12g,%.12g,%.12g,%.6g,%.12g,%.12g,%.6g,%.6g,%.6f,%d,%d\n", o->name,
                si->name, si->is_explicit, mcf_status_name(runs[k].status), runs[k].steps, runs[k].dt,
                runs[k].dt * lam, T, R0, rf, re, fabs(rf - re) / re, vf, ve, fabs(vf - ve) / ve, maxe, runs[k].wall,
                runs[k].solves, runs[k].factorizations);
    }
    if (lab_csv_close(f, path) != 0) {
        f = NULL;
        goto done;
    }
    f = NULL;

    for (int fig = 0; fig < 3; fig++) {
        static const char *const suffix[3] = {"sphere-radius", "sphere-volume", "sphere-error"};
        char title[512], blk[32];
        int pf = 1;
        b.len = 0;
        static const char *const what[3] = {"volume-equivalent radius R = (3V/4π)^{1/3} against sqrt(R_0^2 - 4t)",
                                            "enclosed volume V against 4/3 π (R_0^2 - 4t)^{3/2}",
                                            "relative radius error |R - sqrt(R_0^2 - 4t)| / sqrt(R_0^2 - 4t)"};
        snprintf(title, sizeof title, "%s: %s\n{/*0.85 %d vertices, radius %g; R_0 = %.5f, its volume-equivalent radius}",
                 o->name, what[fig], mcf_mesh_nvertices(start), o->radius, R0);
        lab_gp_axes(&b, title, "time t (same units as the radius squared)",
                fig == 0 ? "volume-equivalent radius R" : fig == 1 ? "enclosed volume V" : "relative radius error",
                0, fig == 2);
        api_buf_printf(&b, "set xrange [0:%.9g]\n", T * 1.02);
        if (fig == 2)
            api_buf_printf(&b, "set xrange [%.9g:%.9g]\n", T / 50, T * 1.02);
        for (int k = 0; k < o->nschemes; k++) {
            const mcf_flow_stats *s = &st[k];
            int stride = s->nlog > SERIES_POINTS ? (s->nlog + SERIES_POINTS - 1) / SERIES_POINTS : 1;
            snprintf(blk, sizeof blk, "r%d", k);
            lab_gp_block_begin(&b, blk);
            if (fig < 2)
                api_buf_printf(&b, "0 %.12g\n", fig == 0 ? R0 : V0);
            for (int i = 0; i < s->nlog; i++) {
                if ((i + 1) % stride != 0 && i != s->nlog - 1)
                    continue;
                double t = s->log[i].t, r = r_of_volume(s->log[i].volume), x = sqrt(fmax(R0 * R0 - 4 * t, 0));
                double y = fig == 0 ? r : fig == 1 ? s->log[i].volume : fabs(r - x) / x;
                api_buf_printf(&b, "%.12g %.12g\n", t, y);
            }
            if (s->nlog == 0)
                api_buf_printf(&b, "NaN NaN\n");
            lab_gp_block_end(&b);
        }
        for (int k = 0; k < o->nschemes; k++) {
            char leg[128];
            const mcf_scheme_info *si = mcf_scheme_get(o->schemes[k]);
            snprintf(blk, sizeof blk, "r%d", k);
            snprintf(leg, sizeof leg, "%s, %d steps%s", si->name, runs[k].steps,
                     runs[k].status == MCF_OK ? "" : " (failed)");
            gp_series(&b, &pf, blk, "1:2", "lines", o->schemes[k], leg);
        }
        if (fig == 0)
            api_buf_printf(&b, ", \\\n    sqrt(%.12g - 4*x) with lines lc rgb \"#000000\" dt 3 lw 2.5 title "
                               "\"exact sqrt(R_0^2 - 4t)\"",
                           R0 * R0);
        else if (fig == 1)
            api_buf_printf(&b, ", \\\n    4.0/3*pi*(%.12g - 4*x)**1.5 with lines lc rgb \"#000000\" dt 3 lw 2.5 "
                               "title \"exact\"",
                           R0 * R0);
        api_buf_printf(&b, "\n");
        if (gp_render(o, suffix[fig], &b) != 0)
            goto done;
    }
    rc = 0;
done:
    if (f)
        fclose(f);
    if (st)
        for (int k = 0; k < o->nschemes; k++)
            mcf_flow_stats_free(&st[k]);
    free(st);
    free(runs);
    api_buf_free(&b);
    mcf_mesh_free(start);
    return rc;
}
