#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""aniso_study.py - issue 31, organic normal noise: the ORACLE of an anisotropic filter steered
by a pilot's curvature. A lab study, not the product.

Pilot P: the default request's output (build/mcf smooth). Per edge ij the pilot's normal
curvature along it, kap_ij = (nP_j - nP_i) . (P_j - P_i) / |P_j - P_i|^2; steering weight
exp(-(kap_ij / (c m))^2), m the median |kap| over the edges, c in {0.5, 1, 2, 4, inf} (inf: no
steering): edges across a ridge (large normal curvature along them) carry less smoothing, edges
along it the full weight. Base weights: uniform or the pilot's cotan (negative ones clamped).
The filter: lambda|mu passes (0.5, -0.53) of X with those weights held fixed (linear in X),
k = 1..128; the output moves X along the normals of the result (the product's rule) or takes the
result as it is; the error (area-weighted RMS against the clean mesh) over the input's, the best
over k and the two outputs for each (base, c): an oracle (the clean mesh picks k), to compare
with c = inf (the same family unsteered) and with make quality's Taubin oracle (the *_t
fields: over issue31-before's taubin_best / input, the bar's definition).
Usage: aniso_study.py MESH[,MESH..] RHO[,RHO..] MCF"""
import json, os, subprocess, sys
import numpy as np
import scipy.sparse as sp
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import surelet_study as S
from local_study import taubin_anchor

def case(name, rho, mcf, anchor):
    C, F, n, Nc, Acl, X, e_in, s = S.noisy_case(name, rho)
    S.write_obj('/tmp/h3_aniso_in.obj', X, F)
    subprocess.run([mcf, 'smooth', '--quiet', '/tmp/h3_aniso_in.obj', '/tmp/h3_aniso_out.obj'], check=True)
    P = S.read_obj('/tmp/h3_aniso_out.obj')[0]
    res = {'default': S.err(P, C, Acl) / e_in}
    nP, E = S.vnormals(P, F), S.edges(F)
    d = P[E[:, 1]] - P[E[:, 0]]
    kap = np.sum((nP[E[:, 1]] - nP[E[:, 0]]) * d, 1) / np.sum(d * d, 1)
    m = np.median(np.abs(kap))
    bases = {'u': S.adjacency(F, n), 'cot': S.cotan(P, F, n)}
    ks = list(range(1, 129))
    for bn, W0 in bases.items():
        W0 = W0.tocoo()
        i, j = W0.row, W0.col
        # each directed entry's edge curvature: look it up by the sorted pair
        key = np.minimum(i, j) * n + np.maximum(i, j)
        ek = E[:, 0] * n + E[:, 1]
        order = np.argsort(ek)
        kk = kap[order][np.searchsorted(ek[order], key)]
        for c in (0.5, 1.0, 2.0, 4.0, np.inf):
            st = np.exp(-(kk / (c * m)) ** 2) if np.isfinite(c) else np.ones_like(kk)
            W = sp.coo_matrix((W0.data * st, (i, j)), shape=(n, n)).tocsr()
            W = W + sp.identity(n) * 1e-12
            its = S.pass_iterates(X, W, ks, np.zeros((n, 0)))
            best = np.inf
            for k in ks:
                Y = its[k][0]
                D = Y - X
                ny = S.vnormals(Y, F)
                best = min(best, S.err(Y, C, Acl), S.err(X + ny * np.sum(ny * D, 1)[:, None], C, Acl))
            res['%s_c%s' % (bn, c)] = best / e_in
    t = anchor.get((name, rho))
    row = {'mesh': name, 'rho': rho}
    row.update({k: round(v, 4) for k, v in res.items()})
    if t:
        row.update({k + '_t': round(v / t, 4) for k, v in res.items()})
    print(json.dumps(row), flush=True)

if __name__ == '__main__':
    anc = taubin_anchor()
    for m in sys.argv[1].split(','):
        for r in sys.argv[2].split(','):
            case(m, float(r), sys.argv[3], anc)
