# SPDX-License-Identifier: MIT
"""plated.py MESH... - issue 31's plated gate and coarse reading in numpy, an independent
computation of core/mcf_fairing_input.c's mcf__fair_plated_share and the coarse reading
(docs/fairing.md, "Correlated noise on plated parts"): the normals of 9 uniform graph averages
of the positions; regions grown from seeds in index order, of free vertices facing within
8 degrees of the seed's; the share of the free vertices in regions of at least 2% of them;
the robust deviation (1.4826 MAD) of n . (x - Avg^9 x) over the free vertices of degree >= 3,
in mean edges. Free: not on a boundary edge, with an edge. Prints, per mesh, the share as a
fraction (the count of vertices inside over the free count) and the reading of the clean mesh,
and of the mesh with corr noise of 0.1 h (issue 31's definition, numpy's draws, seed 1).
`/usr/bin/python3 plated.py blade.obj spot.obj` (OBJ files under /work/shared/meshes or
$MCF_MESHES)."""
import numpy as np, scipy.sparse as sp, sys, os

def load_obj(p):
    V, F = [], []
    for l in open(p):
        if l.startswith('v '):
            V.append([float(x) for x in l.split()[1:4]])
        elif l.startswith('f '):
            idx = [int(x.split('/')[0]) - 1 for x in l.split()[1:]]
            for k in range(1, len(idx) - 1):
                F.append([idx[0], idx[k], idx[k + 1]])
    return np.array(V), np.array(F, dtype=np.int64)

def graph(X, F):
    nv = len(X)
    i = np.r_[F[:, 0], F[:, 1], F[:, 2], F[:, 1], F[:, 2], F[:, 0]]
    j = np.r_[F[:, 1], F[:, 2], F[:, 0], F[:, 0], F[:, 1], F[:, 2]]
    A = sp.coo_matrix((np.ones(len(i)), (i, j)), shape=(nv, nv)).tocsr()
    A.data[:] = 1
    deg = np.asarray(A.sum(1)).ravel()
    fe = np.sort(np.r_[F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]], axis=1)
    u, c = np.unique(fe, axis=0, return_counts=True)
    fixed = np.zeros(nv, bool)
    fixed[u[c == 1].ravel()] = True
    fixed[deg == 0] = True
    e = np.unique(np.sort(np.c_[i, j], axis=1), axis=0)
    h = np.mean(np.linalg.norm(X[e[:, 0]] - X[e[:, 1]], axis=1))
    return A, deg, fixed, h

def vnormals(X, F):
    n = np.cross(X[F[:, 1]] - X[F[:, 0]], X[F[:, 2]] - X[F[:, 0]])
    N = np.zeros_like(X)
    for k in range(3):
        np.add.at(N, F[:, k], n)
    L = np.linalg.norm(N, axis=1)
    return np.where(L[:, None] > 0, N / np.where(L > 0, L, 1)[:, None], 0.0)

def avg9(A, deg, Y):
    d = np.where(deg > 0, deg, 1)[:, None]
    for _ in range(9):
        Y = np.where(deg[:, None] > 0, (A @ Y) / d, Y)
    return Y

def plated(A, N, fixed, cos_t=np.cos(np.radians(8.0)), frac=0.02):
    nv = len(N)
    lab = np.zeros(nv, bool)
    nfree = int((~fixed).sum())
    inside = 0
    for s in range(nv):
        if lab[s] or fixed[s]:
            continue
        lab[s] = True
        stack, size = [s], 0
        while stack:
            v = stack.pop()
            size += 1
            for w in A.indices[A.indptr[v]:A.indptr[v + 1]]:
                if not lab[w] and not fixed[w] and N[w] @ N[s] >= cos_t:
                    lab[w] = True
                    stack.append(w)
        if size >= frac * nfree:
            inside += size
    return inside, nfree

def reading(A, deg, fixed, X, F):
    Z = avg9(A, deg, X)
    N = vnormals(Z, F)
    d = ((X - Z) * N).sum(1)[(~fixed) & (deg >= 3)]
    return 1.4826 * np.median(np.abs(d - np.median(d))), N

if __name__ == '__main__':
    root = os.environ.get('MCF_MESHES', '/work/shared/meshes')
    for m in sys.argv[1:]:
        X, F = load_obj(os.path.join(root, m))
        A, deg, fixed, h = graph(X, F)
        rng = np.random.default_rng(1)
        z = rng.standard_normal(len(X))
        for _ in range(9):
            z = (z + A @ z) / (1 + deg)
        z /= np.sqrt(np.mean(z[~fixed] ** 2))
        n0 = vnormals(X, F)
        for name, Y in (('clean', X), ('corr 0.1', X + np.where(fixed, 0, 0.1 * h * z)[:, None] * n0)):
            r, N = reading(A, deg, fixed, Y, F)
            inside, nfree = plated(A, N, fixed)
            print('%s %s: plated %d / %d = %.6f, coarse reading %.5f h' % (m, name, inside, nfree, inside / nfree, r / h))
