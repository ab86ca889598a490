#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""adaptive_study.py - issue 31, Gaussian noise along the normals on organic meshes:
spatially adaptive stopping (a step count per region, picked by local SURE) as a way past
the linear filters' ceiling, its oracle and its blind version. A lab study, not the product.

Per mesh and level rho (noise as surelet_study.py: sigma = rho h along the clean
area-weighted vertex normals, numpy seed 1; its helpers are imported from there):
  * default: the product's default request (MCF smooth, nothing set), error over the input's;
  * taubin: lambda|mu = 0.5|-0.53 passes with cotan weights of the current mesh recomputed
    every half pass (negative ones clamped to 0), full 3D moves, at the pass count (1..300)
    least in error against the clean mesh: the numpy stand-in for make quality's
    taubin_best on this draw (the scheme's weights are not clamped: a few % apart);
  * the product's implicit step (I + N^2)^-k on the uniform graph, k in KS, each iterate's
    displacement D_k taken along the normals of X + D_k (as the product's output);
    per-vertex SURE along the noisy normals n0: w (n0.D_k)^2 + 2 s^2 diag(T_k - I), the
    diagonal estimated from 6 Rademacher probes carried through the same solves
    (Hutchinson per vertex; s the true level);
      global_sure / global_orc: one k for the mesh, least SURE / least error (oracle);
      P<m>_sure / P<m>_orc: one k per region of about m vertices (k-means on the noisy
      positions), least summed SURE / least summed error in the region;
      P<m>_orc+def: the oracle choosing per region among the iterates AND the default's output.
  * with --check on a mesh of <= 1000 vertices: the probes' per-vertex diagonal summed over
    the regions against the exact diagonal of T_k (dense inverse), printed.
All errors: area-weighted RMS distance to the clean vertex over the input's (clean areas).
Usage: adaptive_study.py MESH[,..] RHO[,..] MCF [SIZES] [--raw DIR]
"""
import json, os, subprocess, sys
import numpy as np
import scipy.sparse as sp
from scipy.cluster.vq import kmeans2
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import surelet_study as S

KS = [1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48]

def taubin_oracle(X, F, C, Acl, e_in, maxk=300):
    n, Y, best, bk = len(X), X.copy(), np.inf, 0
    for k in range(1, maxk + 1):
        for lam in (0.5, -0.53):
            W = S.cotan(Y, F, n)
            d = np.asarray(W.sum(1)).ravel()
            Y = Y + lam * ((W @ Y) / np.maximum(d, 1e-300)[:, None] - Y)
        e = S.err(Y, C, Acl) / e_in
        if e < best:
            best, bk, bY = e, k, Y.copy()
        elif e > 1.05 * best and k >= 2 * bk + 5:
            break
    return best, bk, bY

def write_raw(p, V, F):
    with open(p, 'wb') as f:
        f.write(np.array([len(V), len(F)], dtype=np.int32).tobytes())
        f.write(np.ascontiguousarray(V, dtype=np.float64).tobytes())
        f.write(np.ascontiguousarray(F, dtype=np.int32).tobytes())

def case(name, rho, mcf, sizes, raw=None, check=False):
    C, F, n, Nc, Acl, X, e_in, s = S.noisy_case(name, rho)
    res = {'mesh': name, 'rho': rho, 'n': n}
    S.write_obj('/tmp/adaptive_in.obj', X, F)
    subprocess.run([mcf, 'smooth', '--quiet', '/tmp/adaptive_in.obj', '/tmp/adaptive_out.obj'], check=True)
    Ydef = S.read_obj('/tmp/adaptive_out.obj')[0]
    res['default'] = S.err(Ydef, C, Acl) / e_in
    res['taubin'], res['taubin_k'], Ytb = taubin_oracle(X, F, C, Acl, e_in)
    n0, w = S.vnormals(X, F), S.areas(X, F)
    w = w / w.mean()
    Z = np.where(np.random.default_rng(7).random((n, 6)) < 0.5, -1.0, 1.0)
    A = S.adjacency(F, n)
    its = S.implicit_iterates(X, A, KS, Z)
    Ds = []
    for k in KS:  # the displacement along the normals of X + D (the product's output rule)
        D = its[k][0] - X
        ny = S.vnormals(X + D, F)
        Ds.append(ny * np.sum(ny * D, 1)[:, None])
    Ds = np.array(Ds)
    R = np.einsum('kni,ni->kn', np.array([its[k][0] - X for k in KS]), n0)
    dg = np.array([np.mean(Z * its[k][1], 1) - 1 for k in KS])
    sure_v = w[None, :] * (R ** 2 + 2 * s * s * dg)
    orc_v = Acl[None, :] * np.sum((X[None] + Ds - C[None]) ** 2, 2)
    orc_def = Acl * np.sum((Ydef - C) ** 2, 1)

    def out(kidx):
        return S.err(X + Ds[kidx, np.arange(n)], C, Acl) / e_in
    g_s, g_o = int(np.argmin(sure_v.sum(1))), int(np.argmin(orc_v.sum(1)))
    res['global_sure'], res['k_sure'] = out(np.full(n, g_s)), KS[g_s]
    res['global_orc'], res['k_orc'] = out(np.full(n, g_o)), KS[g_o]
    for P in sizes:
        m = max(1, n // P)
        _, lab = kmeans2(X, m, seed=3, minit='++')
        M = sp.csr_matrix((np.ones(n), (lab, np.arange(n))), shape=(m, n))
        ks_s = np.argmin((M @ sure_v.T).T, 0)[lab]
        ks_o = np.argmin((M @ orc_v.T).T, 0)[lab]
        res['P%d_sure' % P], res['P%d_orc' % P] = out(ks_s), out(ks_o)
        both = np.vstack([orc_v, orc_def[None]])
        pick = np.argmin((M @ both.T).T, 0)[lab]
        Yb = np.where((pick == len(KS))[:, None], Ydef, X + Ds[np.minimum(pick, len(KS) - 1), np.arange(n)])
        res['P%d_orc+def' % P] = S.err(Yb, C, Acl) / e_in
        if check and n <= 1000:
            sq = np.sqrt(np.asarray(A.sum(1)).ravel())
            Nn = np.eye(n) - (A.toarray() / sq[:, None]) / sq[None, :]
            Ti = np.linalg.inv(np.eye(n) + Nn @ Nn)
            rel = []
            for j, k in enumerate(KS):
                Tk = np.linalg.matrix_power(Ti, k)
                ex, est = M @ (w * (np.diag(Tk) - 1)), M @ (w * dg[j])
                rel.append(float(np.max(np.abs(est - ex) / np.abs(ex))))
            res['P%d_check_maxrel' % P] = max(rel)
    out_r = {k: (round(v, 4) if isinstance(v, float) else v) for k, v in res.items()}
    for k in list(res):
        if isinstance(res[k], float) and k not in ('rho', 'taubin') and not k.endswith('maxrel'):
            out_r[k + '/tb'] = round(res[k] / res['taubin'], 4)
    print(json.dumps(out_r), flush=True)
    if raw:
        best = min(sizes, key=lambda P: res['P%d_sure' % P])
        tag = '%s/%s-%g' % (raw, name.split('.')[0], rho)
        write_raw(tag + '-clean.raw', C, F); write_raw(tag + '-noisy.raw', X, F)
        write_raw(tag + '-default.raw', Ydef, F); write_raw(tag + '-taubin.raw', Ytb, F)
        m = max(1, n // best)
        _, lab = kmeans2(X, m, seed=3, minit='++')
        M = sp.csr_matrix((np.ones(n), (lab, np.arange(n))), shape=(m, n))
        ks_o = np.argmin((M @ orc_v.T).T, 0)[lab]
        write_raw(tag + '-adaptive_orc.raw', X + Ds[ks_o, np.arange(n)], F)

if __name__ == '__main__':
    a = [x for x in sys.argv[1:] if not x.startswith('--')]
    raw = sys.argv[sys.argv.index('--raw') + 1] if '--raw' in sys.argv else None
    if raw:
        a.remove(raw)
    sizes = [int(x) for x in (a[3] if len(a) > 3 else '30,100,300').split(',')]
    for mname in a[0].split(','):
        for r in a[1].split(','):
            case(mname, float(r), a[2], sizes, raw, '--check' in sys.argv)
