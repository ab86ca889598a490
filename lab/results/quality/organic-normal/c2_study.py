#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""c2_study.py - issue 31, organic normal noise: is the pilot-cotan family's SURE wrong at 0.5 h
because the pilot depends on the noise? A lab study, not the product.

Noise as surelet_study.py (sigma = s = rho h along the clean vertex normals, numpy seed 1).
Columns D_k = T_k X - X:
  f   the implicit step (I + N^2)^-k on the uniform graph, k = 1..32 (linear: the divergence
      of each height r_k = n0.D_k is the trace of T_k - I, 16 Rademacher probes, Hutchinson);
  c2  lambda|mu passes (0.5, -0.53), k = 1..128, with the cotan weights (negative ones clamped)
      of a PILOT that is itself a smooth function of X: the implicit step's 8th iterate
      (PILOT_K). Its divergence two ways: 'lin' with the pilot held fixed (Hutchinson through
      the passes, 16 probes: what pick_study.py's c did), 'mc' by Monte-Carlo finite differences
      of the whole map, pilot included (Ramani, Blu, Unser 2008: b.(r(X + e b n0) - r(X)) / e,
      e = 0.01 s, NMC Rademacher probes b).
SURE-LET along n0 (w: noisy vertex areas, mean 1; true s). Printed (error over the input's,
clean areas; outputs along the normals of X + D): default (mcf smooth), let_f, let_c2_lin,
let_c2_mc, orc_c2, let_fc2_mc (both families' columns, 14 weights), orc_fc2, and pick: the
default unless let_fc2_mc's penalised SURE (+2 s^2 per weight) is below let_f's (the default's
stand-in).
Usage: c2_study.py MESH[,..] RHO[,..] MCF"""
import json, os, subprocess, sys
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spl
os.makedirs('/tmp/s31o', exist_ok=True)  # the scripts' scratch files
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import surelet_study as S

NMC = int(os.environ.get('NMC', '8'))
PILOT_K = int(os.environ.get('PILOT_K', '8'))
KF, KC = [1, 2, 4, 8, 16, 32], [1, 2, 4, 8, 16, 32, 64, 128]

class Implicit:
    def __init__(self, F, n):
        A = S.adjacency(F, n)
        self.sq = np.sqrt(np.asarray(A.sum(1)).ravel())
        N = sp.identity(n) - sp.diags(1 / self.sq) @ A @ sp.diags(1 / self.sq)
        self.lu = spl.splu((sp.identity(n) + N @ N).tocsc())

    def iterates(self, Y, ks):
        y, out = Y * self.sq[:, None], {}
        for k in range(1, max(ks) + 1):
            y = self.lu.solve(y)
            if k in ks:
                out[k] = y / self.sq[:, None]
        return out

def c2_cols(X, F, imp, Z=None):
    pilot = imp.iterates(X, [PILOT_K])[PILOT_K]
    its = S.pass_iterates(X, S.cotan(pilot, F, len(X)), KC, Z if Z is not None else np.zeros((len(X), 0)))
    return np.array([its[k][0] - X for k in KC]), its

def case(name, rho, mcf):
    C, F, n, Nc, Acl, X, e_in, s = S.noisy_case(name, rho)
    S.write_obj('/tmp/s31o/c2_in.obj', X, F)
    subprocess.run([mcf, 'smooth', '--quiet', '/tmp/s31o/c2_in.obj', '/tmp/s31o/c2_out.obj'], check=True)
    Ydef = S.read_obj('/tmp/s31o/c2_out.obj')[0]
    n0, w = S.vnormals(X, F), S.areas(X, F)
    w = w / w.mean()
    imp = Implicit(F, n)
    Z = np.where(np.random.default_rng(7).random((n, 16)) < 0.5, -1.0, 1.0)
    # f: linear, Hutchinson through the solves
    y = np.hstack([X * imp.sq[:, None], Z])  # T = D^-1/2 R D^1/2 has R's diagonal: probes through R
    Df, divf = [], []
    for k in range(1, max(KF) + 1):
        y = imp.lu.solve(y)
        if k in KF:
            Df.append(y[:, :3] / imp.sq[:, None] - X)
            divf.append(np.sum(w * (np.mean(Z * y[:, 3:], 1) - 1)))
    Df, divf = np.array(Df), np.array(divf)
    # c2: columns, the fixed-pilot traces, the whole map's Monte-Carlo divergence
    Dc, its = c2_cols(X, F, imp, Z)
    divc_lin = np.array([np.sum(w * (np.mean(Z * its[k][1], 1) - 1)) for k in KC])
    rc = np.einsum('kni,ni->kn', Dc, n0)
    rng, eps, divc_mc = np.random.default_rng(11), 0.01 * s, np.zeros(len(KC))
    for _ in range(NMC):
        b = np.where(rng.random(n) < 0.5, -1.0, 1.0)
        Xp = X + eps * b[:, None] * n0
        rp = np.einsum('kni,ni->kn', c2_cols(Xp, F, imp)[0], n0)
        divc_mc += np.sum(w * b * (rp - rc), 1) / eps / NMC

    def out(D):
        ny = S.vnormals(X + D, F)
        return S.err(X + ny * np.sum(ny * D, 1)[:, None], C, Acl) / e_in

    def let(cols, divs):
        R = np.einsum('kni,ni->kn', cols, n0)
        G = (R * w[None]) @ R.T
        th = np.linalg.solve(G + 1e-12 * np.trace(G) * np.eye(len(cols)), -s * s * divs)
        return np.tensordot(th, cols, 1), (float(th @ G @ th + 2 * s * s * th @ divs) + 2 * s * s * len(cols)) / (s * s * w.sum())

    def orc(cols):
        sw = np.sqrt(Acl)
        A = np.einsum('kni,ni->nk', cols, n0) * sw[:, None]
        th = np.linalg.lstsq(A, np.sum((C - X) * n0, 1) * sw, rcond=None)[0]
        return np.tensordot(th, cols, 1)
    res = {'mesh': name, 'rho': rho, 'n': n, 'default': S.err(Ydef, C, Acl) / e_in}
    D, sf = let(Df, divf); res['let_f'] = out(D)
    D, _ = let(Dc, divc_lin); res['let_c2_lin'] = out(D)
    D, _ = let(Dc, divc_mc); res['let_c2_mc'] = out(D)
    res['orc_c2'] = out(orc(Dc))
    both = np.concatenate([Df, Dc])
    D, sfc = let(both, np.concatenate([divf, divc_mc])); res['let_fc2_mc'] = out(D)
    res['orc_fc2'] = out(orc(both))
    res['pick'] = res['let_fc2_mc'] if sfc < sf else res['default']
    res['sure_f'], res['sure_fc2'] = sf, sfc
    res['divc_lin/mc'] = [round(a / b, 4) for a, b in zip(divc_lin, divc_mc)]
    print(json.dumps({k: (round(v, 4) if isinstance(v, float) else v) for k, v in res.items()}), flush=True)

if __name__ == '__main__':
    for m in sys.argv[1].split(','):
        for r in sys.argv[2].split(','):
            case(m, float(r), sys.argv[3])
