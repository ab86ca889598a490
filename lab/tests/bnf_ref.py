#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""bnf_ref.py - an independent numpy implementation of bilateral normal
filtering (Zheng et al. 2011) with Sun et al. 2007's vertex update, as
lab/bench/quality_bnf.c defines it, for lab/tests/test_quality.c.

    bnf_ref.py IN MOVABLE SIGMA_R NORMAL_ITERS VERTEX_ITERS OUT

IN: a raw mesh (int32 nv, int32 nf, nv*3 float64, nf*3 int32); MOVABLE: nv
bytes, 1 where the vertex may move; OUT receives nv*3 float64 positions.
Written from the definitions, not from the C: neighbourhoods as Python sets
of faces sharing a vertex, sigma_s from the set of faces sharing an edge,
the sums as dense numpy reductions per face, the vertex update from the
per-vertex face lists.
"""
import sys

import numpy as np


def main():
    inp, movable_path, sigma_r, nit, vit, out = sys.argv[1:7]
    sigma_r, nit, vit = float(sigma_r), int(nit), int(vit)
    with open(inp, "rb") as f:
        nv, nf = (int(x) for x in np.frombuffer(f.read(8), dtype=np.int32))
        X0 = np.frombuffer(f.read(24 * nv), dtype=np.float64).reshape(-1, 3).copy()
        F = np.frombuffer(f.read(12 * nf), dtype=np.int32).reshape(-1, 3).astype(int)
    movable = np.frombuffer(open(movable_path, "rb").read(), dtype=np.uint8).astype(bool)

    cr = np.cross(X0[F[:, 1]] - X0[F[:, 0]], X0[F[:, 2]] - X0[F[:, 0]])
    ln = np.linalg.norm(cr, axis=1)
    A = 0.5 * ln
    n0 = np.where(ln[:, None] > 0, cr / np.where(ln > 0, ln, 1)[:, None], 0.0)
    C = X0[F].mean(axis=1)

    faces_of = [set() for _ in range(nv)]
    for f, t in enumerate(F):
        for v in t:
            faces_of[v].add(f)
    nbr = [sorted(set().union(*(faces_of[v] for v in t))) for t in F]
    d_edge = [np.linalg.norm(C[f] - C[g]) for f, t in enumerate(F) for g in nbr[f]
              if g != f and len(set(t) & set(F[g])) >= 2]
    sigma_s = float(np.mean(d_edge)) if d_edge else 1.0

    n = n0.copy()
    for _ in range(nit):
        new = np.empty_like(n)
        for f in range(nf):
            J = np.array(nbr[f])
            w = (A[J] * np.exp(-np.sum((C[J] - C[f]) ** 2, axis=1) / (2 * sigma_s ** 2))
                 * np.exp(-np.sum((n[J] - n[f]) ** 2, axis=1) / (2 * sigma_r ** 2)))
            s = (w[:, None] * n[J]).sum(axis=0)
            ls = np.linalg.norm(s)
            new[f] = s / ls if ls > 0 else n[f]
        n = new

    X = X0.copy()
    for _ in range(vit):
        Cx = X[F].mean(axis=1)
        Xn = X.copy()
        for v in range(nv):
            fs = sorted(faces_of[v])
            if not fs or not movable[v]:
                continue
            N = n[fs]
            Xn[v] = X[v] + (N * np.sum(N * (Cx[fs] - X[v]), axis=1)[:, None]).sum(axis=0) / len(fs)
        X = Xn
    X.astype(np.float64).tofile(out)


if __name__ == "__main__":
    main()
