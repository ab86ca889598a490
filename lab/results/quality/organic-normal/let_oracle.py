#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""let_oracle.py - issue 31, organic normal noise: the ceiling of SURE-LET over NON-linear
filter outputs. The output X + sum_j c_j (Y_j - X) with the weights c fitted to the CLEAN mesh
(3D least squares, clean vertex areas): what any blind weighting (SURE-LET, Blu & Luisier 2007)
of these filters could at best reach. Columns Y_j: the product's default request, its
feature-aware scheme (fairing_feature: bilateral normal filtering + vertex update, range and
iterations by SURE), the numpy Taubin stand-in at its oracle pass count (adaptive_study.py),
and the implicit step's iterates k = 1, 2, 4, 8, 16, 32 along their normals. Noise as
surelet_study.py (seed 1). Printed: each over the Taubin stand-in, the combinations' oracles,
and the blind SURE-LET of the default and the feature scheme: the weights from the noisy mesh
alone, each filter's divergence by Monte-Carlo probes through the product as a black box
(NPROBE probes, default 2; SURE_NORMALS=pilot: along the default output's normals, not the
noisy mesh's); let1: the same with the two weights summing to 1 (one weight t); flips: faces
turned against the clean mesh's.
Usage: let_oracle.py MESH[,..] RHO[,..] MCF"""
import json, os, subprocess, sys
import numpy as np
NPROBE = int(os.environ.get("NPROBE", "2"))  # probes for the blind weights' divergences
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import surelet_study as S
import adaptive_study as AS

def run(mcf, X, F, extra):
    S.write_obj('/tmp/letorc_in.obj', X, F)
    subprocess.run([mcf, 'smooth', '--quiet'] + extra + ['/tmp/letorc_in.obj', '/tmp/letorc_out.obj'], check=True)
    return S.read_obj('/tmp/letorc_out.obj')[0]

def case(name, rho, mcf):
    C, F, n, Nc, Acl, X, e_in, s = S.noisy_case(name, rho)
    tb, _, Ytb = AS.taubin_oracle(X, F, C, Acl, e_in)
    cols = {'default': run(mcf, X, F, []), 'feature': run(mcf, X, F, ['--scheme', 'fairing_feature']), 'taubin': Ytb}
    Z = np.zeros((n, 1))
    its = S.implicit_iterates(X, S.adjacency(F, n), [1, 2, 4, 8, 16, 32], Z)
    for k, (Y, _) in its.items():
        D = Y - X
        ny = S.vnormals(Y, F)
        cols['f%d' % k] = X + ny * np.sum(ny * D, 1)[:, None]
    res = {'mesh': name, 'rho': rho, 'taubin': round(tb, 4)}
    for k, Y in cols.items():
        res[k + '/tb'] = round(S.err(Y, C, Acl) / e_in / tb, 4)
    sw = np.sqrt(Acl)[:, None]

    def fit(names):
        M = np.stack([((cols[k] - X) * sw).ravel() for k in names], 1)
        c = np.linalg.lstsq(M, ((C - X) * sw).ravel(), rcond=None)[0]
        Y = X + sum(ci * (cols[k] - X) for ci, k in zip(c, names))
        return round(S.err(Y, C, Acl) / e_in / tb, 4), [round(x, 3) for x in c]
    res['orc_def+feat/tb'], res['w_def+feat'] = fit(['default', 'feature'])
    res['orc_def+feat+tb/tb'], _ = fit(['default', 'feature', 'taubin'])
    res['orc_all/tb'], res['w_all'] = fit(list(cols))
    # blind: SURE-LET of the default and the feature scheme, the product as a black box.
    # Heights r_j = n0.(Y_j - X) along the noisy normals; each filter's divergence by
    # Monte-Carlo (Ramani, Blu, Unser 2008): b.(r_j(X + eps b n0) - r_j(X)) / eps, b Rademacher,
    # eps = 0.01 s, NPROBE probes; weights from G c = -s^2 div (area weights of the noisy mesh).
    n0, w = S.vnormals(X, F), S.areas(X, F)
    if os.environ.get('SURE_NORMALS') == 'pilot':  # heights and probes along the default's normals
        n0 = S.vnormals(cols['default'], F)
    w = w / w.mean()
    names, extra = ['default', 'feature'], {'default': [], 'feature': ['--scheme', 'fairing_feature']}
    r = np.array([np.sum((cols[k] - X) * n0, 1) for k in names])
    div = np.zeros(2)
    rng, eps = np.random.default_rng(11), 0.01 * s
    for _ in range(NPROBE):
        b = np.where(rng.random(n) < 0.5, -1.0, 1.0)
        Xp = X + eps * b[:, None] * n0
        for j, k in enumerate(names):
            rp = np.sum((run(mcf, Xp, F, extra[k]) - Xp) * n0, 1)  # D(X + eps b n0) along n0
            div[j] += np.sum(w * b * (rp - r[j])) / eps / NPROBE
    G = (r * w[None]) @ r.T
    c = np.linalg.solve(G, -s * s * div)
    Y = X + sum(ci * (cols[k] - X) for ci, k in zip(c, names))
    res['let_def+feat/tb'], res['wlet_def+feat'] = round(S.err(Y, C, Acl) / e_in / tb, 4), [round(x, 3) for x in c]
    res['div_def+feat'] = [round(x / w.sum(), 4) for x in div]
    # the same, weights summing to 1 (Y = Y_def + t (Y_feat - Y_def)): one weight, no shrink
    dr = r[1] - r[0]
    t = -(np.sum(w * r[0] * dr) + s * s * (div[1] - div[0])) / np.sum(w * dr * dr)
    Y = cols['default'] + t * (cols['feature'] - cols['default'])
    res['let1_def+feat/tb'], res['t_let1'] = round(S.err(Y, C, Acl) / e_in / tb, 4), round(t, 3)
    # faces turned against the clean mesh's (face normals' dot product < 0)
    fc = S.face_normals(C, F)
    flips = lambda V: int(np.sum(np.sum(S.face_normals(V, F) * fc, 1) < 0))
    Ylet = X + sum(ci * (cols[k] - X) for ci, k in zip(c, names))
    res['flips'] = {'input': flips(X), 'default': flips(cols['default']), 'feature': flips(cols['feature']),
                    'let': flips(Ylet), 'let1': flips(Y)}
    print(json.dumps(res), flush=True)

if __name__ == '__main__':
    for m in sys.argv[1].split(','):
        for r in sys.argv[2].split(','):
            case(m, float(r), sys.argv[3])
