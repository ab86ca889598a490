/* SPDX-License-Identifier: MIT */
/*
 * mcf_schemes.c - the scheme table (what `mcf schemes` and GET /v1/schemes
 * print: name, order, stability, cost) and the checks of a run's
 * parameters (mcf_flow_params_check), before any work.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_flow_ctx.h"

/* ------------------------------------------------------- scheme table */

static const mcf_scheme_info SCHEMES[MCF_NSCHEMES] = {
    [MCF_EULER] = {"euler", "explicit (forward) Euler", 1, 1, 2.0, 0, 0, 0, "",
                   "cheap steps on small meshes; the explicit baseline"},
    [MCF_TAYLOR2] = {"taylor2", "explicit Taylor, operator frozen (article: 2nd-order explicit)", 1, 1, 2.0, 0, 0, 0, "",
                     "reproducing the article; first order on MCF because L and M move"},
    [MCF_DESBRUN] = {"desbrun", "semi-implicit Euler (Desbrun 1999 / Dziuk 1990)", 1, 0, 0.0, 1, 1, 1,
                     "step doubling",
                     "robust first-order smoothing at any step"},
    [MCF_NEUMANN2] = {"neumann2", "truncated Neumann series I + dtA + dt^2A^2 (article eq. ***)", 1, 1, 1.0, 0, 0, 0, "",
                      "reproducing the article's erratum: first order, half Euler's stability"},
    [MCF_DESBRUN2] = {"desbrun2", "linearly implicit BDF2 on the extrapolated operator", 2, 0, 0.0, 1, 1, 1,
                      "Milne device (new step vs quadratic extrapolation)",
                      "default: second order, A/L-stable, one factorization per step"},
    [MCF_ROS2] = {"ros2", "Rosenbrock-W, gamma = 1 + 1/sqrt(2)", 2, 0, 0.0, 2, 1, 1,
                  "embedded first-order solution, filtered by W^-1 M",
                  "second order with a free error estimate; small steps"},
    [MCF_RICHARDSON] = {"richardson", "Richardson extrapolation of desbrun steps", 2, 0, 0.0, 3, 3, 1,
                        "difference of the two desbrun solutions",
                        "second order from a first-order solver; 3 factorizations"},
    [MCF_IMPLICIT] = {"implicit", "fully implicit Euler by Picard iteration", 1, 0, 0.0, 0, 0, 0, "",
                      "reference for the nonlinear backward Euler; costly"},
    [MCF_HUISKEN2] = {"huisken2", "Taylor step from Huisken's evolution equations (corrected)", 1, 1, 2.0, 0, 0, 0, "",
                      "experiments; exact to 2nd order on spheres"},
    [MCF_ARC] = {"arc", "osculating-sphere arc step", 1, 1, 2.0, 0, 0, 0, "",
                 "explicit, exact radius law on spheres, never overshoots"},
    [MCF_CMCF] = {"cmcf", "conformalized MCF (Kazhdan 2012), L from the input", 1, 0, 0.0, 1, 1, 0, "",
                  "large-time smoothing without neck pinches (libigl/pmp/CGAL)"},
    [MCF_LINEAR] = {"linear", "heat flow: L and M frozen, factor once", 1, 0, 0.0, 1, 0, 0, "",
                    "fastest implicit smoothing; not geometric MCF"},
    [MCF_TAUBIN] = {"taubin", "Taubin lambda/mu filter, lambda 0.5, mu -0.53", 0, 1, 0.0, 0, 0, 0, "",
                    "volume-preserving-ish denoising baseline (MeshLab/Open3D)"},
    [MCF_FAIRING] = {"fairing", "implicit bi-Laplacian fairing along the normals, amount by SURE", 0, 0, 0.0, 3, 0, 0, "",
                     "default: denoising scans; one factorization per run"},
    [MCF_FAIRING_EXPLICIT] = {"fairing_explicit", "Taubin passes along the normals, amount by SURE", 0, 1, 0.0, 0, 0, 0, "",
                              "denoising meshes too large to factor; no linear solve"},
    [MCF_FAIRING_FEATURE] = {"fairing_feature", "bilateral normal filtering and vertex update, parameters by SURE", 0, 1, 0.0, 0, 0, 0, "",
                             "denoising CAD parts: flat faces and sharp edges (the default's choice for them)"},
};

int mcf__is_fairing(mcf_scheme s)
{
    return s == MCF_FAIRING || s == MCF_FAIRING_EXPLICIT || s == MCF_FAIRING_FEATURE;
}

const mcf_scheme_info *mcf_scheme_get(mcf_scheme s)
{
    return (int)s >= 0 && s < MCF_NSCHEMES ? &SCHEMES[s] : NULL;
}

mcf_status mcf_scheme_from_name(const char *name, mcf_scheme *out)
{
    for (int s = 0; name && s < MCF_NSCHEMES; s++)
        if (strcmp(name, SCHEMES[s].name) == 0) {
            *out = (mcf_scheme)s;
            return MCF_OK;
        }
    return MCF_EINVAL;
}

/* ------------------------------------------------------------ params */

void mcf_flow_params_init(mcf_flow_params *p)
{
    memset(p, 0, sizeof *p);
    p->scheme = MCF_DESBRUN2;
    p->dt = 0.0;        /* derived from the amount */
    p->iterations = 0;  /* MCF_DEFAULT_STEPS */
    p->strength = MCF_DEFAULT_STRENGTH;
    p->boundary = MCF_BOUNDARY_FIXED;
    p->rescale = MCF_RESCALE_NONE;
    p->normalize = 1;
    p->laplacian = MCF_LAPLACIAN_COTAN;
    p->mass = MCF_MASS_BARYCENTRIC;
    p->tol = 1e-4;
    p->max_steps = 10000;
    p->implicit_tol = 1e-10;
    p->implicit_maxit = 200;
}

mcf_status mcf_flow_params_check(const mcf_flow_params *p, int nv, mcf_error *err)
{
    const mcf_scheme_info *si = mcf_scheme_get(p->scheme);
    if (!si)
        return mcf__fail(err, MCF_EINVAL, "scheme: unknown scheme %d", (int)p->scheme);
    if (p->dt_auto && !si->is_explicit)
        return mcf__fail(err, MCF_EINVAL, "dt: \"auto\" applies to explicit schemes only, not '%s'", si->name);
    if (!p->dt_auto && !(isfinite(p->dt) && p->dt >= 0.0))
        return mcf__fail(err, MCF_EINVAL, "dt: must be a finite number > 0 (or 0: derived), got %g", p->dt);
    if (!isfinite(p->time) || p->time < 0.0)
        return mcf__fail(err, MCF_EINVAL, "time: must be a finite number >= 0, got %g", p->time);
    if (p->iterations < 0)
        return mcf__fail(err, MCF_EINVAL, "iterations: must be >= 1 (or 0: the default), got %d", p->iterations);
    if (!(isfinite(p->strength) && p->strength > 0.0))
        return mcf__fail(err, MCF_EINVAL, "strength: must be a finite number > 0, got %g", p->strength);
    if (p->scheme == MCF_TAUBIN && (p->time > 0.0 || p->adaptive || p->dt_auto))
        return mcf__fail(err, MCF_EINVAL, "taubin is a filter: it takes iterations (passes), not time, dt=auto or adaptive");
    if (mcf__is_fairing(p->scheme) && (p->time > 0.0 || p->adaptive || p->dt_auto || p->dt > 0.0))
        return mcf__fail(err, MCF_EINVAL, "%s is a filter: it takes iterations (steps) or the noise level, not time, dt or adaptive",
                         si->name);
    if (p->scheme == MCF_FAIRING_FEATURE && p->iterations > 0)
        return mcf__fail(err, MCF_EINVAL, "fairing_feature chooses its own iterations (by SURE): it takes the noise level only");
    if (!(isfinite(p->noise_sigma) && p->noise_sigma >= 0.0))
        return mcf__fail(err, MCF_EINVAL, "noise_sigma: must be a finite number >= 0, got %g", p->noise_sigma);
    if (p->adaptive && !si->has_estimate)
        return mcf__fail(err, MCF_EINVAL, "adaptive: scheme '%s' has no error estimate (use desbrun2, ros2, richardson or desbrun)", si->name);
    if (p->adaptive && !(p->tol > 0.0 && p->tol <= 1.0))
        return mcf__fail(err, MCF_EINVAL, "tol: must be in (0, 1], got %g", p->tol);
    if (p->max_steps < 1)
        return mcf__fail(err, MCF_EINVAL, "max_steps: must be >= 1, got %d", p->max_steps);
    if ((unsigned)p->boundary > MCF_BOUNDARY_FREE)
        return mcf__fail(err, MCF_EINVAL, "boundary: must be fixed or free");
    if ((unsigned)p->rescale > MCF_RESCALE_AREA)
        return mcf__fail(err, MCF_EINVAL, "rescale: must be none, volume or area");
    if ((unsigned)p->laplacian > MCF_LAPLACIAN_UNIFORM)
        return mcf__fail(err, MCF_EINVAL, "laplacian: must be cotan or uniform");
    if ((unsigned)p->mass > MCF_MASS_VORONOI)
        return mcf__fail(err, MCF_EINVAL, "mass: must be barycentric or voronoi");
    if (p->scheme == MCF_IMPLICIT && (!(p->implicit_tol > 0.0) || p->implicit_maxit < 1))
        return mcf__fail(err, MCF_EINVAL, "implicit: needs implicit_tol > 0 and implicit_maxit >= 1");
    if (p->nfixed < 0 || (p->nfixed > 0 && !p->fixed))
        return mcf__fail(err, MCF_EINVAL, "fixed_vertices: %d indices but no array", p->nfixed);
    for (int i = 0; i < p->nfixed; i++)
        if (p->fixed[i] < 0 || p->fixed[i] >= nv)
            return mcf__fail(err, MCF_EINVAL, "fixed_vertices: index %d out of range 0..%d", (int)p->fixed[i], nv - 1);
    return MCF_OK;
}
