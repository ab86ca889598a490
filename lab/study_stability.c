/* SPDX-License-Identifier: MIT */
/*
 * study_stability.c - `mcflab stability`: per scheme, the largest dt whose
 * run of a few steps ends acceptably (no failure, NaN or face folded in a
 * step, error under a threshold), found by probing the top of the range,
 * doubling up from the bottom and bisecting; beside the theory's bound,
 * as a CSV and a bar figure.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "study.h"

/* Why a stability run is not acceptable ("" when it is): the flow failed
 * or left NaN, a step folded a face (turned its normal by more than 90
 * degrees: what an unstable step does, and what the flow itself refuses
 * for the explicit schemes), or the error is over the threshold. Faces
 * inverted against the clean target are not a criterion: noise folds a
 * few slivers, and a long smoothing legitimately turns faces at sharp
 * features; they are in the CSV. */
static const char *stab_reason(const xrun *r, double threshold)
{
    if (r->nonfinite)
        return "NaN";
    if (r->status != MCF_OK)
        return mcf_status_name(r->status);
    if (r->folded > 0)
        return "face folded in a step";
    if (!(r->cmp.rms_rel <= threshold))
        return "error over threshold";
    return "";
}

typedef struct {
    mcf_scheme scheme;
    double measured;        /* largest acceptable dt found (0: none) */
    double first_fail;      /* smallest unacceptable dt found (0: none) */
    char reason[64];        /* why first_fail was not acceptable */
    int censored;           /* acceptable up to the top of the range */
    int runs;
} stab_result;

/* One stability run of sr's scheme at dt, written to f with its phase. */
static int stab_run(const xopts *o, const mcf_mesh *noisy, const mcf_mesh *target, double lam, double dt,
                    const char *phase, FILE *f, xrun *r, stab_result *sr)
{
    char why[64];
    if (run_flow(o, noisy, target, sr->scheme, dt, o->iterations, 0, 0, r, NULL, NULL) != 0)
        return 1;
    sr->runs++;
    run_note(o, r);
    lab_csv_clean(stab_reason(r, o->threshold), why, sizeof why);
    run_csv_fields(f, o, r, lam);
    fprintf(f, ",%s,%d,%s\n", phase, why[0] == '\0', why);
    return 0;
}

int study_stability(xopts *o)
{
    mcf_mesh *target = NULL, *noisy = NULL;
    stab_result *res = NULL;
    double lam = 0;
    int rc = 1;
    mcf_compare_result c0;
    api_buf b;
    FILE *f = NULL;
    char path[4096];

    api_buf_init(&b, 16u << 20);
    if (noisy_study_mesh(o, &target, &noisy, &c0, &lam) != 0)
        goto done;
    double lo, hi;
    if (dt_range(o, lam, 0, &lo, &hi) != 0) {
        rc = LAB_EXIT_USAGE;
        goto done;
    }
    note(o, "%s: stability, %d steps, threshold rms_rel %g (noisy input %.4g), lambda_max %.6g, dt %.3g..%.3g\n",
         o->name, o->iterations, o->threshold, c0.rms_rel, lam, lo, hi);
    res = calloc((size_t)o->nschemes, sizeof *res);
    if (!res) {
        lab_fail(1, "out of memory");
        goto done;
    }
    if (!(f = study_csv_open(o, "stability-runs.csv", path, sizeof path)))
        goto done;
    fprintf(f, "%s,phase,acceptable,reason\n", run_csv_header);

    /* Per scheme: the top of the range first (an unconditionally stable
     * scheme needs one run), then doublings up from the bottom until a run
     * is not acceptable, then geometric bisection of that bracket. */
    for (int k = 0; k < o->nschemes; k++) {
        stab_result *sr = &res[k];
        xrun r;
        double good = 0, bad = 0;
        sr->scheme = o->schemes[k];
        if (stab_run(o, noisy, target, lam, hi, "top", f, &r, sr) != 0)
            goto done;
        if (stab_reason(&r, o->threshold)[0] == '\0') {
            sr->measured = hi;
            sr->censored = 1;
            continue;
        }
        bad = hi;
        snprintf(sr->reason, sizeof sr->reason, "%s", stab_reason(&r, o->threshold));
        for (double dt = lo; dt < hi; dt *= 2) {
            if (stab_run(o, noisy, target, lam, dt, "scan", f, &r, sr) != 0)
                goto done;
            if (stab_reason(&r, o->threshold)[0] != '\0') {
                bad = dt;
                snprintf(sr->reason, sizeof sr->reason, "%s", stab_reason(&r, o->threshold));
                break;
            }
            good = dt;
        }
        for (int it = 0; good > 0 && it < o->bisect; it++) {
            double mid = sqrt(good * bad);
            if (stab_run(o, noisy, target, lam, mid, "bisect", f, &r, sr) != 0)
                goto done;
            if (stab_reason(&r, o->threshold)[0] == '\0') {
                good = mid;
            } else {
                bad = mid;
                snprintf(sr->reason, sizeof sr->reason, "%s", stab_reason(&r, o->threshold));
            }
        }
        sr->measured = good;
        sr->first_fail = bad;
    }
    if (lab_csv_close(f, path) != 0) {
        f = NULL;
        goto done;
    }
    f = NULL;

    if (!(f = study_csv_open(o, "stability.csv", path, sizeof path)))
        goto done;
    fprintf(f, "mesh,scheme,explicit,lambda_max,theory,theory_dt_lambda,theory_dt,measured_dt,measured_dt_lambda,"
               "censored,first_failing_dt,first_failing_dt_lambda,failure,threshold,noisy_rms_rel,noisy_inverted_faces,"
               "iterations,runs\n");
    for (int k = 0; k < o->nschemes; k++) {
        const stab_result *sr = &res[k];
        const mcf_scheme_info *si = mcf_scheme_get(sr->scheme);
        char theory[32];
        if (si->stability > 0)
            snprintf(theory, sizeof theory, "%g/lambda_max", si->stability);
        else
            snprintf(theory, sizeof theory, "unconditional");
        fprintf(f, "%s,%s,%d,%.9g,%s,%.9g,%.9g,%.9g,%.6g,%d,%.9g,%.6g,%s,%g,%.9g,%d,%d,%d\n", o->name, si->name,
                si->is_explicit, lam, theory, si->stability > 0 ? si->stability : NAN,
                si->stability > 0 ? si->stability / lam : NAN, sr->measured, sr->measured * lam, sr->censored,
                sr->first_fail > 0 ? sr->first_fail : NAN, sr->first_fail > 0 ? sr->first_fail * lam : NAN,
                sr->censored ? "none" : sr->reason, o->threshold, c0.rms_rel, c0.inverted_faces, o->iterations,
                sr->runs);
    }
    if (lab_csv_close(f, path) != 0) {
        f = NULL;
        goto done;
    }
    f = NULL;

    /* bars: measured dt * lambda_max next to the theory */
    {
        char title[512];
        /* up to the top of the range when a scheme is unconditional (its
         * theory bar reaches it), else just above the tallest bar */
        double ylo = lo * lam / 2, top = 0;
        int uncond = 0;
        for (int k = 0; k < o->nschemes; k++) {
            double th = mcf_scheme_get(res[k].scheme)->stability;
            uncond |= !(th > 0);
            top = fmax(top, fmax(res[k].measured * lam, th > 0 ? th : 0));
        }
        double yhi = uncond ? hi * lam * 4 : top * 8;
        snprintf(title, sizeof title,
                 "%s: largest acceptable dt in %d steps, and what failed above it\n{/*0.85 %d vertices, noise %g × mean "
                 "edge; acceptable: no failure, NaN or face folded in a step, RMS error ≤ %g; small print: "
                 "what failed next}",
                 o->name, o->iterations, mcf_mesh_nvertices(target), o->rho, o->threshold);
        lab_gp_axes(&b, title, "", "dt × λ_{max}  (dimensionless)", 0, 1);
        api_buf_printf(&b, "set xrange [-0.7:%d.7]\nset yrange [%.9g:%.9g]\nset xtics rotate by -30 (", o->nschemes - 1,
                       ylo, yhi);
        for (int k = 0; k < o->nschemes; k++)
            api_buf_printf(&b, "%s\"%s\" %d", k ? ", " : "", mcf_scheme_get(o->schemes[k])->name, k);
        api_buf_printf(&b, ")\nset grid noxtics nomxtics\nset key outside below center horizontal\n"
                           "set style fill solid 0.85 border rgb \"#333333\"\n"
                           "set style textbox opaque noborder margins 1,1\n");
        lab_gp_block_begin(&b, "bars");
        for (int k = 0; k < o->nschemes; k++) {
            const mcf_scheme_info *si = mcf_scheme_get(res[k].scheme);
            double m = res[k].measured * lam;
            double th = si->stability > 0 ? si->stability : yhi;
            /* short: a label must fit over its bar */
            const char *why = res[k].censored ? "none" : res[k].reason;
            if (!strcmp(why, "ENUMERIC"))
                why = "fold (flow)";
            else if (!strcmp(why, "ENOCONV"))
                why = "no conv.";
            else if (!strcmp(why, "face folded in a step"))
                why = "fold";
            else if (!strcmp(why, "error over threshold"))
                why = "error";
            api_buf_printf(&b, "%d %.9g %.9g \"%s%.3g\" %d \"%s\"\n", k, m > 0 ? m : ylo, th,
                           res[k].censored ? "≥" : "", m, si->stability > 0, m > 0 ? why : "none ok");
        }
        lab_gp_block_end(&b);
        api_buf_printf(&b,
                       "plot $bars using 1:2:($1-0.38):($1):(%.9g):2 with boxxyerror lc rgb \"#3b75af\" "
                       "title \"measured\", \\\n"
                       "    $bars using ($1+0.19):($5 > 0 ? $3 : NaN):($1):($1+0.38):(%.9g):3 with boxxyerror "
                       "fs solid 0.5 lc rgb \"#999999\" title \"theory (explicit bound)\"",
                       ylo, ylo);
        if (uncond)
            api_buf_printf(&b, ", \\\n    $bars using ($1+0.19):($5 > 0 ? NaN : $3):($1):($1+0.38):(%.9g):3 with "
                               "boxxyerror fs pattern 4 lc rgb \"#999999\" title \"theory: unconditional\"",
                           ylo);
        /* the labels last, over the bars; on a white box so the hatching
         * does not cross them */
        api_buf_printf(&b, ", \\\n    $bars using ($1-0.19):2:4 with labels offset 0,0.8 font \",11\" boxed notitle"
                           ", \\\n    $bars using ($1-0.19):2:6 with labels offset 0,2.1 font \",9\" tc rgb \"#444444\" "
                           "boxed notitle\n");
        if (gp_render(o, "stability", &b) != 0)
            goto done;
    }
    rc = 0;
done:
    if (f)
        fclose(f);
    api_buf_free(&b);
    free(res);
    mcf_mesh_free(target);
    mcf_mesh_free(noisy);
    return rc;
}
