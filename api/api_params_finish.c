/* SPDX-License-Identifier: MIT */
/*
 * api_params_finish.c - the job parameters' rules once the mesh is known:
 * the default scheme, the automatic amount, the step count, time/dt/
 * iterations agreeing, and the work bound (steps x vertices).
 */
#include <math.h>

#include "api_params_internal.h"

mcf_scheme api_default_scheme(long long nv)
{
    return nv > API_FAIRING_IMPLICIT_MAX ? MCF_FAIRING_EXPLICIT : MCF_FAIRING;
}

mcf_scheme api_params_scheme(const api_params *p, long long nv)
{
    if (!p)
        return api_default_scheme(nv);
    if (p->scheme_set || p->scheme_chosen)
        return p->flow.scheme;
    /* a request that sets a flow's parameters (time, dt, adaptive,
     * laplacian, mass, rescale) and no scheme is a flow request, as
     * before the fairing filter became the default: desbrun2 */
    return p->flow_keys_set ? MCF_DESBRUN2 : api_default_scheme(nv);
}

int api__is_fairing(mcf_scheme s)
{
    return s == MCF_FAIRING || s == MCF_FAIRING_EXPLICIT || s == MCF_FAIRING_FEATURE;
}

int api_params_auto_amount(const api_params *p)
{
    return p->flow.strength_auto ||
           !(p->time_set || p->iterations_set || p->dt_set || p->strength_set);
}

double api_params_steps(const api_params *p, const api_limits *lim,
                        int *by_mesh)
{
    const mcf_flow_params *f = &p->flow;
    /* unnamed and not chosen yet (before the mesh): desbrun2 for a flow
     * request, else a fairing filter, which the mesh's size picks */
    mcf_scheme s = api_params_scheme(p, 0);
    int known = p->scheme_set || p->scheme_chosen || p->flow_keys_set,
        mesh = 0;
    /* Taubin's automatic pass count (api_params_auto_amount) */
    int auto_passes = s == MCF_TAUBIN && f->iterations <= 0 &&
                      api_params_auto_amount(p);
    double n;

    if (api__is_fairing(s) && f->iterations <= 0) {
        /* the fairing filters' automatic amount stops at its cap (the
         * larger one while the filter is not known), or at max_steps
         * (which the work limit may lower) */
        double cap = known && s == MCF_FAIRING ? MCF_FAIRING_MAX_STEPS
                                               : MCF_FAIRING_MAX_PASSES;
        mesh = 1;
        n = f->max_steps > 0 && f->max_steps < cap ? f->max_steps : cap;
    } else if (!auto_passes && (s == MCF_TAUBIN || api__is_fairing(s) ||
                                (!f->adaptive && !f->dt_auto && !(f->dt > 0.0))))
        n = f->iterations > 0 ? f->iterations : MCF_DEFAULT_STEPS;
    else if (!auto_passes && !f->adaptive && !f->dt_auto && f->time > 0.0)
        n = ceil(f->time / f->dt - 1e-9);
    else if (!auto_passes && !f->adaptive && f->iterations > 0 && f->time <= 0.0)
        n = f->iterations;
    else {
        mesh = 1;
        n = f->max_steps > 0 && f->max_steps < lim->max_iterations
                ? f->max_steps : lim->max_iterations;
    }
    if (by_mesh)
        *by_mesh = mesh;
    return n;
}

/* time, dt and iterations say the same thing twice (mcf.h: "The amount
 * of smoothing"): with time and dt given, the steps are ceil(time / dt)
 * and iterations would be dropped without a word, and a dt over the time
 * would be cut to it. Refused, naming both, unless they agree. */
static mcf_status amounts_agree(const api_params *p, mcf_error *err)
{
    const mcf_flow_params *f = &p->flow;
    double steps;

    if (!p->time_set || !(f->time > 0.0))
        return MCF_OK;
    if (f->dt_auto && p->iterations_set)
        return api__fail(err, MCF_EINVAL,
                         "parameters 'time' and 'iterations' contradict 'dt' = auto, which "
                         "sets the steps itself: give dt=auto with time, or time with "
                         "iterations");
    if (!(f->dt > 0.0))
        return MCF_OK;
    if (f->dt > f->time * (1.0 + 1e-12))
        return api__fail(err, MCF_EINVAL,
                         "parameter 'dt' (%g) is larger than 'time' (%g): the run would be "
                         "one step of the time; give a dt at most the time, or drop one",
                         f->dt, f->time);
    /* the core's own count (api_params_steps, the work bound's too) */
    steps = ceil(f->time / f->dt - 1e-9);
    if (p->iterations_set && steps != (double)f->iterations)
        return api__fail(err, MCF_EINVAL,
                         "parameters 'time' (%g) and 'dt' (%g) make %.0f steps, but "
                         "'iterations' says %d: give two of the three",
                         f->time, f->dt, steps, f->iterations);
    return MCF_OK;
}

mcf_status api_params_finish(api_params *p, int nv, const api_limits *lim,
                             mcf_error *err)
{
    api_limits def;
    double steps;
    mcf_status rc;
    int i, by_mesh;

    if (!lim) {
        api_limits_default(&def);
        lim = &def;
    }
    if (p->tol_set && !p->flow.adaptive)
        return api__fail(err, MCF_EINVAL,
                         "parameter 'tol' applies to adaptive runs only: add adaptive=true or drop tol");
    if (!p->scheme_set) {
        p->scheme_chosen = 0;
        p->flow.scheme = api_params_scheme(p, nv);
        p->scheme_chosen = 1;
        /* the default's implicit filter chooses, by SURE, between its
         * steps and the explicit passes (on a coarse mesh the passes keep
         * the low modes better: docs/fairing.md); a named `fairing` is
         * the implicit filter alone */
        p->flow.fairing_pick = p->flow.scheme == MCF_FAIRING;
        /* and repairs the spikes first (docs/fairing.md, "Spikes") */
        p->flow.fairing_robust = api__is_fairing(p->flow.scheme);
    }
    /* the fairing filters' strength: the noise level (mean edges) whose
     * removal their amount optimizes; unset or auto: estimated */
    if (api__is_fairing(p->flow.scheme))
        p->flow.noise_sigma = p->strength_set && !p->flow.strength_auto ? p->flow.strength : 0.0;
    for (i = 0; i < p->flow.nfixed; i++)
        if (p->flow.fixed[i] < 0 || p->flow.fixed[i] >= nv)
            return api__fail(err, MCF_EINVAL,
                             "parameter 'fixed_vertices': index %ld out of range (0..%d)",
                             (long)p->flow.fixed[i], nv - 1);
    /* the MCF schemes' and Taubin's automatic amount (the fairing filters
     * choose their own: noise_sigma above) */
    if (!api__is_fairing(p->flow.scheme))
        p->flow.strength_auto = api_params_auto_amount(p);
    if ((rc = mcf_flow_params_check(&p->flow, nv, err)) != MCF_OK)
        return rc;
    if ((rc = amounts_agree(p, err)) != MCF_OK)
        return rc;
    if (nv < 1)
        return api__fail(err, MCF_EINVAL, "mesh has no vertices");

    /* Work bound: steps x vertices. When the parameters alone give the
     * step count, it is checked here; when it depends on the mesh (its
     * edge lengths, lambda_max, a fairing filter's estimated noise, or
     * Taubin's automatic pass count), the core's hard cap max_steps is
     * lowered to what the limits allow instead. */
    steps = api_params_steps(p, lim, &by_mesh);
    if (!by_mesh && steps > lim->max_iterations) {
        /* iterations are bounded when parsed: time / dt */
        return api__fail(err, MCF_EINVAL,
                         "parameters 'time'/'dt' = %.3g steps exceeds max_iterations (%d)",
                         steps, lim->max_iterations);
    } else if (by_mesh && api__is_fairing(p->flow.scheme)) {
        /* the automatic amount stops at its cap, max_steps or the work
         * limit, whichever comes first */
        double cap = p->flow.scheme == MCF_FAIRING ? MCF_FAIRING_MAX_STEPS : MCF_FAIRING_MAX_PASSES;
        double room = floor(lim->max_work / nv);
        if (room < cap && room < p->flow.max_steps)
            p->flow.max_steps = room < 1 ? 1 : (int)room;
        steps = fmin(cap, p->flow.max_steps);
    } else if (by_mesh) {
        double cap = floor(lim->max_work / nv);
        if (cap < p->flow.max_steps)
            p->flow.max_steps = cap < 1 ? 1 : (int)cap;
        if (p->flow.max_steps > lim->max_iterations)
            p->flow.max_steps = lim->max_iterations;
        steps = p->flow.max_steps;
    }
    if (steps * (double)nv > lim->max_work)
        return api__fail(err, MCF_ELIMIT,
                         "work of %.0f steps x %d vertices = %.3g exceeds max_work (%.3g)",
                         steps, nv, steps * (double)nv, lim->max_work);
    return MCF_OK;
}
