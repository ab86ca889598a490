#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""nonlin_let.py - issue 31, organic normal noise: SURE-LET with POINTWISE NON-LINEAR
shrinkage of multiscale bands (Blu & Luisier 2007's form, on the mesh's own diffusion
frame), its oracle and its blind version. A lab study, not the product.

Noise as surelet_study.py (sigma = s = rho h along the clean vertex normals, numpy seed 1).
Family FAM of linear smoothers T_k applied to the noisy positions X (k in KS):
  f  the product's implicit step (I + N^2)^-k on the uniform graph,
  c  lambda|mu passes (0.5, -0.53) with cotan weights of a PILOT held fixed (the product's
     default output), so the operator is linear in the noise and the probes' traces are
     SURE's divergence.
Bands B_0 = I - T_k1, B_j = T_kj - T_kj+1, low-pass L = T_klast; per vertex the band height
beta_j = n0 . (B_j X) (n0: the noisy mesh's normals). The displacement
    D = a_L (L - I) X + sum_j [a_j + c_j phi_j] B_j X,   phi_j = exp(-beta_j^2 / (2 (tau sigma_j)^2))
(a_j: a linear gain per band; c_j: more gain where the band's height is small against its
noise sigma_j, i.e. a soft threshold; sigma_j = s * RMS of B_j z over Rademacher probes z).
SURE in heights along n0 (w: noisy vertex areas, mean 1) is quadratic in (a, c):
    G theta = -s^2 div,  div of term (phi beta) = sum_i w_i phi_i (1 - beta_i^2/(tau sigma_j)^2) (B_j)_ii,
the diagonal by NPROBE Rademacher probes carried through the same operators (Hutchinson,
per vertex, summed). Columns printed (error over the input's, clean vertex areas; the output
moves along the normals of X + D as the product's does):
  default     the product's default request (mcf smooth);
  lin_sure    the linear part alone (c = 0) by SURE; lin_orc its weights fitted to the clean mesh;
  nl_sure     the full non-linear LET by SURE (blind, true s);  nl_orc its clean-fitted oracle;
  nl_guard    nl_sure when its SURE beats lin_sure's by more than 2 s^2 per extra weight
              (the guard's stand-in: the default is within a few % of lin_sure), else default;
  def+nl_orc  the default's displacement added to the non-linear columns, oracle (what a
              correction of the default could at best reach).
SEED=N draws the noise with seed N (default 1). DUMP=DIR saves each case's columns, and dgv, each
column's per-vertex divergence (divs = sum of w * dgv), for pilot_sure.py's other weights.
Usage: nonlin_let.py MESH[,..] RHO[,..] MCF [FAM]"""
import json, os, subprocess, sys
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spl
os.makedirs('/tmp/s31o', exist_ok=True)  # the scripts' scratch files
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import surelet_study as S

NPROBE = int(os.environ.get('NPROBE', '16'))
TAUS = [float(t) for t in os.environ.get('TAUS', '1.5').split(',')]

def mcf_default(mcf, X, F, tag):
    S.write_obj('/tmp/s31o/%s_in.obj' % tag, X, F)
    subprocess.run([mcf, 'smooth', '--quiet', '/tmp/s31o/%s_in.obj' % tag, '/tmp/s31o/%s_out.obj' % tag], check=True)
    return S.read_obj('/tmp/s31o/%s_out.obj' % tag)[0]

def family(fam, X, F, Z, pilot):
    n = len(X)
    if fam == 'f':
        return S.implicit_iterates(X, S.adjacency(F, n), [1, 2, 4, 8, 16, 32], Z), [1, 2, 4, 8, 16, 32]
    ks = [1, 2, 4, 8, 16, 32, 64, 128]
    return S.pass_iterates(X, S.cotan(pilot, F, n), ks, Z), ks

def case(name, rho, mcf, fam):
    C, F = S.read_obj(S.MESHES + name)
    n, E = len(C), S.edges(F)
    h = np.linalg.norm(C[E[:, 0]] - C[E[:, 1]], axis=1).mean()
    Nc, Acl = S.vnormals(C, F), S.areas(C, F)
    X = C + rho * h * np.random.default_rng(int(os.environ.get('SEED', '1'))).standard_normal(n)[:, None] * Nc
    e_in, s = S.err(X, C, Acl), rho * h
    tag = '%s-%g-%s' % (name.split('.')[0], rho, fam)
    Ydef = mcf_default(mcf, X, F, tag)
    res = {'mesh': name, 'rho': rho, 'fam': fam, 'n': n, 'default': S.err(Ydef, C, Acl) / e_in}
    n0, w = S.vnormals(X, F), S.areas(X, F)
    w = w / w.mean()
    Z = np.where(np.random.default_rng(7).random((n, NPROBE)) < 0.5, -1.0, 1.0)
    its, ks = family(fam, X, F, Z, Ydef)
    prevX, prevZ, cols, divs, kinds, dgv = X, Z, [], [], [], []
    for k in ks:  # bands, their heights, per-vertex diagonal estimates
        TX, TZ = its[k]
        BX, BZ = prevX - TX, prevZ - TZ
        beta = np.sum(n0 * BX, 1)
        dg = np.mean(Z * BZ, 1)                      # (B_j)_ii, Hutchinson
        sig = s * np.sqrt(np.mean(BZ ** 2))          # the band height's noise level
        cols.append(BX); divs.append(np.sum(w * dg)); kinds.append('lin'); dgv.append(dg)
        for tau in TAUS:
            t2 = (tau * sig) ** 2
            phi = np.exp(-beta ** 2 / (2 * t2))
            cols.append(phi[:, None] * BX); divs.append(np.sum(w * phi * (1 - beta ** 2 / t2) * dg)); kinds.append('nl')
            dgv.append(phi * (1 - beta ** 2 / t2) * dg)
        prevX, prevZ = TX, TZ
    cols.append(prevX - X); divs.append(np.sum(w * (np.mean(Z * prevZ, 1) - 1))); kinds.append('lin')
    dgv.append(np.mean(Z * prevZ, 1) - 1)
    cols, divs = np.array(cols), np.array(divs)
    R = np.einsum('kni,ni->kn', cols, n0)
    Dd = Ydef - X

    def out(D):
        ny = S.vnormals(X + D, F)
        return X + ny * np.sum(ny * D, 1)[:, None]

    def e(Y):
        return S.err(Y, C, Acl) / e_in

    def sure_fit(idx):
        Ri = R[idx]
        G = (Ri * w[None]) @ Ri.T
        th = np.linalg.solve(G + 1e-12 * np.trace(G) * np.eye(len(idx)), -s * s * divs[idx])
        sure = float(th @ G @ th + 2 * s * s * th @ divs[idx])   # minus the constant s^2 sum w
        return np.tensordot(th, cols[idx], 1), sure

    def orc_fit(M):  # the weights least in error along n0 against the clean heights (an oracle)
        M = np.array(M)
        sw = np.sqrt(Acl)
        A = np.einsum('kni,ni->nk', M, n0) * sw[:, None]
        th = np.linalg.lstsq(A, np.sum((C - X) * n0, 1) * sw, rcond=None)[0]
        return np.tensordot(th, M, 1)
    lin = [i for i, k in enumerate(kinds) if k == 'lin']
    alli = list(range(len(kinds)))
    Dl, sl = sure_fit(lin)
    Dn, sn = sure_fit(alli)
    res['lin_sure'], res['nl_sure'] = e(out(Dl)), e(out(Dn))
    res['lin_orc'], res['nl_orc'] = e(out(orc_fit(cols[lin]))), e(out(orc_fit(cols)))
    res['def+nl_orc'] = e(out(orc_fit(list(cols) + [Dd])))
    res['sure_gain'] = (sl - sn) / (s * s * w.sum())                 # per vertex, in s^2
    take = sl - sn > 2 * s * s * (len(alli) - len(lin))
    res['nl_guard'] = res['nl_sure'] if take else res['default']
    res['took'] = bool(take)
    if os.environ.get('DUMP'):  # the columns, for cross-mesh weights (crossfit.py)
        np.savez_compressed('%s/%s.npz' % (os.environ['DUMP'], tag), cols=cols, kinds=np.array(kinds), X=X, C=C,
                            F=F, n0=n0, Acl=Acl, Dd=Dd, e_in=e_in, divs=divs, w=w, s=s, dgv=np.array(dgv))
    print(json.dumps({k: (round(v, 4) if isinstance(v, float) else v) for k, v in res.items()}), flush=True)

if __name__ == '__main__':
    for m in sys.argv[1].split(','):
        for r in sys.argv[2].split(','):
            case(m, float(r), sys.argv[3], sys.argv[4] if len(sys.argv) > 4 else 'f')
