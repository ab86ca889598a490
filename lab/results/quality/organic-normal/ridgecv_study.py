#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""ridgecv_study.py - issue 31, organic normal noise: fewlet_study.py's ridge toward the default
(D = Dd + sum_k t_k col_k over the 16 linear f and c columns, t least SURE + L sum_k G_kk t_k^2)
with its strength L chosen blind by cross-validated SURE. A lab study, not the product.

SURE is a sum over vertices, so it can score weights fitted on OTHER vertices: the vertices are
split into two folds, the weights fitted on one fold's SURE (the Gram and the divergences summed
over that fold only), scored by the other fold's SURE (the default's own divergence is common to
every L and drops out), and back; SPLITS repetitions. L = inf (the default) is a candidate. The
pick is refitted on all vertices. Folds: 'rand' (vertices at random) or 'block' (cubes of
BLOCK mean edges: the filters mix neighbours, so a random split leaks a vertex's noise into the
other fold's columns). Input: nonlin_let.py's f and c dumps and fewlet_study.py's cache of the
default's displacement (CACHE=DIR, run fewlet_study.py first). Printed (error over the input's):
default, cv_rand, cv_block (and the L picked), ridge_<L> for the grid.
COLS=f or COLS=c: one family's columns only (default fc, both).
ANCHOR=flin: shrink toward the f columns' own SURE-LET (linear) instead of the default's output
(L = inf is then that anchor, printed as 'anchor').
CRIT=p: SURE of the heights along the default output's normals p (its areas) instead of n0
(the divergences unchanged: every column is a scalar operator per coordinate, pilot_sure.py).
RAW=DIR RAW_CASE=mesh-rho (e.g. knot1-0.1): also writes that case's clean, noisy, default and
cv_block meshes as render_quality.py's raw files.
Usage: ridgecv_study.py DIR CACHE"""
import glob, json, os, sys
import numpy as np
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import surelet_study as S
from pick_study import err

LAMS = [0, 0.003, 0.01, 0.03, 0.1, 0.3, 1, 3, np.inf]
SPLITS = int(os.environ.get('SPLITS', '4'))
BLOCK = float(os.environ.get('BLOCK', '8'))

def fit(R, w, hd, dgv, s, L, m):
    if np.isinf(L):
        return np.zeros(len(R))
    Rm, wm = R[:, m], w[m]
    G = (Rm * wm) @ Rm.T
    g = (Rm * wm) @ hd[m] + s * s * (dgv[:, m] @ wm)
    return np.linalg.solve(G + L * np.diag(np.diag(G)) + 1e-12 * np.trace(G) * np.eye(len(G)), -g)

def score(R, w, hd, dgv, s, th, m):
    r = hd[m] + th @ R[:, m]
    return float(np.sum(w[m] * r * r) + 2 * s * s * (th @ (dgv[:, m] @ w[m])))

def folds(kind, X, h, rng):
    if kind == 'rand':
        return rng.random(len(X)) < 0.5
    off = rng.random(3) * BLOCK * h
    cell = np.floor((X + off) / (BLOCK * h)).astype(np.int64)
    key = (cell[:, 0] * 73856093) ^ (cell[:, 1] * 19349663) ^ (cell[:, 2] * 83492791)
    u, inv = np.unique(key, return_inverse=True)
    return (rng.random(len(u)) < 0.5)[inv]

def main(d, cache):
    for pf in sorted(glob.glob(d + '/*-f.npz')):
        zf, zc = dict(np.load(pf)), dict(np.load(pf[:-6] + '-c.npz'))
        mesh, rho = os.path.basename(pf).rsplit('-', 2)[:2]
        q = np.load('%s/%s-%s-dd.npz' % (cache, mesh, rho))
        Dd = q['Dd']
        X, F, s, n0, w = zf['X'], zf['F'], float(zf['s']), zf['n0'], zf['w']
        lf = [i for i, k in enumerate(zf['kinds']) if k == 'lin']
        lc = [i for i, k in enumerate(zc['kinds']) if k == 'lin']
        res = {'mesh': mesh, 'rho': float(rho), 'default': S.err(X + Dd, zf['C'], zf['Acl']) / zf['e_in']}
        fams = os.environ.get('COLS', 'fc')  # which families' columns: f, c or both
        cols = np.concatenate([z['cols'][l] for f, z, l in (('f', zf, lf), ('c', zc, lc)) if f in fams])
        dgv = np.concatenate([z['dgv'][l] for f, z, l in (('f', zf, lf), ('c', zc, lc)) if f in fams])
        if os.environ.get('CRIT') == 'p':  # heights along the pilot's (the default output's) normals
            n0 = S.vnormals(X + Dd, F)
            w = S.areas(X + Dd, F)
            w = w / w.mean()
        R = np.einsum('kni,ni->kn', cols, n0)
        if os.environ.get('ANCHOR') == 'flin':
            # the anchor made linear: the f columns' own SURE-LET (the product's combination of
            # its iterates stands for the default), so every displacement SURE compares is linear
            Rf = np.einsum('kni,ni->kn', zf['cols'][lf], n0)
            Gf = (Rf * w) @ Rf.T
            tf = np.linalg.solve(Gf + 1e-12 * np.trace(Gf) * np.eye(len(Gf)), -s * s * (zf['dgv'][lf] @ w))
            Dd = np.tensordot(tf, zf['cols'][lf], 1)
            ny = S.vnormals(X + Dd, F)
            res['anchor'] = S.err(X + ny * np.sum(ny * Dd, 1)[:, None], zf['C'], zf['Acl']) / zf['e_in']
        hd = np.sum(n0 * Dd, 1)
        E = S.edges(F)
        h = np.linalg.norm(X[E[:, 0]] - X[E[:, 1]], axis=1).mean()
        allm = np.ones(len(X), bool)
        out = {}
        for L in LAMS:
            th = fit(R, w, hd, dgv, s, L, allm)
            out[L] = err(zf, Dd + np.tensordot(th, cols, 1)) if not np.isinf(L) else res.get('anchor', res['default'])
            res['ridge_%g' % L] = out[L]
        for kind in ('rand', 'block'):
            rng = np.random.default_rng(5)
            cv = np.zeros((SPLITS, len(LAMS)))
            for t in range(SPLITS):
                a = folds(kind, X, h, rng)
                for m, o in ((a, ~a), (~a, a)):
                    for j, L in enumerate(LAMS):
                        cv[t, j] += score(R, w, hd, dgv, s, fit(R, w, hd, dgv, s, L, m), o)
            mean = cv.mean(0)
            j = int(np.argmin(mean))
            res['cv_' + kind], res['L_' + kind] = out[LAMS[j]], str(LAMS[j])
            # the one-standard-error rule: the strongest shrinkage whose score is within one
            # standard error (over the splits, of its difference to the best) of the best's
            se = np.array([np.std(cv[:, i] - cv[:, j], ddof=1) / np.sqrt(SPLITS) for i in range(len(LAMS))])
            j1 = max(i for i in range(len(LAMS)) if mean[i] - mean[j] <= se[i])
            res['cv1_' + kind], res['L1_' + kind] = out[LAMS[j1]], str(LAMS[j1])
            # the product's guard: the pick's gain over the default (L = inf, last) at least twice
            # its standard error over the splits, else the default
            k = len(LAMS) - 1
            res['cvg_' + kind] = out[LAMS[j]] if mean[k] - mean[j] >= 2 * se[k] else res['default']
        if os.environ.get('RAW_CASE') == '%s-%s' % (mesh, rho):  # render_quality.py's raw files
            from adaptive_study import write_raw
            th = fit(R, w, hd, dgv, s, float(res['L_block']), allm)
            D = Dd + np.tensordot(th, cols, 1)
            ny = S.vnormals(X + D, F)
            tag = '%s/%s-%s' % (os.environ['RAW'], mesh, rho)
            for nm, V in (('clean', zf['C']), ('noisy', X), ('default', X + Dd),
                          ('ridgecv', X + ny * np.sum(ny * D, 1)[:, None])):
                write_raw('%s-%s.raw' % (tag, nm), V, F)
        print(json.dumps({k: (round(v, 4) if isinstance(v, float) else v) for k, v in res.items()}), flush=True)

if __name__ == '__main__':
    main(sys.argv[1], sys.argv[2])
