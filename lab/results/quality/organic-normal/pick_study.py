#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""pick_study.py - issue 31, organic normal noise: a second linear family, lambda|mu passes with
the cotan weights of a PILOT held fixed (the default's output; the filter is then linear in the
noise and the probes' traces are its divergence), picked against the product's family by SURE.
A lab study, not the product.

Input: the dumps of nonlin_let.py for families f and c of the same case (DUMP=DIR). Linear
columns only (bands and low-pass; f: 7, c: 9). For each family its SURE-LET along the noisy
normals n0 (16 Rademacher probes, true s), and its SURE at those weights plus 2 s^2 per weight
(the fitted weights' optimism). Printed (error over the input's, clean areas):
  default, let_f, let_c (blind, each family alone), orc_c (c's weights fitted to the clean mesh);
  pick      the family of lower penalised SURE;
  pick_def  the default unless c's penalised SURE is below f's (f's SURE-LET stands for the
            default, which is within a few % of it: the guard a product change would run);
  let_fc    SURE-LET over both families' columns together (16 weights), orc_fc its oracle.
ORC_FROM=DIR2 (the same cases dumped with another noise seed, SEED=2): also orc_c_x / orc_fc_x,
the oracle weights fitted on DIR2's draw and applied to this one (the best FIXED weights for the
mesh and level, without the in-sample oracle's fit to this draw's noise: 9 or 16 weights fitted to
n heights gain up to ~k s^2 of the squared error on a small mesh by fitting the noise itself).
RAW=DIR RAW_CASE=mesh-rho (e.g. knot1-0.1): also writes that case's clean, noisy, default,
SURE-LET c and f+c oracle meshes as render_quality.py's raw files.
Usage: pick_study.py DIR"""
import glob, json, os, sys
import numpy as np
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import surelet_study as S

def let(z, cols, divs):
    R = np.einsum('kni,ni->kn', cols, z['n0'])
    G = (R * z['w'][None]) @ R.T
    th = np.linalg.solve(G + 1e-12 * np.trace(G) * np.eye(len(cols)), -z['s'] ** 2 * divs)
    sure = float(th @ G @ th + 2 * z['s'] ** 2 * th @ divs) + 2 * z['s'] ** 2 * len(cols)
    return np.tensordot(th, cols, 1), sure / (z['s'] ** 2 * z['w'].sum())

def orc_w(z, cols):
    sw = np.sqrt(z['Acl'])
    A = np.einsum('kni,ni->nk', cols, z['n0']) * sw[:, None]
    return np.linalg.lstsq(A, np.sum((z['C'] - z['X']) * z['n0'], 1) * sw, rcond=None)[0]

def orc(z, cols):
    return np.tensordot(orc_w(z, cols), cols, 1)

def err(z, D):
    X = z['X']
    ny = S.vnormals(X + D, z['F'])
    return S.err(X + ny * np.sum(ny * D, 1)[:, None], z['C'], z['Acl']) / z['e_in']

def main(d):
    for pf in sorted(glob.glob(d + '/*-f.npz')):
        pc = pf[:-6] + '-c.npz'
        if not os.path.exists(pc):
            continue
        zf, zc = dict(np.load(pf)), dict(np.load(pc))
        mesh, rho = os.path.basename(pf).rsplit('-', 2)[:2]
        lf = [i for i, k in enumerate(zf['kinds']) if k == 'lin']
        lc = [i for i, k in enumerate(zc['kinds']) if k == 'lin']
        Df, sf = let(zf, zf['cols'][lf], zf['divs'][lf])
        Dc, sc = let(zc, zc['cols'][lc], zc['divs'][lc])
        both = np.concatenate([zf['cols'][lf], zc['cols'][lc]])
        Dfc, sfc = let(zf, both, np.concatenate([zf['divs'][lf], zc['divs'][lc]]))
        res = {'mesh': mesh, 'rho': float(rho), 'default': S.err(zf['X'] + zf['Dd'], zf['C'], zf['Acl']) / zf['e_in'], 'let_f': err(zf, Df),
               'let_c': err(zf, Dc), 'orc_c': err(zf, orc(zf, zc['cols'][lc])), 'sure_f': sf, 'sure_c': sc}
        res['pick'] = res['let_c'] if sc < sf else res['let_f']
        res['pick_def'] = res['let_c'] if sc < sf else res['default']
        res['let_fc'], res['sure_fc'], res['orc_fc'] = err(zf, Dfc), sfc, err(zf, orc(zf, both))
        if os.environ.get('ORC_FROM'):
            q = os.path.join(os.environ['ORC_FROM'], os.path.basename(pf))
            if os.path.exists(q) and os.path.exists(q[:-6] + '-c.npz'):
                yf, yc = dict(np.load(q)), dict(np.load(q[:-6] + '-c.npz'))
                res['orc_c_x'] = err(zf, np.tensordot(orc_w(yf, yc['cols'][lc]), zc['cols'][lc], 1))
                w2 = orc_w(yf, np.concatenate([yf['cols'][lf], yc['cols'][lc]]))
                res['orc_fc_x'] = err(zf, np.tensordot(w2, both, 1))
        if os.environ.get('RAW_CASE') == '%s-%s' % (mesh, rho):
            from adaptive_study import write_raw
            X, F, tag = zf['X'], zf['F'], '%s/%s-%s' % (os.environ['RAW'], mesh, rho)
            for nm, V in (('clean', zf['C']), ('noisy', X), ('default', X + zf['Dd']), ('let_c', X + Dc),
                          ('orc_fc', X + orc(zf, both))):
                if nm in ('let_c', 'orc_fc'):  # the output rule: along the normals of X + D
                    D = V - X
                    ny = S.vnormals(V, F)
                    V = X + ny * np.sum(ny * D, 1)[:, None]
                write_raw('%s-%s.raw' % (tag, nm), V, F)
        print(json.dumps({k: (round(v, 4) if isinstance(v, float) else v) for k, v in res.items()}), flush=True)

if __name__ == '__main__':
    main(sys.argv[1])
