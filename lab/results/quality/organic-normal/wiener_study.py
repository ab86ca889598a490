#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""wiener_study.py - issue 31, organic normal noise: an "empirical Wiener" second stage (BM3D's
second step on the mesh's own bands) with the default's output as the pilot. A lab study, not
the product.

Bands of the pilot-cotan passes (nonlin_let.py's family c: lambda|mu passes with the cotan weights
of the pilot P held fixed, k = 1, 2, 4, .., 128): B_0 = I - T_1, B_j = T_kj-1 - T_kj, low-pass kept.
For each band j and vertex i the pilot's energy e_ji = the 1-ring average (applied AVG times, the
vertex included) of (n0 . B_j P)_i^2, the band's noise sigma_ji^2 = s^2 mean_z (B_j z)_i^2 (16
Rademacher probes: the row norms of B_j), the gain g_ji = e / (e + sigma^2) (local), or one gain per
band from the sums over the vertices (global). The estimate keeps g of each band of X:
    D = - sum_j (1 - g_j) . B_j X,   its divergence - sum_j (1 - g_j) . diag(B_j) (gains held fixed,
the pilot's dependence on each vertex's own noise neglected as in pick_study.py).
P: the default's output from fewlet_study.py's cache (CACHE), the same as the dump's pilot up to
the build. Printed (error over the input's, the output along the normals of X + D): default,
wien_loc, wien_glob, their SURE along n0 (per vertex, in s^2) and the default's (fewlet_study.py's
Monte-Carlo divergence: biased high at 0.5 h, see the README), and g_loc / g_glob: the Wiener
output when its SURE is below the default's.
Usage: wiener_study.py DIR CACHE"""
import glob, json, os, sys
import numpy as np
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import surelet_study as S
from pick_study import err

AVG = int(os.environ.get('AVG', '2'))

def main(d, cache):
    for pf in sorted(glob.glob(d + '/*-f.npz')):
        zf = dict(np.load(pf))
        mesh, rho = os.path.basename(pf).rsplit('-', 2)[:2]
        q = np.load('%s/%s-%s-dd.npz' % (cache, mesh, rho))
        Dd, dd = q['Dd'], float(q['dd'])
        X, F, s, n0, w = zf['X'], zf['F'], float(zf['s']), zf['n0'], zf['w']
        n, P = len(X), X + zf['Dd']
        Z = np.where(np.random.default_rng(7).random((n, 16)) < 0.5, -1.0, 1.0)
        Wc = S.cotan(P, F, n)
        ks = [1, 2, 4, 8, 16, 32, 64, 128]
        itx = S.pass_iterates(X, Wc, ks, Z)
        itp = S.pass_iterates(P, Wc, ks, Z[:, :0])
        A = S.adjacency(F, n) + S.sp.identity(n)
        A = S.sp.diags(1 / np.asarray(A.sum(1)).ravel()) @ A
        px, pp, pz = X, P, Z
        Dl, Dg, dvl, dvg = np.zeros_like(X), np.zeros_like(X), 0.0, 0.0
        for k in ks:
            BX, BZ, BP = px - itx[k][0], pz - itx[k][1], pp - itp[k][0]
            e = np.sum(n0 * BP, 1) ** 2
            for _ in range(AVG):
                e = A @ e
            sig2 = s * s * np.mean(BZ ** 2, 1)
            dg = np.mean(Z * BZ, 1)
            gl = e / (e + sig2)
            gg = np.sum(w * e) / (np.sum(w * e) + np.sum(w * sig2))
            Dl -= (1 - gl)[:, None] * BX
            Dg -= (1 - gg) * BX
            dvl -= np.sum(w * (1 - gl) * dg)
            dvg -= (1 - gg) * np.sum(w * dg)
            px, pz, pp = itx[k][0], itx[k][1], itp[k][0]
        sure = lambda D, dv: float(np.sum(w * np.sum(n0 * D, 1) ** 2) + 2 * s * s * dv) / (s * s * w.sum())
        res = {'mesh': mesh, 'rho': float(rho), 'default': S.err(X + Dd, zf['C'], zf['Acl']) / zf['e_in'],
               'wien_loc': err(zf, Dl), 'wien_glob': err(zf, Dg), 'sure_loc': sure(Dl, dvl),
               'sure_glob': sure(Dg, dvg), 'sure_def': sure(Dd, dd)}
        res['g_loc'] = res['wien_loc'] if res['sure_loc'] < res['sure_def'] else res['default']
        res['g_glob'] = res['wien_glob'] if res['sure_glob'] < res['sure_def'] else res['default']
        print(json.dumps({k: (round(v, 4) if isinstance(v, float) else v) for k, v in res.items()}), flush=True)

if __name__ == '__main__':
    main(sys.argv[1], sys.argv[2])
