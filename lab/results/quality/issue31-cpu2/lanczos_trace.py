# SPDX-License-Identifier: MIT
# Does Lanczos quadrature give the fairing's per-probe Hutchinson traces
# z' W R^K z (R = (I + N^2)^-1, N = D^-1/2 L_FF D^-1/2) for K = 1..200 without
# carrying the probes through the 200 solves? numpy/scipy check on a shared mesh.
import sys, time
import numpy as np, scipy.sparse as sp, scipy.sparse.linalg as sla
from scipy.linalg import solve_banded

def load_obj(p):
    V, F = [], []
    for l in open(p):
        if l.startswith('v '):
            V.append([float(t) for t in l.split()[1:4]])
        elif l.startswith('f '):
            F.append([int(t.split('/')[0]) - 1 for t in l.split()[1:4]])
    return np.array(V), np.array(F)

V, F = load_obj(sys.argv[1])
cap = int(sys.argv[2]) if len(sys.argv) > 2 else 200
nv = len(V)
E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
E = np.sort(E, axis=1)
Eu, cnt = np.unique(E, axis=0, return_counts=True)
A = sp.coo_matrix((np.ones(len(Eu)), (Eu[:, 0], Eu[:, 1])), shape=(nv, nv)).tocsr()
A = ((A + A.T) > 0).astype(float)
deg = np.asarray(A.sum(1)).ravel()
bnd = np.zeros(nv, bool)
bnd[Eu[cnt == 1].ravel()] = True
free = np.where((~bnd) & (deg > 0))[0]
n = len(free)
Aff = A[free][:, free]
sq = np.sqrt(deg[free])
N = sp.identity(n) - sp.diags(1 / sq) @ Aff @ sp.diags(1 / sq)
N = N.tocsr()
# barycentric areas over their mean
cr = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
a = np.linalg.norm(cr, axis=1) / 6
w = np.zeros(nv)
for k in range(3):
    np.add.at(w, F[:, k], a)
w = w[free]
w = w * n / w.sum()
rng = np.random.default_rng(1)
nprobe = 6
Z = rng.choice([-1.0, 1.0], size=(n, nprobe))
print('free', n, 'nnz(N)', N.nnz)
# exact: the probes through the solves, as the engine does
t0 = time.process_time()
lu = sla.splu((sp.identity(n) + N @ N).tocsc())
Y = Z.copy()
ex = np.zeros((cap + 1, nprobe))
ex[0] = (w[:, None] * Z * Y).sum(0)
for K in range(1, cap + 1):
    Y = lu.solve(Y)
    ex[K] = (w[:, None] * Z * Y).sum(0)
t_ex = time.process_time() - t0

def lanczos_est(z, a, m, reorth):
    # Lanczos on N from z: alpha, beta, c_j = a . q_j; est(K) = |z| c' (I + T^2)^-K e1
    nz = np.linalg.norm(z)
    q = z / nz
    qprev = np.zeros(n)
    al, be, c = [], [], []
    Q = [] if reorth else None
    b = 0.0
    for j in range(m):
        c.append(a @ q)
        if reorth:
            Q.append(q)
        v = N @ q - b * qprev
        al.append(q @ v)
        v -= al[-1] * q
        if reorth:
            Qm = np.array(Q)
            v -= Qm.T @ (Qm @ v)
        b = np.linalg.norm(v)
        be.append(b)
        if b < 1e-14:
            break
        qprev, q = q, v / b
    m = len(al)
    T = np.diag(al) + np.diag(be[:m - 1], 1) + np.diag(be[:m - 1], -1)
    M = np.eye(m) + T @ T
    # banded storage, bandwidth 2
    ab = np.zeros((5, m))
    for d in range(-2, 3):
        diag = np.diag(M, d)
        if d >= 0:
            ab[2 - d, d:] = diag
        else:
            ab[2 - d, :m + d] = diag
    x = np.zeros(m); x[0] = 1.0
    c = np.array(c)
    out = np.zeros(cap + 1)
    out[0] = nz * (c @ x)
    for K in range(1, cap + 1):
        x = solve_banded((2, 2), ab, x)
        out[K] = nz * (c @ x)
    return out, m

for m in [int(t) for t in (sys.argv[3] if len(sys.argv) > 3 else '20,40,80,120,160,240').split(',')]:
    for reorth in (False,):
        t0 = time.process_time()
        lz = np.stack([lanczos_est(Z[:, q], w * Z[:, q], m, reorth)[0] for q in range(nprobe)], 1)
        t_lz = time.process_time() - t0
        err = np.abs(lz - ex)
        # SURE's scale: 2 s^2 tr against s^2 sum w = s^2 n: the error in units of n
        worstK = [int(np.argmax(err.max(1)))]
        print('m %3d reorth %d: max |est - exact| / n over K<=%d: %.2e (at K %d); K<=8: %.2e; K<=64: %.2e; cpu %.2f s (exact %.2f s)'
              % (m, reorth, cap, err.max() / n, worstK[0], err[:9].max() / n, err[:65].max() / n, t_lz, t_ex))
print('trace/n at K=1,8,64,200:', [round(ex[K].mean() / n, 6) for K in (1, 8, 64, min(200, cap))])
