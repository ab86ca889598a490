#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""rule_bias_check.py - issue 31, organic normal noise: is the default's SURE bias at 0.5 h
(fewlet_study.py DIAG) made by the OUTPUT RULE (each vertex moved along the normal of the result,
X + n <n, D>, n the normals of X + D) rather than by the filter? A lab check, not the product.

For the implicit step's low-pass D = T_k X - X (surelet_study.py's implicit_iterates, uniform graph,
k in KS) and the same D after the output rule, the divergence along the noisy normals n0 by
Monte-Carlo (4 Rademacher probes, X perturbed by eps b_i n0_i, eps = 0.1 s, the whole map
recomputed, n0 held; and the same with X perturbed along the normals p of a pilot, the 16-step
low-pass: the noise is along the clean normals, which p follows and n0 does not), SURE = sum w (n0 . D)^2 / (s^2 sum w) + 2 div, and what it estimates
(the same risk from the clean mesh); printed: the bias SURE - truth per vertex in s^2, for
the linear D ('lin') and after the rule ('rule').
Usage: rule_bias_check.py MESH-RHO[,..] [KS]   (nonlin_let.py dumps in /tmp/s31o/pdump)"""
import os, sys
import numpy as np
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import surelet_study as S

def maps(X, F, A, k):
    T = S.implicit_iterates(X, A, [k], np.zeros((len(X), 0)))[k][0]
    D = T - X
    ny = S.vnormals(X + D, F)
    return D, ny * np.sum(ny * D, 1)[:, None]

for case in sys.argv[1].split(','):
    z = dict(np.load('/tmp/s31o/pdump/%s-f.npz' % case))
    X, F, s, n0, w, C = z['X'], z['F'], float(z['s']), z['n0'], z['w'], z['C']
    A = S.adjacency(F, len(X))
    t = np.sum(n0 * (C - X), 1)
    for k in [int(v) for v in (sys.argv[2] if len(sys.argv) > 2 else '4,16').split(',')]:
        base = maps(X, F, A, k)
        p = S.vnormals(X + maps(X, F, A, 16)[0], F)  # a pilot's normals: the 16-step low-pass
        out = []
        for dn, u in (('n0', n0), ('p', p)):
            rng, div = np.random.default_rng(11), np.zeros(2)
            for _ in range(4):
                b = np.where(rng.random(len(X)) < 0.5, -1.0, 1.0)
                Xp = X + 0.1 * s * b[:, None] * u
                pert = maps(Xp, F, A, k)
                for j in range(2):  # D(Xp) - D(X), the identity part included (D = Y - X)
                    div[j] += np.sum(w * b * np.sum(n0 * (pert[j] - base[j]), 1)) / (0.1 * s) / 4
            for j, nm in enumerate(('lin', 'rule')):
                h = np.sum(n0 * base[j], 1)
                sure = (np.sum(w * h * h) + 2 * s * s * div[j]) / (s * s * w.sum())
                true = np.sum(w * (h - t) ** 2) / (s * s * w.sum()) - 1
                out.append('%s, perturbed along %s: bias %.3f (true %.3f)' % (nm, dn, sure - true, true))
        print(case, 'k', k, ' | '.join(out), flush=True)
