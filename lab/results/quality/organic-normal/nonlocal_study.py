#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""nonlocal_study.py - issue 31, organic normal noise: a NON-LOCAL correction of the default's
output, its oracle and its blind version. A lab study, not the product.

Noise as surelet_study.py (sigma = s = rho h along the clean vertex normals, numpy seed 1).
P: the product's default output (mcf smooth), n_p its vertex normals. What P still misses
along n_p is t = n_p.(C - P) (clean); the noisy mesh shows d = n_p.(X - P) = t + noise.
Idea: vertices whose pilot looks alike (shape descriptors of P: its heights over its own
smoothed copies at several scales, q_k = n_p.(P - T_k P) / s, T_k the implicit step on the
uniform graph, k in 1, 2, 4, 8, 16; and the local roughness of d over the 1-ring) miss alike, so
t_i is estimated by averaging d over the K vertices nearest in descriptor space (i excluded,
and its 1-ring: their d shares i's noise through P only weakly; Nadaraya-Watson, uniform
weights). Printed (error over the input's, clean vertex areas):
  default           P;
  nl_oracle_K       P + n_p * mean of t over the K neighbours (the clean t: how much of
                    what P misses its descriptors predict, the ceiling of this family);
  nl_blind_K        the same with d (the noisy mesh alone);
  nl_blind_K_a      P + n_p * a * mean d, a in [0, 1] least in SURE-free form: a = the share
                    of the neighbour mean's variance above its noise variance s^2/K (James-Stein
                    style, per mesh), blind.
Usage: nonlocal_study.py MESH[,..] RHO[,..] MCF"""
import json, os, subprocess, sys
import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree
os.makedirs('/tmp/s31o', exist_ok=True)  # the scripts' scratch files
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import surelet_study as S

KS = [8, 32, 128]

def case(name, rho, mcf):
    C, F, n, Nc, Acl, X, e_in, s = S.noisy_case(name, rho)
    tag = '/tmp/s31o/nloc-%s-%g' % (name.split('.')[0], rho)
    S.write_obj(tag + '_in.obj', X, F)
    subprocess.run([mcf, 'smooth', '--quiet', tag + '_in.obj', tag + '_out.obj'], check=True)
    P = S.read_obj(tag + '_out.obj')[0]
    npv = S.vnormals(P, F)
    t, d = np.sum(npv * (C - P), 1), np.sum(npv * (X - P), 1)
    res = {'mesh': name, 'rho': rho, 'n': n, 'default': S.err(P, C, Acl) / e_in}
    A = S.adjacency(F, n)
    its = S.implicit_iterates(P, A, [1, 2, 4, 8, 16], np.zeros((n, 0)))
    q = [np.sum(npv * (P - its[k][0]), 1) / s for k in (1, 2, 4, 8, 16)]
    deg = np.asarray(A.sum(1)).ravel()
    rough = np.sqrt((A @ d ** 2 + d ** 2) / (deg + 1)) / s
    Q = np.array(q + [rough]).T
    Q = (Q - Q.mean(0)) / Q.std(0)
    tree = cKDTree(Q)
    ring = A + sp.identity(n, format='csr')
    _, nb = tree.query(Q, k=max(KS) + 40)
    # drop i and its 1-ring from its own neighbour list
    excl = np.array([np.isin(nb[i], ring.indices[ring.indptr[i]:ring.indptr[i + 1]]) for i in range(n)])
    res['res_t_rms/s'] = float(np.sqrt(np.mean(t ** 2)) / s)
    for K in KS:
        sel = np.zeros_like(nb, dtype=bool)
        keep = ~excl
        cs = np.cumsum(keep, 1)
        sel = keep & (cs <= K)
        cnt = sel.sum(1)
        mt = np.sum(np.where(sel, t[nb], 0), 1) / cnt
        md = np.sum(np.where(sel, d[nb], 0), 1) / cnt
        res['nl_oracle_%d' % K] = S.err(P + npv * mt[:, None], C, Acl) / e_in
        res['nl_blind_%d' % K] = S.err(P + npv * md[:, None], C, Acl) / e_in
        a = max(0.0, 1 - (s * s / K) / max(np.mean(md ** 2), 1e-300))
        res['nl_blind_%d_a' % K] = S.err(P + a * npv * md[:, None], C, Acl) / e_in
        res['R2_oracle_%d' % K] = float(1 - np.mean((t - mt) ** 2) / np.mean(t ** 2))
    print(json.dumps({k: (round(v, 4) if isinstance(v, float) else v) for k, v in res.items()}), flush=True)

if __name__ == '__main__':
    for m in sys.argv[1].split(','):
        for r in sys.argv[2].split(','):
            case(m, float(r), sys.argv[3])
