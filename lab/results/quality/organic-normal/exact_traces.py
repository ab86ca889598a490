#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""exact_traces.py - SURE-LET over the implicit steps (f) and the uniform passes (u) of
surelet_study.py, with the traces from 6 Rademacher probes and exact (the identity's n
columns carried through the same iterations: the diagonal of each iterate's operator).
Small meshes only (n columns). Usage: exact_traces.py MESH[,MESH..]   (rho 0.1, 0.25, 0.5)"""
import os, sys, importlib.util
import numpy as np
spec = importlib.util.spec_from_file_location('S', os.path.join(os.path.dirname(os.path.abspath(__file__)),
                                                                 'surelet_study.py'))
S = importlib.util.module_from_spec(spec)
spec.loader.exec_module(S)

def run(name, rho, nprobe):
    C, F, n, Nc, Acl, X, e_in, s = S.noisy_case(name, rho)
    n0, w = S.vnormals(X, F), S.areas(X, F)
    w = w / w.mean()
    A = S.adjacency(F, n)
    Z = np.where(np.random.default_rng(7).random((n, nprobe)) < 0.5, -1.0, 1.0) if nprobe else np.eye(n)
    fam = {'f': S.implicit_iterates(X, A, [1, 2, 4, 8, 16, 32], Z),
           'u': S.pass_iterates(X, A, [2, 4, 8, 16, 32, 64, 128], Z)}
    Ds, tr, tag = [], [], []
    for p, its in fam.items():
        for k, (Y, TZ) in its.items():
            Ds.append(Y - X)
            tag.append(p)
            t = np.mean(np.sum(w[:, None] * Z * TZ, 0)) if nprobe else np.sum(w * np.diag(TZ))
            tr.append(t - w.sum())
    R, b = np.array([np.sum(D * n0, 1) for D in Ds]).T, np.array(tr)
    out = {}
    for P in ('f', 'fu'):
        cols = [j for j, t in enumerate(tag) if t in P]
        G = (R[:, cols] * w[:, None]).T @ R[:, cols]
        c = np.linalg.solve(G + 1e-12 * np.trace(G) * np.eye(len(cols)), -s * s * b[cols])
        D = sum(c[i] * Ds[j] for i, j in enumerate(cols))
        ny = S.vnormals(X + D, F)
        out['LET_' + P] = round(S.err(X + ny * np.sum(ny * D, 1)[:, None], C, Acl) / e_in, 4)
    print(name, rho, 'traces:', f'{nprobe} probes' if nprobe else 'exact', out, flush=True)

if __name__ == '__main__':
    for m in sys.argv[1].split(','):
        for r in (0.1, 0.25, 0.5):
            for npb in (6, 0):
                run(m, r, npb)
