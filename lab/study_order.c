/* SPDX-License-Identifier: MIT */
/*
 * study_order.c - `mcflab order`: the temporal order of each scheme by the
 * protocol of docs/MATH.md: the error at a fixed final time against a fine
 * reference run, per step count, the fitted slope, the local and the
 * reference-free orders, and the error-against-dt figure with slope guides.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "study.h"

/* Whether scheme s integrates MCF itself. cmcf (L from the input) and
 * linear (L and M from the input) integrate other flows: their error is
 * measured against their own fine run. */
static int same_flow(mcf_scheme s)
{
    return s != MCF_CMCF && s != MCF_LINEAR;
}

int study_order(xopts *o)
{
    mcf_mesh *start = NULL, *ref = NULL, **sol = NULL;
    mcf_mesh *own_ref = NULL; /* cmcf, linear: their own fine run */
    mcf_error err = {MCF_OK, ""};
    xrun *runs = NULL;
    double *e = NULL, lam = 0;
    int rc = 1, n = o->nsteps, nmax = o->steps[o->nsteps - 1];
    api_buf b;
    FILE *f = NULL;
    char path[4096];
    double *slope = NULL;

    api_buf_init(&b, 16u << 20);
    if (study_mesh(o, &start) != 0)
        goto done;
    if (o->presmooth > 0) {
        /* smooth data: the highest modes of a scan would reduce the order */
        xrun pr;
        mcf_mesh *sm = NULL;
        if (run_flow(o, start, NULL, MCF_DESBRUN2, o->presmooth / 10, 10, 0, 0, &pr, &sm, NULL) != 0)
            goto done;
        if (!run_ok(&pr)) {
            mcf_mesh_free(sm);
            lab_fail(1, "pre-smoothing failed: %s", pr.msg);
            goto done;
        }
        mcf_mesh_free(start);
        start = sm;
    }
    if (mcf_lambda_max(start, MCF_LAPLACIAN_COTAN, MCF_MASS_BARYCENTRIC, &lam, &err) != MCF_OK) {
        lab_fail(1, "%s", err.msg);
        goto done;
    }
    int nref = o->ref_factor * nmax;
    note(o, "%s: order at T = %g, %d..%d steps, reference %s at %d steps, lambda_max %.6g (T lambda %.3g)\n",
         o->name, o->time, o->steps[0], nmax, mcf_scheme_get(o->ref_scheme)->name, nref, lam, o->time * lam);
    {
        xrun rr;
        if (run_flow(o, start, NULL, o->ref_scheme, o->time / nref, nref, 0, 0, &rr, &ref, NULL) != 0)
            goto done;
        note(o, "reference: %s, %.2f s\n", mcf_status_name(rr.status), rr.wall);
        if (!run_ok(&rr)) {
            lab_fail(1, "the reference run failed: %s", rr.msg);
            goto done;
        }
    }
    runs = calloc((size_t)o->nschemes * n, sizeof *runs);
    e = calloc((size_t)o->nschemes * n, sizeof *e);
    sol = calloc((size_t)n, sizeof *sol);
    slope = calloc((size_t)o->nschemes, sizeof *slope);
    if (!runs || !e || !sol || !slope) {
        lab_fail(1, "out of memory");
        goto done;
    }
    if (!(f = study_csv_open(o, "order.csv", path, sizeof path)))
        goto done;
    fprintf(f, "mesh,scheme,explicit,T,steps,dt,dt_lambda,status,error,local_order,reference_free_order,wall_s,"
               "solves,factorizations,message\n");
    for (int k = 0; k < o->nschemes; k++) {
        mcf_scheme s = o->schemes[k];
        xrun *rs = runs + (size_t)k * n;
        double *ek = e + (size_t)k * n, dtv[MAX_LIST];
        const mcf_mesh *rk = ref;
        if (!same_flow(s)) {
            /* a different flow: its limit is its own, not MCF's */
            xrun rr;
            mcf_mesh_free(own_ref);
            own_ref = NULL;
            if (run_flow(o, start, NULL, s, o->time / nref, nref, 0, 0, &rr, &own_ref, NULL) != 0)
                goto done;
            if (!run_ok(&rr)) {
                lab_fail(1, "the reference run of %s failed: %s", mcf_scheme_get(s)->name, rr.msg);
                goto done;
            }
            rk = own_ref;
        }
        for (int i = 0; i < n; i++) {
            mcf_compare_result c;
            if (run_flow(o, start, NULL, s, o->time / o->steps[i], o->steps[i], 0, 0, &rs[i], &sol[i], NULL) != 0)
                goto done;
            ek[i] = NAN;
            if (run_ok(&rs[i])) {
                if (mcf_compare(sol[i], rk, &c, &err) != MCF_OK) {
                    lab_fail(1, "compare: %s", err.msg);
                    goto done;
                }
                ek[i] = c.rms_rel;
            }
            dtv[i] = o->time / o->steps[i];
            note(o, "%s %-10s steps %-6d error %-11.4g %s %.2f s\n", o->name, mcf_scheme_get(s)->name, o->steps[i],
                 ek[i], mcf_status_name(rs[i].status), rs[i].wall);
        }
        int used;
        slope[k] = fit_loglog(dtv, ek, n, &used);
        for (int i = 0; i < n; i++) {
            char msg[MCF_ERRMSG_SIZE];
            double local = NAN, free_p = NAN;
            if (i > 0 && isfinite(ek[i]) && isfinite(ek[i - 1]) && ek[i] > 0)
                local = log(ek[i - 1] / ek[i]) / log(dtv[i - 1] / dtv[i]);
            /* reference-free: log2 |X_dt - X_dt/2| / |X_dt/2 - X_dt/4| */
            if (i >= 2 && o->steps[i] == 2 * o->steps[i - 1] && o->steps[i - 1] == 2 * o->steps[i - 2] &&
                run_ok(&rs[i]) && run_ok(&rs[i - 1]) && run_ok(&rs[i - 2])) {
                mcf_compare_result c1, c2;
                if (mcf_compare(sol[i - 2], sol[i - 1], &c1, NULL) == MCF_OK &&
                    mcf_compare(sol[i - 1], sol[i], &c2, NULL) == MCF_OK && c2.rms_rel > 0)
                    free_p = log2(c1.rms_rel / c2.rms_rel);
            }
            lab_csv_clean(rs[i].msg, msg, sizeof msg);
            fprintf(f, "%s,%s,%d,%.9g,%d,%.9g,%.6g,%s,%.9g,%.4f,%.4f,%.6f,%d,%d,%s\n", o->name,
                    mcf_scheme_get(s)->name, mcf_scheme_get(s)->is_explicit, o->time, o->steps[i], dtv[i],
                    dtv[i] * lam, mcf_status_name(rs[i].status), ek[i], local, free_p, rs[i].wall, rs[i].solves,
                    rs[i].factorizations, msg);
        }
        for (int i = 0; i < n; i++) {
            mcf_mesh_free(sol[i]);
            sol[i] = NULL;
        }
        note(o, "%s %-10s fitted slope %.3f over %d points\n", o->name, mcf_scheme_get(s)->name, slope[k], used);
    }
    if (lab_csv_close(f, path) != 0) {
        f = NULL;
        goto done;
    }
    f = NULL;
    if (!(f = study_csv_open(o, "order-summary.csv", path, sizeof path)))
        goto done;
    fprintf(f, "mesh,scheme,explicit,expected_order,T,presmooth,lambda_max,steps_min,steps_max,reference,"
               "reference_steps,fitted_slope,points,last_local_order\n");
    for (int k = 0; k < o->nschemes; k++) {
        const mcf_scheme_info *si = mcf_scheme_get(o->schemes[k]);
        const double *ek = e + (size_t)k * n;
        int pts = 0;
        for (int i = 0; i < n; i++)
            pts += isfinite(ek[i]) && ek[i] > 0;
        double last = n >= 2 && isfinite(ek[n - 1]) && isfinite(ek[n - 2]) && ek[n - 1] > 0
                          ? log(ek[n - 2] / ek[n - 1]) / log((double)o->steps[n - 1] / o->steps[n - 2])
                          : NAN;
        fprintf(f, "%s,%s,%d,%d,%.9g,%.9g,%.9g,%d,%d,%s,%d,%.4f,%d,%.4f\n", o->name, si->name, si->is_explicit,
                si->order, o->time, o->presmooth, lam, o->steps[0], nmax,
                same_flow(o->schemes[k]) ? mcf_scheme_get(o->ref_scheme)->name : si->name, nref,
                slope[k], pts, last);
    }
    if (lab_csv_close(f, path) != 0) {
        f = NULL;
        goto done;
    }
    f = NULL;

    {
        char title[512], blk[32], leg[160];
        int pf = 1;
        char pre[64] = "";
        if (o->presmooth > 0)
            snprintf(pre, sizeof pre, ", pre-smoothed to t = %g", o->presmooth);
        snprintf(title, sizeof title,
                 "%s: error at a fixed time T = %g against a fine reference\n{/*0.85 %d vertices%s; reference: %s with "
                 "%d steps (cmcf, linear: their own); T × λ_{max} = %.3g}",
                 o->name, o->time, mcf_mesh_nvertices(start), pre, mcf_scheme_get(o->ref_scheme)->name, nref,
                 o->time * lam);
        lab_gp_axes(&b, title, "time step dt = T / steps", "error: M-weighted RMS / sqrt(area)", 1, 1);
        double d0 = o->time / nmax, d1 = o->time / o->steps[0];
        api_buf_printf(&b, "set xrange [%.9g:%.9g]\nset xtics (", d0 / 1.5, d1 * 1.5);
        for (int i = 0; i < n; i++) {
            char num[32], *ex;
            snprintf(num, sizeof num, "%.2e", o->time / o->steps[i]);
            ex = strchr(num, 'e');
            *ex = '\0';
            api_buf_printf(&b, "%s\"%s·10^{%d}\\n%d steps\" %.9g", i ? ", " : "", num, atoi(ex + 1), o->steps[i],
                           o->time / o->steps[i]);
        }
        api_buf_printf(&b, ")\nset bmargin 6\nset xlabel offset 0,-1.2\n");
        for (int k = 0; k < o->nschemes; k++) {
            snprintf(blk, sizeof blk, "o%d", k);
            lab_gp_block_begin(&b, blk);
            int any = 0;
            for (int i = 0; i < n; i++)
                if (isfinite(e[(size_t)k * n + i]) && e[(size_t)k * n + i] > 0) {
                    api_buf_printf(&b, "%.9g %.9g\n", o->time / o->steps[i], e[(size_t)k * n + i]);
                    any = 1;
                }
            if (!any)
                api_buf_printf(&b, "NaN NaN\n");
            lab_gp_block_end(&b);
        }
        for (int k = 0; k < o->nschemes; k++) {
            const char *nm = mcf_scheme_get(o->schemes[k])->name;
            snprintf(blk, sizeof blk, "o%d", k);
            if (isfinite(slope[k]))
                snprintf(leg, sizeof leg, "%s (slope %.2f)", nm, slope[k]);
            else
                snprintf(leg, sizeof leg, "%s: unstable at every dt", nm);
            gp_series(&b, &pf, blk, "1:2", "linespoints", o->schemes[k], leg);
        }
        /* guides through the smallest plotted error at the finest dt */
        double emin = INFINITY;
        for (int k = 0; k < o->nschemes * n; k++)
            if (isfinite(e[k]) && e[k] > 0 && e[k] < emin)
                emin = e[k];
        if (isfinite(emin)) {
            api_buf_printf(&b, ", \\\n    (x >= %.9g && x <= %.9g ? %.9g*(x/%.9g) : NaN) with lines lc rgb \"#444444\" "
                               "dt 3 lw 1.5 title \"slope 1\"",
                           d0, d1, emin / 3, d0);
            api_buf_printf(&b, ", \\\n    (x >= %.9g && x <= %.9g ? %.9g*(x/%.9g)**2 : NaN) with lines lc rgb \"#444444\" "
                               "dt 4 lw 1.5 title \"slope 2\"",
                           d0, d1, emin / 3, d0);
        }
        api_buf_printf(&b, "\n");
        if (gp_render(o, "order", &b) != 0)
            goto done;
    }
    rc = 0;
done:
    if (f)
        fclose(f);
    if (sol)
        for (int i = 0; i < n; i++)
            mcf_mesh_free(sol[i]);
    free(sol);
    free(runs);
    free(e);
    free(slope);
    api_buf_free(&b);
    mcf_mesh_free(start);
    mcf_mesh_free(ref);
    mcf_mesh_free(own_ref);
    return rc;
}
