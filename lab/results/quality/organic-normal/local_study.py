#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""local_study.py - issue 31, organic normal noise: BM3D-style two-stage shrinkage in LOCAL
(per-patch) bases on the mesh, against the same study's global eigenbasis oracle. A lab study,
not the product.

The signal: heights over a smooth base B = T_K X (the product's implicit step (I + N^2)^-1 on
the uniform graph, K times; surelet_study.implicit_iterates), along B's vertex normals nB:
    h = nB . (X - B) = g + e,   g = nB . (C - B) (the clean detail),  e ~ s (nB . Nc) xi.
An estimate g' of g gives the output X - nB (h - g') (X moved along nB only; with g' = g its
error is the noise's part across nB, under 1% of the input's here).
Bases: for every vertex i the patch of its R-ring (R = 2: ~19 vertices, 3: ~37 on a regular
mesh); the orthonormal eigenvectors U_i of the patch's combinatorial graph Laplacian (a local
graph Fourier basis, the mesh's analogue of BM3D's local DCT). Overlapping patches aggregated per
vertex with BM3D's weights.
  stage 1 (hard): coefficients a = U_i^T h_i kept where |a| > LAM s (LAM = 2.7, BM3D's), zero
                  elsewhere; weight 1 / max(1, kept) per patch;
  stage 2 (wien): the stage-1 estimate as pilot p, b = U_i^T p_i, gains b^2 / (b^2 + s^2) on a,
                  weight 1 / sum gains^2 per patch (BM3D's 1 / ||gains||^2);
  loc_orc:        stage 2 with the clean g as its pilot (the ideal local Wiener filter: an
                  oracle, the best any pilot could make stage 2 do);
  glob_orc:       the same ideal Wiener in the whole graph's eigenbasis (dense; n <= 6000):
                  the oracle of every filter diagonal in that basis;
  base:           g' = 0 (B itself, moved as above);
  above:          the share of the clean detail's local coefficients whose square exceeds the
                  noise's variance (how sparse g is in these bases: what thresholding can keep).
s: the true level (the product reads it blind within 0.98-1.18 of it). Printed: error
(area-weighted RMS against the clean mesh) over the input's, for the default request
(build/mcf smooth) and each of the above; divided by make quality's stored Taubin oracle
(issue31-before's taubin_best / input; the bar's definition) in the *_t fields.
Usage: local_study.py MESH[,MESH..] RHO[,RHO..] MCF   (env: K=32, R=2, LAM=2.7)"""
import csv, json, os, subprocess, sys
import numpy as np
import scipy.sparse as sp
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import surelet_study as S

K = int(os.environ.get('K', '32'))
R = int(os.environ.get('R', '2'))
LAM = float(os.environ.get('LAM', '2.7'))
NZ = int(os.environ.get('NZ', '0'))
HERE = os.path.dirname(os.path.abspath(__file__))

def taubin_anchor():
    t = {}
    rows = list(csv.reader(open(HERE + '/../issue31-before/quality.csv')))
    head = rows[0]
    for r in rows[1:]:
        if r[0] == 'mesh':
            continue
        d = dict(zip(head, r))
        if d['model'] == 'normal' and d['method'] == 'taubin_best' and d['seed'] == '1':
            t[(d['mesh'], float(d['rho']))] = float(d['ratio'])
    for f in ('baseline-small.csv', 'baseline-large.csv'):
        for r in csv.DictReader(open(HERE + '/' + f)):
            if r.get('mesh') != 'mesh' and r.get('method') == 'taubin_best' and r.get('model') == 'normal':
                t.setdefault((r['mesh'], float(r['rho'])), float(r['ratio']))
    return t

def patches(A, n):
    """Padded patch index array P (n, M), -1 padding, and the patches' Laplacians (n, M, M):
    the R-ring of each vertex; padding rows get distinct huge diagonals (their eigenvectors are
    unit vectors, their coefficients of a zero-padded signal exactly 0)."""
    Rr = sp.identity(n, format='csr')
    Ai = (A + sp.identity(n)).tocsr()
    for _ in range(R):
        Rr = (Rr @ Ai).tocsr()
        Rr.data[:] = 1
    sizes = np.diff(Rr.indptr)
    M = sizes.max()
    P = -np.ones((n, M), dtype=np.int64)
    for i in range(n):
        P[i, :sizes[i]] = Rr.indices[Rr.indptr[i]:Rr.indptr[i + 1]]
    mask = P >= 0
    Q = np.where(mask, P, 0)
    L = np.zeros((n, M, M))
    Ad = A.tocsr()
    for i in range(n):
        idx = P[i, :sizes[i]]
        L[i, :sizes[i], :sizes[i]] = -Ad[idx][:, idx].toarray()
    deg = -L.sum(2)
    ar = np.arange(M)
    L[:, ar, ar] = deg
    pad = ~mask
    L[:, ar, ar] += pad * (1e6 + ar)[None, :]
    return Q, mask, L

def implicit_T(Y, A):
    """T_K Y, T = D^-1/2 (I + N^2)^-1 D^1/2 (surelet_study.implicit_iterates' step, here applied
    to every column, probes included)."""
    sq = np.sqrt(np.asarray(A.sum(1)).ravel())
    N = sp.identity(len(Y)) - sp.diags(1 / sq) @ A @ sp.diags(1 / sq)
    lu = S.spl.splu((sp.identity(len(Y)) + N @ N).tocsc())
    y = Y * sq[:, None]
    for _ in range(K):
        y = lu.solve(y)
    return y / sq[:, None]

def aggregate(n, Q, mask, est, wt):
    num, den = np.zeros(n), np.zeros(n)
    np.add.at(num, Q[mask], (wt[:, None] * est)[mask])
    np.add.at(den, Q[mask], np.broadcast_to(wt[:, None], est.shape)[mask])
    return num / den

def case(name, rho, mcf, anchor):
    C, F, n, Nc, Acl, X, e_in, s = S.noisy_case(name, rho)
    S.write_obj('/tmp/h3_local_in.obj', X, F)
    subprocess.run([mcf, 'smooth', '--quiet', '/tmp/h3_local_in.obj', '/tmp/h3_local_out.obj'], check=True)
    res = {'default': S.err(S.read_obj('/tmp/h3_local_out.obj')[0], C, Acl) / e_in}
    A = S.adjacency(F, n)
    Z = np.random.default_rng(11).standard_normal((n, NZ))
    BT = implicit_T(np.hstack([X, Z]), A)
    B, TZ = BT[:, :3], BT[:, 3:]
    nB = S.vnormals(B, F)
    h, g = np.sum(nB * (X - B), 1), np.sum(nB * (C - B), 1)
    out = lambda gp: S.err(X - nB * (h - gp)[:, None], C, Acl) / e_in
    res['base'], res['g_exact'] = out(np.zeros(n)), out(g)
    Q, mask, L = patches(A, n)
    _, U = np.linalg.eigh(L)                      # (n, M, M), columns = basis vectors
    a = np.einsum('nmk,nm->nk', U, h[Q] * mask)
    # the noise's variance per coefficient: s^2 where h's noise is white (K large), else from
    # NZ Gaussian probes through I - T_K (h's noise is (I - T_K) e: less at low local frequency)
    az = np.einsum('nmk,nmz->nkz', U, (Z - TZ)[Q] * mask[:, :, None])
    v = s * s * np.mean(az * az, 2) if NZ else s * s * np.ones_like(a)
    keep = a * a > LAM * LAM * v
    est1 = np.einsum('nmk,nk->nm', U, a * keep)
    g1 = aggregate(n, Q, mask, est1, 1 / np.maximum(1, keep.sum(1)))
    res['hard'] = out(g1)

    def wien(pilot):
        b = np.einsum('nmk,nm->nk', U, pilot[Q] * mask)
        gam = b * b / np.maximum(b * b + v, 1e-300)   # padding: b = v = 0, gain 0
        est = np.einsum('nmk,nk->nm', U, a * gam)
        return aggregate(n, Q, mask, est, 1 / np.maximum(np.sum(gam * gam, 1), 1e-3))
    g2 = wien(g1)
    res['wien'] = out(g2)
    res['wien2'] = out(wien(g2))                  # a second pass, the stage-2 output as pilot
    res['loc_orc'] = out(wien(g))
    cl = np.einsum('nmk,nm->nk', U, g[Q] * mask)   # the clean detail's local coefficients
    res['above'] = float(np.sum((cl * cl > v) & mask) / mask.sum())   # share above the noise
    if n <= 6000:
        Lg = sp.diags(np.asarray(A.sum(1)).ravel()) - A
        _, V = np.linalg.eigh(Lg.toarray())
        ag, cg, zg = V.T @ h, V.T @ g, V.T @ (Z - TZ)
        vg = s * s * np.mean(zg * zg, 1) if NZ else s * s
        res['glob_orc'] = out(V @ (ag * cg * cg / (cg * cg + vg)))
        ap = V.T @ g1                             # the global empirical Wiener, stage-1 pilot
        res['glob_wien'] = out(V @ (ag * ap * ap / (ap * ap + vg)))
    t = anchor.get((name, rho))
    row = {'mesh': name, 'rho': rho, 'K': K, 'R': R, 'LAM': LAM, 'NZ': NZ, 'n': n, 'M': int(mask.shape[1])}
    row.update({k: round(v, 4) for k, v in res.items()})
    if t:
        row.update({k + '_t': round(v / t, 4) for k, v in res.items() if k != 'above'})
    print(json.dumps(row), flush=True)

if __name__ == '__main__':
    anc = taubin_anchor()
    for m in sys.argv[1].split(','):
        for r in sys.argv[2].split(','):
            case(m, float(r), sys.argv[3], anc)
