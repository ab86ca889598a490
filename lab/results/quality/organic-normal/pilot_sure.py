#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""pilot_sure.py - issue 31, organic normal noise: the SURE-LET over the f and c families
(pick_study.py's let_fc, 16 linear weights) with the risk taken along the PILOT's normals
instead of the noisy mesh's. A lab study, not the product.

Why: pick_study.py's SURE is of the heights along n0, the noisy mesh's normals; n0 moves with
each vertex's own noise, so Stein's lemma does not hold for it exactly. Model the noise as
X = C + s xi_i p_i with p the normals of the pilot P = X + Dd (the default's output; a vertex's
own noise reaches p_i only through P's smoothing, i.e. barely). Every column is a scalar
operator B applied per coordinate, D_i = sum_j B_ij X_j, so d(p_i . D_i)/d xi_i = s B_ii and
the divergence term is the same per-vertex diagonal as before (dgv, Hutchinson over 16
Rademacher probes, saved by nonlin_let.py); only the quadratic term and the vertex weights change:
  n0   pick_study.py's criterion: sum w (n0 . D)^2 + 2 s^2 sum w B_ii, w the noisy areas;
  p    heights along the pilot's normals, w the pilot's areas (mean 1);
  3d   the full 3D displacement sum w |D|^2 (the risk of X + D itself, tangential drift
       included), w the pilot's areas.
Each: weights theta = -s^2 G^-1 d (G the Gram of the columns in that norm, d the weighted
divergences), and SURE at theta plus 2 s^2 per weight (the fitted weights' optimism), per
vertex in s^2. The output moves along the normals of X + D (the product's rule).
The guard ("never worse than the default by SURE"): the default's own SURE in the same norm,
its divergence by Monte-Carlo through `mcf smooth` (DEFPROBES runs, default 4, perturbing X by
eps b_i p_i, b Rademacher, eps = 0.1 s: div ~ sum_i w_i b_i p_i . (Dd'_i - Dd_i) / eps, the
Ramani-Blu-Unser estimate along p); g_<crit> is let_<crit> when its SURE is below the default's,
else the default. DEFPROBES=0 skips it. Printed (error over the input's, clean areas):
  default, let_n0, let_p, let_3d, g_p, g_3d, took_p / took_3d, sure_* (the criteria's values),
  orc_fc (the 16 weights fitted to the clean mesh), orc_fc_x (ORC_FROM=DIR2: fitted on the
  seed-2 draw of the same mesh and level, applied to this one: the best fixed weights).
DIAG=1 also prints, per criterion, true_<crit>: what its SURE estimates, computed from the
clean mesh at its own weights (with the same 2 s^2 per weight), and sure_x_<crit> / true_x_<crit>:
SURE and truth at the fixed seed-2 weights: SURE's pick is wrong when sure_x > sure while
true_x < true.
Usage: pilot_sure.py DIR MCF"""
import glob, json, os, subprocess, sys
import numpy as np
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import surelet_study as S
from pick_study import orc_w, err
DIAG = bool(os.environ.get('DIAG'))

def gram(cols, w, dgv, crit_dir):
    if crit_dir is None:
        return np.einsum('kni,lni,n->kl', cols, cols, w), dgv @ w
    R = np.einsum('kni,ni->kn', cols, crit_dir)
    return (R * w[None]) @ R.T, dgv @ w

def fit(cols, w, dgv, s, crit_dir):
    """theta, the displacement and SURE per vertex (in s^2, minus the constant 1), for heights
    along crit_dir (n x 3 unit vectors) or the full 3D norm (crit_dir None)."""
    G, d = gram(cols, w, dgv, crit_dir)
    th = np.linalg.solve(G + 1e-12 * np.trace(G) * np.eye(len(d)), -s * s * d)
    return th, np.tensordot(th, cols, 1), sure_at(th, G, d, s, w)

def sure_at(th, G, d, s, w):  # penalised by 2 s^2 per weight, as pick_study.py
    return (float(th @ G @ th + 2 * s * s * th @ d) + 2 * s * s * len(d)) / (s * s * w.sum())

def truth(z, D, w, crit_dir):
    """what SURE estimates, from the clean mesh: risk per vertex in s^2, minus 1."""
    E = z['X'] + D - z['C']
    q = np.sum(E * E, 1) if crit_dir is None else np.sum(E * crit_dir, 1) ** 2
    return float(np.sum(w * q) / (float(z['s']) ** 2 * w.sum())) - 1

def default_sure(z, mcf, p, wp, tag):
    """SURE of the default's displacement, along p and in 3D, divergence by MC through mcf."""
    X, F, Dd, s = z['X'], z['F'], z['Dd'], float(z['s'])
    nprobe, eps = int(os.environ.get('DEFPROBES', '4')), 0.1 * float(z['s'])
    if nprobe == 0:
        return None, None
    rng, div = np.random.default_rng(11), 0.0
    for _ in range(nprobe):
        b = np.where(rng.random(len(X)) < 0.5, -1.0, 1.0)
        S.write_obj('/tmp/s31o/ps_%s_in.obj' % tag, X + eps * b[:, None] * p, F)
        subprocess.run([mcf, 'smooth', '--quiet', '/tmp/s31o/ps_%s_in.obj' % tag, '/tmp/s31o/ps_%s_out.obj' % tag],
                       check=True)
        D2 = S.read_obj('/tmp/s31o/ps_%s_out.obj' % tag)[0] - X - eps * b[:, None] * p
        div += np.sum(wp * b * np.sum(p * (D2 - Dd), 1)) / eps / nprobe
    sp_ = (np.sum(wp * np.sum(p * Dd, 1) ** 2) + 2 * s * s * div) / (s * s * wp.sum())
    s3 = (np.sum(wp * np.sum(Dd * Dd, 1)) + 2 * s * s * div) / (s * s * wp.sum())
    return sp_, s3

def main(d, mcf):
    for pf in sorted(glob.glob(d + '/*-f.npz')):
        pc = pf[:-6] + '-c.npz'
        if not os.path.exists(pc):
            continue
        zf, zc = dict(np.load(pf)), dict(np.load(pc))
        mesh, rho = os.path.basename(pf).rsplit('-', 2)[:2]
        lf = [i for i, k in enumerate(zf['kinds']) if k == 'lin']
        lc = [i for i, k in enumerate(zc['kinds']) if k == 'lin']
        cols = np.concatenate([zf['cols'][lf], zc['cols'][lc]])
        dgv = np.concatenate([zf['dgv'][lf], zc['dgv'][lc]])
        X, F, s = zf['X'], zf['F'], float(zf['s'])
        P = X + zf['Dd']
        p = S.vnormals(P, F)
        wp = S.areas(P, F)
        wp = wp / wp.mean()
        res = {'mesh': mesh, 'rho': float(rho), 'default': S.err(P, zf['C'], zf['Acl']) / zf['e_in']}
        thx = None
        if os.environ.get('ORC_FROM'):
            q = os.path.join(os.environ['ORC_FROM'], os.path.basename(pf))
            if os.path.exists(q) and os.path.exists(q[:-6] + '-c.npz'):
                yf, yc = dict(np.load(q)), dict(np.load(q[:-6] + '-c.npz'))
                thx = orc_w(yf, np.concatenate([yf['cols'][lf], yc['cols'][lc]]))
        for nm, w, dirs in (('n0', zf['w'], zf['n0']), ('p', wp, p), ('3d', wp, None)):
            th, D, sure = fit(cols, w, dgv, s, dirs)
            res['let_' + nm], res['sure_' + nm] = err(zf, D), sure
            if DIAG:  # SURE against its truth, at its own weights and at the fixed (seed-2) ones
                res['true_' + nm] = truth(zf, D, w, dirs) + 2 * len(th) * s * s / (s * s * w.sum())
                if thx is not None:
                    G, dd = gram(cols, w, dgv, dirs)
                    res['sure_x_' + nm] = sure_at(thx, G, dd, s, w)
                    res['true_x_' + nm] = truth(zf, np.tensordot(thx, cols, 1), w, dirs) + 2 * len(th) / w.sum()
        sdp, sd3 = default_sure(zf, mcf, p, wp, '%s-%s' % (mesh, rho))
        if sdp is not None:
            res['sure_def_p'], res['sure_def_3d'] = sdp, sd3
            res['took_p'], res['took_3d'] = bool(res['sure_p'] < sdp), bool(res['sure_3d'] < sd3)
            res['g_p'] = res['let_p'] if res['took_p'] else res['default']
            res['g_3d'] = res['let_3d'] if res['took_3d'] else res['default']
            if DIAG:
                res['true_def_p'], res['true_def_3d'] = truth(zf, zf['Dd'], wp, p), truth(zf, zf['Dd'], wp, None)
        res['orc_fc'] = err(zf, np.tensordot(orc_w(zf, cols), cols, 1))
        if thx is not None:
            res['orc_fc_x'] = err(zf, np.tensordot(thx, cols, 1))
        print(json.dumps({k: (round(v, 4) if isinstance(v, float) else v) for k, v in res.items()}), flush=True)

if __name__ == '__main__':
    main(sys.argv[1], sys.argv[2])
