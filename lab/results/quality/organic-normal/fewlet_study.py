#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""fewlet_study.py - issue 31, organic normal noise: the f + c SURE-LET's blocker was the variance
of 16 weights fitted by SURE (pilot_sure.py's DIAG: SURE's own minimiser looks better than the
truth by 0.01-0.2 s^2 a vertex). This tries FEWER or SHRUNK weights around the product's default.
A lab study, not the product.

Input: nonlin_let.py's dumps of families f and c (DUMP=DIR) of each case; the default's
displacement Dd is recomputed with MCF (the tree under test) and its divergence along the noisy
normals n0 estimated by Monte-Carlo through `mcf smooth` (DEFPROBES runs, default 4, X perturbed by
eps b_i n0_i, eps = 0.1 s, b Rademacher: div ~ sum_i w_i b_i n0_i . (Dd'_i - Dd_i) / eps, Ramani,
Blu, Unser 2008). SURE everywhere: heights along n0, noisy areas w (mean 1), true s,
    SURE(D) = sum w (n0 . D)^2 + 2 s^2 div(D)      (minus the constant s^2 sum w),
the columns' divergences the 16-probe Hutchinson diagonals of the dumps. Candidates (the output
moves along the normals of X + D, as the product's):
  ridge_L   D = Dd + sum_k t_k col_k over the 16 linear f and c columns (pick_study.py's),
            t least SURE + L sum_k G_kk t_k^2: a ridge toward the default, each weight scaled by
            its column's energy (L in LAMS; L = 0 is pick_study.py's let_fc with Dd added); the
            weights need no divergence of the default (it is common to every t);
  mix_c     D = Dd + g (Ck - Dd), Ck = T^c_k X - X the pilot-cotan passes' k-th low-pass
            displacement (k = 2^j, j = 0..7, printed as mix_c_k = j), k and g by SURE (2 parameters,
            + 2 s^2 for g);
  ab_c      D = a Dd + b Ck, k, a, b by SURE (3 parameters);
  mix_f, ab_f  the same with the implicit step's low-pass Fk (k = 1..32);
  g_mix_<f>    mix_<f> when its SURE is below the default's, else the default.
Each candidate's oracle (its parameters by the clean mesh) is printed as orc_<name>.
DIAG=1 also prints bias_def, bias_c, bias_f: SURE minus what it estimates (the same risk along n0
computed from the clean mesh), per vertex in s^2, for the default and each low-pass Ck / Fk, and
true_* (that risk). CACHE=DIR keeps the default's displacement and divergence per case (for
ridgecv_study.py and wiener_study.py; DEFPROBES=0 skips the divergence).
Usage: fewlet_study.py DIR MCF"""
import glob, json, os, subprocess, sys
import numpy as np
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import surelet_study as S
from pick_study import err

LAMS = [float(t) for t in os.environ.get('LAMS', '0,0.003,0.01,0.03,0.1,0.3,1').split(',')]

def mcf_run(mcf, V, F, tag):
    S.write_obj('/tmp/s31o/fl_%s_in.obj' % tag, V, F)
    subprocess.run([mcf, 'smooth', '--quiet', '/tmp/s31o/fl_%s_in.obj' % tag, '/tmp/s31o/fl_%s_out.obj' % tag], check=True)
    return S.read_obj('/tmp/s31o/fl_%s_out.obj' % tag)[0]

def default_div(mcf, X, F, Dd, n0, w, s, tag):
    nprobe, eps = int(os.environ.get('DEFPROBES', '4')), 0.1 * s
    rng, div = np.random.default_rng(11), 0.0
    for _ in range(nprobe):
        b = np.where(rng.random(len(X)) < 0.5, -1.0, 1.0)
        Xp = X + eps * b[:, None] * n0
        D2 = mcf_run(mcf, Xp, F, tag) - Xp
        div += np.sum(w * b * np.sum(n0 * (D2 - Dd), 1)) / eps / nprobe
    return div

def main(d, mcf):
    for pf in sorted(glob.glob(d + '/*-f.npz')):
        pc = pf[:-6] + '-c.npz'
        if not os.path.exists(pc):
            continue
        zf, zc = dict(np.load(pf)), dict(np.load(pc))
        mesh, rho = os.path.basename(pf).rsplit('-', 2)[:2]
        X, F, s, n0, w, C = zf['X'], zf['F'], float(zf['s']), zf['n0'], zf['w'], zf['C']
        tag = '%s-%s' % (mesh, rho)
        cache = os.environ.get('CACHE') and '%s/%s-dd.npz' % (os.environ['CACHE'], tag)
        if cache and os.path.exists(cache):
            q = np.load(cache)
            Dd, dd = q['Dd'], float(q['dd'])
        else:
            Dd = mcf_run(mcf, X, F, tag) - X
            dd = default_div(mcf, X, F, Dd, n0, w, s, tag)
            if cache:
                np.savez(cache, Dd=Dd, dd=dd)
        lf = [i for i, k in enumerate(zf['kinds']) if k == 'lin']
        lc = [i for i, k in enumerate(zc['kinds']) if k == 'lin']
        cf, cc = zf['cols'][lf], zc['cols'][lc]
        df, dc = zf['divs'][lf], zc['divs'][lc]
        h = lambda D: np.sum(n0 * D, 1)
        t_true = np.sum(n0 * (C - X), 1)
        A = zf['Acl']
        sure = lambda D, dv: float(np.sum(w * h(D) ** 2) + 2 * s * s * dv) / (s * s * w.sum())
        res = {'mesh': mesh, 'rho': float(rho), 'default': S.err(X + Dd, C, A) / zf['e_in'],
               'sure_def': sure(Dd, dd), 'div_def': dd / w.sum()}
        if os.environ.get('DIAG'):  # SURE minus what it estimates (from the clean mesh), per vertex in s^2
            true = lambda D: float(np.sum(w * (h(D) - t_true) ** 2)) / (s * s * w.sum()) - 1
            res['bias_def'] = res['sure_def'] - true(Dd)
            for fam, cl, dv in (('c', cc, dc), ('f', cf, df)):
                Ks, Kd = -np.cumsum(cl[:-1], 0), -np.cumsum(dv[:-1])
                res['bias_' + fam] = [round(sure(Ks[j], Kd[j]) - true(Ks[j]), 4) for j in range(len(Ks))]
                res['true_' + fam] = [round(true(Ks[j]), 4) for j in range(len(Ks))]
            res['true_def'] = true(Dd)
        # ridge toward the default over the 16 linear columns
        cols, divs = np.concatenate([cf, cc]), np.concatenate([df, dc])
        R = np.einsum('kni,ni->kn', cols, n0)
        G = (R * w) @ R.T
        b = (R * w) @ h(Dd)
        for L in LAMS:
            th = np.linalg.solve(G + L * np.diag(np.diag(G)) + 1e-12 * np.trace(G) * np.eye(len(G)), -(b + s * s * divs))
            D = Dd + np.tensordot(th, cols, 1)
            res['ridge_%g' % L] = err(zf, D)
            res['sure_ridge_%g' % L] = sure(D, dd + th @ divs)
        # low-pass displacements of each family: T_k X - X = -(B_0 + .. + B_j) X
        for fam, cl, dv in (('c', cc, dc), ('f', cf, df)):
            Ks = -np.cumsum(cl[:-1], 0)
            Kd = -np.cumsum(dv[:-1])
            best, bo, best3, bo3 = None, None, None, None
            for j in range(len(Ks)):
                Dk = Ks[j]
                # mix: D = Dd + g (Dk - Dd); SURE quadratic in g
                u = h(Dk - Dd)
                g = -(np.sum(w * h(Dd) * u) + s * s * (Kd[j] - dd)) / np.sum(w * u * u)
                D = Dd + g * (Dk - Dd)
                sv = sure(D, dd + g * (Kd[j] - dd)) + 2 / w.sum()  # + 2 s^2 for the fitted g
                if best is None or sv < best[0]:
                    best = (sv, D, j, g)
                go = np.sum(A * (t_true - h(Dd)) * u) / np.sum(A * u * u)
                eo = err(zf, Dd + go * (Dk - Dd))
                bo = eo if bo is None else min(bo, eo)
                # a Dd + b Dk
                M = np.stack([h(Dd), h(Dk)])
                G2 = (M * w) @ M.T
                ab = np.linalg.solve(G2, -s * s * np.array([dd, Kd[j]]))
                D3 = ab[0] * Dd + ab[1] * Dk
                sv3 = sure(D3, ab @ np.array([dd, Kd[j]])) + 4 / w.sum()
                if best3 is None or sv3 < best3[0]:
                    best3 = (sv3, D3, j, ab)
                abo = np.linalg.lstsq(M.T * np.sqrt(A)[:, None], t_true * np.sqrt(A), rcond=None)[0]
                eo3 = err(zf, abo[0] * Dd + abo[1] * Dk)
                bo3 = eo3 if bo3 is None else min(bo3, eo3)
            res['mix_' + fam], res['mix_%s_k' % fam], res['mix_%s_g' % fam] = err(zf, best[1]), best[2], round(best[3], 3)
            res['g_mix_' + fam] = res['mix_' + fam] if best[0] < res['sure_def'] else res['default']
            res['orc_mix_' + fam] = bo
            res['ab_' + fam], res['ab_%s_k' % fam], res['ab_%s_w' % fam] = err(zf, best3[1]), best3[2], [round(v, 3) for v in best3[3]]
            res['orc_ab_' + fam] = bo3
        print(json.dumps({k: (round(v, 4) if isinstance(v, float) else v) for k, v in res.items()}), flush=True)

if __name__ == '__main__':
    main(sys.argv[1], sys.argv[2])
