#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""crossfit.py - issue 31, organic normal noise: LEARNED combination weights, fitted on some
meshes and reported on the others (leave one mesh out). A lab study, not the product.

Input: the cases nonlin_let.py dumped (DUMP=DIR: per mesh and level the columns of its
family, the noisy and clean positions, n0, areas, the default's displacement, SURE's
divergences). For each level and each held-out mesh, the weights are the least-squares fit,
pooled over the OTHER meshes at the same level, of the clean heights n0.(C - X) / s by the
columns' heights / s (each training case weighed by its clean areas over their sum: every mesh
counts the same). Applied to the held-out mesh; its output moves along the normals of X + D.
Sets: lin (the linear bands and low-pass), all (with the non-linear ones), +def (the default's
displacement as one more column). Blind guard for lin / all (the weights do not depend on the
held-out mesh's noise, so SURE is unbiased for them): take them when their SURE along n0 is
below the held-out mesh's own SURE-LET over lin (its SURE at its fitted weights plus 2 s^2 per
weight), else the default. Printed: JSON lines, error over the input's.
Usage: crossfit.py DIR"""
import glob, json, os, sys
import numpy as np
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import surelet_study as S

def load(d, fam='f'):
    cases = {}
    for p in sorted(glob.glob(d + '/*-' + fam + '.npz')):
        z = dict(np.load(p))
        mesh, rho = os.path.basename(p).rsplit('-', 2)[:2]
        z['cols+def'] = np.concatenate([z['cols'], z['Dd'][None]])
        cases[(mesh, float(rho))] = z
    return cases

def design(z, idx, withdef):
    M = z['cols+def'] if withdef else z['cols']
    M = M[idx + ([len(z['cols'])] if withdef else [])]
    sw = np.sqrt(z['Acl'] / z['Acl'].sum())
    return np.einsum('kni,ni->nk', M, z['n0']) * sw[:, None] / z['s'], np.sum((z['C'] - z['X']) * z['n0'], 1) * sw / z['s'], M

def out_err(z, M, th):
    D = np.tensordot(th, M, 1)
    X = z['X']
    ny = S.vnormals(X + D, z['F'])
    return S.err(X + ny * np.sum(ny * D, 1)[:, None], z['C'], z['Acl']) / z['e_in']

def sure(z, idx, th):
    R = np.einsum('kni,ni->kn', z['cols'][idx], z['n0'])
    r = th @ R
    return float(np.sum(z['w'] * r * r) + 2 * z['s'] ** 2 * th @ z['divs'][idx])

def main(d):
    cases = load(d)
    kinds = list(next(iter(cases.values()))['kinds'])
    sets = {'lin': [i for i, k in enumerate(kinds) if k == 'lin'], 'all': list(range(len(kinds)))}
    for (mesh, rho), z in cases.items():
        train = [v for (m, r), v in cases.items() if r == rho and m != mesh]
        res = {'mesh': mesh, 'rho': rho, 'train': len(train),
               'default': S.err(z['X'] + z['Dd'], z['C'], z['Acl']) / z['e_in']}
        lin = sets['lin']
        R = np.einsum('kni,ni->kn', z['cols'][lin], z['n0'])
        G = (R * z['w'][None]) @ R.T
        th = np.linalg.solve(G, -z['s'] ** 2 * z['divs'][lin])
        s_let = float(th @ G @ th + 2 * z['s'] ** 2 * th @ z['divs'][lin]) + 2 * z['s'] ** 2 * len(lin)
        for name, idx in sets.items():
            for wd in (False, True):
                A = np.vstack([design(v, idx, wd)[0] for v in train])
                b = np.concatenate([design(v, idx, wd)[1] for v in train])
                th = np.linalg.lstsq(A, b, rcond=None)[0]
                key = name + ('+def' if wd else '')
                res[key] = out_err(z, design(z, idx, wd)[2], th)
                if not wd:
                    take = sure(z, idx, th) < s_let
                    res[key + '_guard'] = res[key] if take else res['default']
        print(json.dumps({k: (round(v, 4) if isinstance(v, float) else v) for k, v in res.items()}), flush=True)

if __name__ == '__main__':
    main(sys.argv[1])
