# SPDX-License-Identifier: MIT
# Does Lanczos quadrature give the explicit passes' probe traces for every
# pass count K without carrying the probes through the passes? numpy/scipy,
# independent of the product's code, on a shared mesh.
#   One lambda|mu pass on the free vertices (the fixed ones, creases included,
#   enter only the coordinates' affine part) is T = D^-1/2 P(N) D^1/2,
#   N = I - D^-1/2 A_FF D^-1/2, P(l) = (1 - mu l)(1 - lambda l), lambda 0.5,
#   mu -0.53. The passes carried z and read z' W T^K z ("carried"); the
#   product now reads z' W P(N)^K z ("symmetric"): the same mean tr(W T^K).
# Prints, per m, the largest |Lanczos - exact symmetric| / n over K <= cap
# (SURE's terms are s^2 n: the error in those units), and over 60 probes the
# spread of the two estimators at a few K.
#   usage: lanczos_passes.py MESH.obj [CAP] [m,m,...]
import sys, time
import numpy as np, scipy.sparse as sp

LAM, MU = 0.5, -0.53

def load_obj(p):
    V, F = [], []
    for l in open(p):
        if l.startswith('v '):
            V.append([float(t) for t in l.split()[1:4]])
        elif l.startswith('f '):
            F.append([int(t.split('/')[0]) - 1 for t in l.split()[1:4]])
    return np.array(V), np.array(F)

V, F = load_obj(sys.argv[1])
cap = int(sys.argv[2]) if len(sys.argv) > 2 else 512
nv = len(V)
E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
E = np.sort(E, axis=1)
Eu, cnt = np.unique(E, axis=0, return_counts=True)
A = sp.coo_matrix((np.ones(len(Eu)), (Eu[:, 0], Eu[:, 1])), shape=(nv, nv)).tocsr()
A = ((A + A.T) > 0).astype(float)
deg = np.asarray(A.sum(1)).ravel()
bnd = np.zeros(nv, bool)
bnd[Eu[cnt == 1].ravel()] = True
# held: the boundary, and every 50th vertex (stands for held crease vertices)
held = bnd.copy()
held[::50] = True
free = np.where((~held) & (deg > 0))[0]
n = len(free)
Aff = A[free][:, free]
sq = np.sqrt(deg[free])
N = (sp.identity(n) - sp.diags(1 / sq) @ Aff @ sp.diags(1 / sq)).tocsr()
M = (sp.diags(1 / deg[free]) @ Aff).tocsr()   # the graph average, on the probes
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
print('%s: free %d of %d, nnz(N) %d' % (sys.argv[1].split('/')[-1], n, nv, N.nnz))

def passes_exact(Z, cap, symmetric):
    # the probes through the passes, as the engine had them (carried: the
    # graph average x + c (M x - x)), or through P(N) (symmetric)
    out = np.zeros((cap + 1, Z.shape[1]))
    Y = Z.copy()
    out[0] = (w[:, None] * Z * Y).sum(0)
    for K in range(1, cap + 1):
        if symmetric:
            Y = Y - LAM * (N @ Y)
            Y = Y - MU * (N @ Y)
        else:
            Y = Y + LAM * (M @ Y - Y)
            Y = Y + MU * (M @ Y - Y)
        out[K] = (w[:, None] * Z * Y).sum(0)
    return out

t0 = time.process_time()
ex = passes_exact(Z, cap, True)
t_ex = time.process_time() - t0

def lanczos_est(z, a, m):
    # Lanczos on N from z, no reorthogonalization (as the product):
    # est(K) = |z| c' P(T)^K e1, c_j = a . q_j
    nz = np.linalg.norm(z)
    q = z / nz
    qprev = np.zeros(n)
    al, be, c = [], [], []
    b = 0.0
    for j in range(m):
        c.append(a @ q)
        v = N @ q - b * qprev
        al.append(q @ v)
        v -= al[-1] * q
        b = np.linalg.norm(v)
        be.append(b)
        if b < 1e-13:
            break
        qprev, q = q, v / b
    m = len(al)
    T = np.diag(al) + np.diag(be[:m - 1], 1) + np.diag(be[:m - 1], -1)
    P = (np.eye(m) - MU * T) @ (np.eye(m) - LAM * T)
    x = np.zeros(m); x[0] = 1.0
    c = np.array(c)
    out = np.zeros(cap + 1)
    out[0] = nz * (c @ x)
    for K in range(1, cap + 1):
        x = P @ x
        out[K] = nz * (c @ x)
    return out

for m in [int(t) for t in (sys.argv[3] if len(sys.argv) > 3 else '16,32,48,64,96,128,192').split(',')]:
    t0 = time.process_time()
    lz = np.stack([lanczos_est(Z[:, q], w * Z[:, q], m) for q in range(nprobe)], 1)
    t_lz = time.process_time() - t0
    err = np.abs(lz - ex).max(1) / n
    print('m %3d: max |est - exact| / n: K<=16 %.2e, K<=64 %.2e, K<=128 %.2e, K<=%d %.2e; cpu %.2f s (exact %.2f s)'
          % (m, err[:17].max(), err[:65].max(), err[:129].max(), cap, err.max(), t_lz, t_ex))
# the two estimators over 60 probes: same mean (the trace), their spread
Zb = rng.choice([-1.0, 1.0], size=(n, 60))
kk = [k for k in (1, 4, 16, 64, 256) if k <= cap]
es = passes_exact(Zb, max(kk), True)[kk]
ec = passes_exact(Zb, max(kk), False)[kk]
for i, K in enumerate(kk):
    print('K %3d: trace/n symmetric %.6f +- %.2e (sd of one probe %.2e), carried %.6f +- %.2e (sd %.2e)'
          % (K, es[i].mean() / n, es[i].std() / n / np.sqrt(60), es[i].std() / n,
             ec[i].mean() / n, ec[i].std() / n / np.sqrt(60), ec[i].std() / n))
d = np.abs(es - ec).max(1) / n
print('per probe |symmetric - carried| / n at K %s: %s' % (kk, ' '.join('%.2e' % x for x in d)))
