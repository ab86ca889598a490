#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""epsdiv_check.py - issue 31, organic normal noise: the default's divergence along the noisy normals
by Monte-Carlo through `mcf smooth` (fewlet_study.py's estimate) at several step sizes eps (in s), 4
Rademacher probes each, against the divergence its risk implies (from the clean mesh: SURE
unbiased would need div = (risk - sum w (n0 . Dd)^2 / (s^2 sum w)) / 2 per vertex). A lab check.
Run from the repository root. Usage: epsdiv_check.py MESH-RHO EPS[,EPS..]   (nonlin_let.py dumps in /tmp/s31o/pdump)"""
import sys, os
import numpy as np
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fewlet_study as FL
case = sys.argv[1]
z = dict(np.load('/tmp/s31o/pdump/%s-f.npz' % case))
X, F, s, n0, w, C = z['X'], z['F'], float(z['s']), z['n0'], z['w'], z['C']
Dd = FL.mcf_run('build/mcf', X, F, 'eps') - X
for ef in [float(t) for t in sys.argv[2].split(',')]:
    rng, divs = np.random.default_rng(11), []
    for _ in range(4):
        b = np.where(rng.random(len(X)) < 0.5, -1.0, 1.0)
        Xp = X + ef * s * b[:, None] * n0
        D2 = FL.mcf_run('build/mcf', Xp, F, 'eps') - Xp
        divs.append(np.sum(w * b * np.sum(n0 * (D2 - Dd), 1)) / (ef * s) / w.sum())
    print(case, 'eps', ef, 'div/vertex', np.round(divs, 4), flush=True)
h = np.sum(n0 * Dd, 1); t = np.sum(n0 * (C - X), 1)
truth = np.sum(w * (h - t) ** 2) / (s * s * w.sum()) - 1
print('implied div', (truth - np.sum(w * h * h) / (s * s * w.sum())) / 2)
