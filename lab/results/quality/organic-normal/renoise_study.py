#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""renoise_study.py - issue 31, organic normal noise: the f + c columns' weights fitted blind on a
RE-NOISED PILOT: the default's output P stands for the clean mesh, synthetic noise at the level
s along P's normals makes a noisy copy Xs, the weights least squares from Xs's columns to P (what
they would be if P were the truth), then applied to the real noisy mesh's columns. A lab study,
not the product. (P is smoother than the clean mesh, so these weights are biased to smooth more.)

Noise as surelet_study.py (sigma = s = rho h along the clean vertex normals, numpy seed 1; s the
true level). Columns as r2r_study.py (f: implicit step k = 1..32; c: lambda|mu passes k = 1..128
with the cotan weights of the default output of the same input). DRAWS synthetic draws (seed 5).
Printed (error over the input's, clean areas; outputs along the normals of X + D): default,
renoise_f (6 weights), renoise_fc (14).
Usage: renoise_study.py MESH[,..] RHO[,..] MCF"""
import json, os, sys
import numpy as np
os.makedirs('/tmp/s31o', exist_ok=True)  # the scripts' scratch files
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import surelet_study as S
from c2_study import Implicit, KF
from r2r_study import mcf_smooth, columns

DRAWS = int(os.environ.get('DRAWS', '2'))

def case(name, rho, mcf):
    C, F, n, Nc, Acl, X, e_in, s = S.noisy_case(name, rho)
    imp = Implicit(F, n)
    P = mcf_smooth(mcf, X, F)
    npv, w = S.vnormals(P, F), np.sqrt(S.areas(X, F))[:, None]
    cols = columns(X, P, F, imp)
    rng, fit = np.random.default_rng(5), []
    for _ in range(DRAWS):
        Xs = P + s * rng.standard_normal(n)[:, None] * npv
        fit.append((Xs, columns(Xs, mcf_smooth(mcf, Xs, F), F, imp)))

    def solve(idx):
        A = np.vstack([np.stack([(c1[j] * w).ravel() for j in idx], 1) for _, c1 in fit])
        b = np.concatenate([((P - Xs) * w).ravel() for Xs, _ in fit])
        return np.linalg.lstsq(A, b, rcond=None)[0]

    def out(D):
        ny = S.vnormals(X + D, F)
        return S.err(X + ny * np.sum(ny * D, 1)[:, None], C, Acl) / e_in
    res = {'mesh': name, 'rho': rho, 'n': n, 'default': S.err(P, C, Acl) / e_in}
    res['renoise_f'] = out(np.tensordot(solve(list(range(len(KF)))), cols[:len(KF)], 1))
    res['renoise_fc'] = out(np.tensordot(solve(list(range(len(cols)))), cols, 1))
    print(json.dumps({k: (round(v, 4) if isinstance(v, float) else v) for k, v in res.items()}), flush=True)

if __name__ == '__main__':
    for m in sys.argv[1].split(','):
        for r in sys.argv[2].split(','):
            case(m, float(r), sys.argv[3])
