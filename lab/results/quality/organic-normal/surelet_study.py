#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""surelet_study.py - issue 31, Gaussian noise along the normals on organic meshes:
where the default request's remaining error is, and how far linear combinations of
filter outputs (SURE-LET, Blu & Luisier 2007) can take it. A lab study, not the product.

For each mesh and level rho (noise sigma = rho h along the clean area-weighted vertex
normals, numpy seed 1, h the clean mean edge):
  * the product's default request (build/mcf smooth, nothing set): its error
    (area-weighted RMS distance to the clean vertex, over the input's), split along the
    clean normals and in the tangent planes;
  * three filter families on the noisy mesh, the iterates' displacements D_k:
      f  the product's implicit step (I + N^2) on the uniform graph, k = 1..32,
      u  uniform lambda|mu passes (0.5, -0.53), k = 2..128,
      c  the same passes with cotan weights of the noisy mesh (negative ones clamped);
    the output of a displacement D moves each vertex along the normal n of X + D:
    X + n <n, D> (as the product does);
  * LET_P: the combination sum_j c_j D_j over family set P whose SURE along the noisy
    normals n0 is least: G c = -s^2 b, G_jl = sum w r_j r_l, r_j = n0 . D_j, b_j = the
    weighted trace of (T_j - I) from 6 Rademacher probes carried through the same
    iterations (Hutchinson), s the true level; orc_P: the weights of the least squares
    fit of r = sum c_j r_j to the true heights n0 . (C - X) (an oracle, knows C).
Usage: surelet_study.py MESH[,MESH..] RHO[,RHO..] [MCF]   (meshes from /work/shared/meshes)
"""
import json, subprocess, sys
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spl

MESHES = '/work/shared/meshes/'

def read_obj(p):
    V, F = [], []
    for line in open(p):
        if line.startswith('v '):
            V.append([float(t) for t in line.split()[1:4]])
        elif line.startswith('f '):
            idx = [int(t.split('/')[0]) for t in line.split()[1:]]
            F += [[idx[0] - 1, idx[k] - 1, idx[k + 1] - 1] for k in range(1, len(idx) - 1)]
    V, F = np.array(V), np.array(F, dtype=np.int64)
    u, inv = np.unique(F, return_inverse=True)  # unreferenced vertices dropped
    return V[u], inv.reshape(F.shape)

def write_obj(p, V, F):
    with open(p, 'w') as f:
        np.savetxt(f, V, fmt='v %.17g %.17g %.17g')
        np.savetxt(f, F + 1, fmt='f %d %d %d')

def face_normals(V, F):
    return np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])

def vnormals(V, F):
    fn, N = face_normals(V, F), np.zeros_like(V)
    for k in range(3):
        np.add.at(N, F[:, k], fn)
    return N / np.maximum(np.linalg.norm(N, axis=1), 1e-300)[:, None]

def areas(V, F):
    a, A = np.linalg.norm(face_normals(V, F), axis=1) / 6, np.zeros(len(V))
    for k in range(3):
        np.add.at(A, F[:, k], a)
    return A

def edges(F):
    E = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    return np.unique(E, axis=0)

def err(X, C, A):
    return np.sqrt(np.sum(A * np.sum((X - C) ** 2, 1)) / A.sum())

def split(X, C, A, N):
    D = X - C
    dn = np.sum(D * N, 1)
    return np.sqrt(np.sum(A * dn ** 2) / A.sum()), np.sqrt(np.sum(A * np.sum((D - dn[:, None] * N) ** 2, 1)) / A.sum())

def adjacency(F, n):
    E = edges(F)
    A = sp.coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])), shape=(n, n)).tocsr()
    return (A + A.T).tocsr()

def cotan(X, F, n):
    r, c, v = [], [], []
    for k in range(3):
        i, j, o = F[:, k], F[:, (k + 1) % 3], F[:, (k + 2) % 3]
        a, b = X[i] - X[o], X[j] - X[o]
        ct = np.sum(a * b, 1) / np.maximum(np.linalg.norm(np.cross(a, b), axis=1), 1e-300)
        r += [i, j]; c += [j, i]; v += [ct / 2, ct / 2]
    W = sp.coo_matrix((np.concatenate(v), (np.concatenate(r), np.concatenate(c))), shape=(n, n)).tocsr()
    W.data = np.maximum(W.data, 0.0)
    return W

def implicit_iterates(X, A, ks, Z):
    sq = np.sqrt(np.asarray(A.sum(1)).ravel())
    N = sp.identity(len(X)) - sp.diags(1 / sq) @ A @ sp.diags(1 / sq)
    lu = spl.splu((sp.identity(len(X)) + N @ N).tocsc())
    y, out = np.hstack([X * sq[:, None], Z]), {}
    for k in range(1, max(ks) + 1):
        y = lu.solve(y)
        if k in ks:  # T = D^-1/2 R D^1/2 has R's diagonal: probes through R
            out[k] = (y[:, :3] / sq[:, None], y[:, 3:])
    return out

def pass_iterates(X, W, ks, Z, lam=0.5, mu=-0.53):
    P = sp.diags(1 / np.asarray(W.sum(1)).ravel()) @ W
    y, out = np.hstack([X, Z]), {}
    for k in range(1, max(ks) + 1):
        y = y + lam * (P @ y - y)
        y = y + mu * (P @ y - y)
        if k in ks:
            out[k] = (y[:, :3], y[:, 3:])
    return out

def noisy_case(name, rho):
    """The clean mesh C, F (MESHES + name) and its copy X with Gaussian noise of
    deviation s = rho h along the clean vertex normals Nc (seed 1; h the mean edge):
    C, F, n, Nc, the clean areas Acl, X, the input's error e_in and s. Every study
    of this folder draws its noisy case here."""
    C, F = read_obj(MESHES + name)
    n, E = len(C), edges(F)
    h = np.linalg.norm(C[E[:, 0]] - C[E[:, 1]], axis=1).mean()
    Nc, Acl = vnormals(C, F), areas(C, F)
    X = C + rho * h * np.random.default_rng(1).standard_normal(n)[:, None] * Nc
    return C, F, n, Nc, Acl, X, err(X, C, Acl), rho * h

def case(name, rho, mcf):
    C, F, n, Nc, Acl, X, e_in, s = noisy_case(name, rho)
    res = {}
    if mcf:
        write_obj('/tmp/surelet_in.obj', X, F)
        subprocess.run([mcf, 'smooth', '--quiet', '--metrics', '/tmp/surelet_m.json', '/tmp/surelet_in.obj',
                        '/tmp/surelet_out.obj'], check=True)
        Y = read_obj('/tmp/surelet_out.obj')[0]
        dn, dt = split(Y, C, Acl, Nc)
        res['default'] = err(Y, C, Acl) / e_in
        res['default_normal'], res['default_tangential'] = dn / e_in, dt / e_in
    n0, w = vnormals(X, F), areas(X, F)
    w = w / w.mean()
    Z = np.where(np.random.default_rng(7).random((n, 6)) < 0.5, -1.0, 1.0)
    A = adjacency(F, n)
    fam = {'f': implicit_iterates(X, A, [1, 2, 4, 8, 16, 32], Z),
           'u': pass_iterates(X, A, [2, 4, 8, 16, 32, 64, 128], Z),
           'c': pass_iterates(X, cotan(X, F, n), [2, 4, 8, 16, 32, 64, 128], Z)}
    Ds, tr, tag = [], [], []
    for p, its in fam.items():
        for k, (Y, TZ) in its.items():
            Ds.append(Y - X)
            tr.append(np.mean(np.sum(w[:, None] * Z * TZ, 0)) - w.sum())
            tag.append(p)
    R, b = np.array([np.sum(D * n0, 1) for D in Ds]).T, np.array(tr)

    def out_err(cols, c):
        D = sum(c[i] * Ds[j] for i, j in enumerate(cols))
        ny = vnormals(X + D, F)
        return err(X + ny * np.sum(ny * D, 1)[:, None], C, Acl) / e_in

    for P in ('f', 'c', 'fu', 'fc', 'fuc'):
        cols = [j for j, t in enumerate(tag) if t in P]
        G = (R[:, cols] * w[:, None]).T @ R[:, cols]
        c = np.linalg.solve(G + 1e-12 * np.trace(G) * np.eye(len(cols)), -s * s * b[cols])
        res['LET_' + P] = out_err(cols, c)
        G = (R[:, cols] * Acl[:, None]).T @ R[:, cols]
        c = np.linalg.solve(G, (R[:, cols] * Acl[:, None]).T @ np.sum((C - X) * n0, 1))
        res['orc_' + P] = out_err(cols, c)
    print(json.dumps({'mesh': name, 'rho': rho, **{k: round(v, 4) for k, v in res.items()}}), flush=True)

if __name__ == '__main__':
    for m in sys.argv[1].split(','):
        for r in sys.argv[2].split(','):
            case(m, float(r), sys.argv[3] if len(sys.argv) > 3 else None)
