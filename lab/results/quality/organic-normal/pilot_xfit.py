#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""pilot_xfit.py - issue 31, organic normal noise: pilot_sure.py's SURE-LET along the pilot's
normals p with the 16 weights CROSS-FITTED over two random halves of the vertices (seeded): the
weights fitted on one half's SURE displace the other half, so no vertex is moved by weights fitted
to its own SURE term. Tests whether the SURE-LET's loss is its in-sample optimism. A lab study.
Printed: default, xfit_p (error over the input's, clean areas). Usage: pilot_xfit.py DIR"""
import glob, json, os, sys
import numpy as np
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import surelet_study as S
from pick_study import err
from pilot_sure import gram
d = sys.argv[1]
for pf in sorted(glob.glob(d + '/*-f.npz')):
    zf, zc = dict(np.load(pf)), dict(np.load(pf[:-6] + '-c.npz'))
    mesh, rho = os.path.basename(pf).rsplit('-', 2)[:2]
    lf = [i for i, k in enumerate(zf['kinds']) if k == 'lin']; lc = [i for i, k in enumerate(zc['kinds']) if k == 'lin']
    cols = np.concatenate([zf['cols'][lf], zc['cols'][lc]]); dgv = np.concatenate([zf['dgv'][lf], zc['dgv'][lc]])
    X, F, s = zf['X'], zf['F'], float(zf['s']); P = X + zf['Dd']; p = S.vnormals(P, F); wp = S.areas(P, F); wp /= wp.mean()
    half = np.random.default_rng(5).random(len(X)) < 0.5
    D = np.zeros_like(X)
    for m in (half, ~half):
        G, dd = gram(cols, wp * m, dgv, p)
        th = np.linalg.solve(G + 1e-12 * np.trace(G) * np.eye(len(dd)), -s * s * dd)
        D[~m] = np.tensordot(th, cols, 1)[~m]
    print(json.dumps({'mesh': mesh, 'rho': float(rho), 'default': round(S.err(P, zf['C'], zf['Acl']) / zf['e_in'], 4), 'xfit_p': round(err(zf, D), 4)}))
