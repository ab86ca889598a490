/* SPDX-License-Identifier: MIT */
/*
 * mcf_metrics.c - distances between two embeddings of one connectivity:
 * the error of a smoothed mesh against a clean target (docs/MATH.md,
 * "Error against a clean target").
 *
 * The mass-weighted RMS uses the target's barycentric lumped mass
 * (m_i = 1/3 of the area of the faces at i), so it approximates the L2
 * distance between the two surfaces and does not depend on how densely
 * the mesh is sampled; Frobenius is the article's unweighted figure. One
 * pass over vertices and one over faces, O(nv) scratch.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mcf_internal.h"

static const double rad2deg = 57.295779513082320877;

mcf_status mcf_compare(const mcf_mesh *x, const mcf_mesh *target,
                       mcf_compare_result *out, mcf_error *err)
{
    mcf_compare_result r;
    double *mass, msum = 0, wsum = 0, fsum = 0, area = 0, asum = 0;
    size_t i, f, nv, nf;
    int nangle = 0;

    if (!x || !target || !out)
        return mcf__fail(err, MCF_EINVAL, "mcf_compare: NULL argument");
    if (x->nv != target->nv || x->nf != target->nf)
        return mcf__fail(err, MCF_EINVAL,
                         "mcf_compare: %d vertices/%d faces vs %d/%d",
                         x->nv, x->nf, target->nv, target->nf);
    nv = (size_t)x->nv;
    nf = (size_t)x->nf;
    for (i = 0; i < 3 * nf; i++)
        if (x->F[i] != target->F[i])
            return mcf__fail(err, MCF_EINVAL,
                             "mcf_compare: face %zu differs (connectivity "
                             "must be the same)", i / 3);
    mass = mcf__calloc(nv, sizeof *mass);
    if (!mass)
        return mcf__fail(err, MCF_ENOMEM, "compare mass of %zu vertices", nv);
    memset(&r, 0, sizeof r);

    /* Faces: target mass and area, normal angles and inversions. A face
     * whose normal is undefined (zero area) in either mesh has no angle. */
    for (f = 0; f < nf; f++) {
        const int32_t *t = x->F + 3 * f;
        double a1[3], a2[3], na[3], b1[3], b2[3], nb[3], la, lb, c;
        int k;
        mcf__sub3(x->X + 3 * (size_t)t[1], x->X + 3 * (size_t)t[0], a1);
        mcf__sub3(x->X + 3 * (size_t)t[2], x->X + 3 * (size_t)t[0], a2);
        mcf__cross3(a1, a2, na);
        mcf__sub3(target->X + 3 * (size_t)t[1], target->X + 3 * (size_t)t[0], b1);
        mcf__sub3(target->X + 3 * (size_t)t[2], target->X + 3 * (size_t)t[0], b2);
        mcf__cross3(b1, b2, nb);
        la = sqrt(mcf__dot3(na, na));
        lb = sqrt(mcf__dot3(nb, nb));
        area += 0.5 * lb;
        for (k = 0; k < 3; k++)
            mass[t[k]] += lb / 6.0;
        /* atan2(|na x nb|, na . nb) is accurate near 0 and 180 degrees,
         * where acos of the cosine loses half the digits. */
        if (la > 0 && lb > 0) {
            double cr[3];
            c = mcf__dot3(na, nb);
            if (c < 0)
                r.inverted_faces++;
            mcf__cross3(na, nb, cr);
            asum += atan2(sqrt(mcf__dot3(cr, cr)), c);
            nangle++;
        }
    }
    for (i = 0; i < nv; i++) {
        double d[3], d2;
        mcf__sub3(x->X + 3 * i, target->X + 3 * i, d);
        d2 = mcf__dot3(d, d);
        fsum += d2;
        wsum += mass[i] * d2;
        msum += mass[i];
        if (sqrt(d2) > r.max_err)
            r.max_err = sqrt(d2);
    }
    free(mass);
    r.frobenius = sqrt(fsum);
    r.rms_m = msum > 0 ? sqrt(wsum / msum) : 0;
    r.rms_rel = area > 0 ? r.rms_m / sqrt(area) : 0;
    r.normal_angle_deg = nangle > 0 ? rad2deg * asum / nangle : 0;
    *out = r;
    return MCF_OK;
}
