#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""estimate_check.py - per step, how well do the adaptive error estimates of
ros2 and richardson track the true local error (issue 30)?

An independent numpy/scipy implementation of docs/MATH.md's updates (cotan L
without mollification and barycentric lumped M on the unit-area mesh, free
boundary: a closed, well-shaped mesh such as spot.obj): the mesh runs in
the given steps to T = strength 0.5 (0.25 mean edge^2). Per step, the true
local error is the step against the same start state advanced by 64
richardson substeps (their own error ~1/64^2 of the step's, second order),
in the M-norm of MATH.md. Printed per step: Milne's device with the
scheme's error constant (what core/mcf_steps.c computes from the third
step on), and step doubling of the scheme itself (two h/2 steps against one
h, divided by 3 as for order 2) against the true error of the two halves.

  /usr/bin/python3 lab/estimate_check.py MESH ros2|richardson equal|geo

equal: 12 equal steps; geo: 14 steps growing by 1.25. A few minutes on
spot (2,930 vertices).
"""
import sys, numpy as np, scipy.sparse as sp, scipy.sparse.linalg as sla

def load_obj(p):
    V, F = [], []
    for l in open(p):
        t = l.split()
        if not t: continue
        if t[0] == 'v': V.append([float(x) for x in t[1:4]])
        elif t[0] == 'f':
            idx = [int(x.split('/')[0]) for x in t[1:]]
            idx = [i - 1 if i > 0 else len(V) + i for i in idx]
            for k in range(1, len(idx) - 1): F.append([idx[0], idx[k], idx[k + 1]])
    return np.array(V), np.array(F)

def ops(X, F):
    n = len(X); I, J, W = [], [], []
    area = np.zeros(len(F))
    for k in range(3):
        i, j, o = F[:, (k + 1) % 3], F[:, (k + 2) % 3], F[:, k]
        a, b = X[i] - X[o], X[j] - X[o]
        cr = np.cross(a, b); s = np.linalg.norm(cr, axis=1)
        cot = (a * b).sum(1) / s
        I += [i, j, i, j]; J += [j, i, i, j]; W += [-cot / 2, -cot / 2, cot / 2, cot / 2]
        area = s / 2
    L = sp.csc_matrix((np.concatenate(W), (np.concatenate(I), np.concatenate(J))), shape=(n, n))
    m = np.zeros(n)
    for k in range(3): np.add.at(m, F[:, k], area / 3)
    return L, m

def be(X, F, h):  # desbrun: (M + h L) X+ = M X
    L, m = ops(X, F)
    return sla.spsolve((sp.diags(m) + h * L).tocsc(), m[:, None] * X)

def richardson(X, F, h):
    return 2 * be(be(X, F, h / 2), F, h / 2) - be(X, F, h)

def ros2(X, F, h):
    g = 1 + 1 / np.sqrt(2)
    L, m = ops(X, F)
    lu = sla.splu((sp.diags(m) + g * h * L).tocsc())
    K1 = lu.solve(-(L @ X))
    Y = X + h * K1
    LY, mY = ops(Y, F)
    K2 = lu.solve(-(m / mY)[:, None] * (LY @ Y) - 2 * m[:, None] * K1)
    return X + h * (1.5 * K1 + 0.5 * K2)

def mnorm(D, m): return np.sqrt((m[:, None] * D * D).sum() / m.sum())

C = {'ros2': 1.37377344785321, 'richardson': 1 / 6}
step = {'ros2': ros2, 'richardson': richardson}

def run(mesh, scheme, hs):
    X, F = load_obj(mesh)
    _, m = ops(X, F); a = m.sum()
    X = (X - (m[:, None] * X).sum(0) / a) / np.sqrt(a)
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]); E.sort(1); E = np.unique(E, axis=0)
    hbar = np.linalg.norm(X[E[:, 0]] - X[E[:, 1]], axis=1).mean()
    T = 0.25 * hbar ** 2
    hs = np.array(hs) * T / sum(hs)
    hist = [X]; H = []; ratios = []; dbls = []
    for k, h in enumerate(hs):
        Xk = hist[-1]
        Xn = step[scheme](Xk, F, h)
        R = Xk
        for _ in range(64): R = richardson(R, F, h / 64)
        _, mk = ops(Xk, F)
        true = mnorm(Xn - R, mk)
        # the step-doubling estimate of the scheme itself: two h/2 steps
        # against one h, /3 (second order), against the true error of the
        # two half steps
        X2 = step[scheme](step[scheme](Xk, F, h / 2), F, h / 2)
        dbl = mnorm(X2 - Xn, mk) / 3; true2 = mnorm(X2 - R, mk)
        dbls.append(dbl / true2)
        print(f"{scheme} step {k}: doubling est {dbl:.3e} true(two halves) {true2:.3e} ratio {dbl/true2:.2f}")
        if len(hist) >= 3:
            h1, h2 = H[-1], H[-2]
            tk, tm1, tm2, tp = 0, -h1, -h1 - h2, h
            l0 = (tp - tm1) * (tp - tk) / ((tm2 - tm1) * (tm2 - tk))
            l1 = (tp - tm2) * (tp - tk) / ((tm1 - tm2) * (tm1 - tk))
            l2 = (tp - tm2) * (tp - tm1) / ((tk - tm2) * (tk - tm1))
            D = Xn - (l0 * hist[-3] + l1 * hist[-2] + l2 * hist[-1])
            est = 6 * C[scheme] * h * h / ((h + h1) * (h + h1 + h2)) * mnorm(D, mk)
            ratios.append(est / true)
            print(f"{scheme} step {k} h/T {h/T:.4f} true {true:.3e} est {est:.3e} est/true {est/true:.2f}")
        hist.append(Xn); H.append(h)
    d = np.array(dbls)
    print(f"{scheme}: doubling est/true over {len(d)} steps: min {d.min():.2f} median {np.median(d):.2f} max {d.max():.2f}")
    r = np.array(ratios)
    print(f"{scheme}: est/true over {len(r)} steps: min {r.min():.2f} median {np.median(r):.2f} max {r.max():.2f}")

if __name__ == '__main__':
    mesh, scheme, kind = sys.argv[1], sys.argv[2], sys.argv[3]
    hs = [1.0] * 12 if kind == 'equal' else [1.25 ** k for k in range(14)]
    run(mesh, scheme, hs)
