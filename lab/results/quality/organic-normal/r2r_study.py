#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""r2r_study.py - issue 31, organic normal noise: the weights of the f + c columns picked blind by
RECORRUPTED-TO-RECORRUPTED (Pang et al., CVPR 2021) instead of SURE along the noisy normals.
A lab study, not the product.

Noise as surelet_study.py (sigma = s = rho h along the clean vertex normals, numpy seed 1; s the
true level). Columns D_j(Y) (displacements from Y): f, the implicit step's iterates
(I + N^2)^-k Y - Y, k = 1..32 on the uniform graph; c, lambda|mu passes (0.5, -0.53), k = 1..128,
with the cotan weights of the product's default output for Y (mcf smooth). R2R: with z = s g n_p
(g ~ N(0, 1) per vertex, n_p the default output's normals: the noise's direction as read),
Y1 = X + a z and Y2 = X - z / a have independent noises when the noise is s along n_p, so
E|Y1 + sum_j t_j D_j(Y1) - Y2|^2 = E|... - C|^2 + const: a least-squares fit of t on DRAWS draws
(a = 0.5) is an unbiased risk fit from the noisy mesh alone (for the level s sqrt(1 + a^2)).
The weights are then applied to D_j(X). Guard: 2 more draws; the fitted combination's R2R risk
against the default's (mcf smooth of Y1 against Y2); take the combination only when lower.
Printed (error over the input's, clean areas; outputs along the normals of X + D): default,
r2r_f (6 weights), r2r_fc (14), r2r_fc_guard, and the took flag.
Usage: r2r_study.py MESH[,..] RHO[,..] MCF"""
import json, os, subprocess, sys
import numpy as np
os.makedirs('/tmp/s31o', exist_ok=True)  # the scripts' scratch files
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import surelet_study as S
from c2_study import Implicit, KF, KC

DRAWS, ALPHA = int(os.environ.get('DRAWS', '2')), 0.5

def mcf_smooth(mcf, Y, F):
    S.write_obj('/tmp/s31o/r2r_in.obj', Y, F)
    subprocess.run([mcf, 'smooth', '--quiet', '/tmp/s31o/r2r_in.obj', '/tmp/s31o/r2r_out.obj'], check=True)
    return S.read_obj('/tmp/s31o/r2r_out.obj')[0]

def columns(Y, P, F, imp):
    its = imp.iterates(Y, KF)
    cf = [its[k] - Y for k in KF]
    pc = S.pass_iterates(Y, S.cotan(P, F, len(Y)), KC, np.zeros((len(Y), 0)))
    return np.array(cf + [pc[k][0] - Y for k in KC])

def case(name, rho, mcf):
    C, F, n, Nc, Acl, X, e_in, s = S.noisy_case(name, rho)
    imp = Implicit(F, n)
    P = mcf_smooth(mcf, X, F)
    npv, w = S.vnormals(P, F), np.sqrt(S.areas(X, F))[:, None]
    cols = columns(X, P, F, imp)
    rng = np.random.default_rng(5)
    fit, ev = [], []
    for d in range(DRAWS + 2):
        z = s * rng.standard_normal(n)[:, None] * npv
        Y1, Y2 = X + ALPHA * z, X - z / ALPHA
        P1 = mcf_smooth(mcf, Y1, F)
        (fit if d < DRAWS else ev).append((Y1, Y2, P1, columns(Y1, P1, F, imp)))

    def solve(idx):
        A = np.vstack([np.stack([(c1[j] * w).ravel() for j in idx], 1) for _, _, _, c1 in fit])
        b = np.concatenate([((Y2 - Y1) * w).ravel() for Y1, Y2, _, _ in fit])
        return np.linalg.lstsq(A, b, rcond=None)[0]

    def out(D):
        ny = S.vnormals(X + D, F)
        return S.err(X + ny * np.sum(ny * D, 1)[:, None], C, Acl) / e_in
    res = {'mesh': name, 'rho': rho, 'n': n, 'default': S.err(P, C, Acl) / e_in}
    tf = solve(list(range(len(KF))))
    res['r2r_f'] = out(np.tensordot(tf, cols[:len(KF)], 1))
    t = solve(list(range(len(cols))))
    res['r2r_fc'] = out(np.tensordot(t, cols, 1))
    risk_new = sum(np.sum((w * (Y1 + np.tensordot(t, c1, 1) - Y2)) ** 2) for Y1, Y2, _, c1 in ev)
    risk_def = sum(np.sum((w * (P1 - Y2)) ** 2) for Y1, Y2, P1, _ in ev)
    res['took'] = bool(risk_new < risk_def)
    res['r2r_fc_guard'] = res['r2r_fc'] if res['took'] else res['default']
    res['risk_new/def'] = risk_new / risk_def
    print(json.dumps({k: (round(v, 4) if isinstance(v, float) else v) for k, v in res.items()}), flush=True)

if __name__ == '__main__':
    for m in sys.argv[1].split(','):
        for r in sys.argv[2].split(','):
            case(m, float(r), sys.argv[3])
