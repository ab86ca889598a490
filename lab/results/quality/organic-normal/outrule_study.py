#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""outrule_study.py - issue 31, organic normal noise: the default request's error over Taubin's
oracle with variants of the build selected by environment (a lab study, not the product); for the
first variant also its error split along the clean normals and in the tangent planes (errN,
errT) and the error of its displacement's heights moved along the CLEAN normals (cleanN: an
oracle output rule, the most any normal field could give the same heights).

For each mesh, level rho and seed: surelet_study.py's noise law (Gaussian of s = rho h along the
clean area-weighted vertex normals; numpy seed SEED), `MCF smooth` (nothing set) once per variant
(VARIANTS: ';'-separated NAME=ENV,ENV.. e.g. 'base=;xn2=MCF_XN=2'), the output's area-weighted RMS
error against the clean mesh over the input's, and that over issue31-before's stored taubin_best
ratio (the bar's definition; nan where none is stored). user+sys CPU of each run (children's).
Prints one JSON line per case.
Usage: outrule_study.py MESH[,..] RHO[,..] SEED[,..] MCF VARIANTS"""
import csv, json, os, resource, subprocess, sys
import numpy as np
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import surelet_study as S

Q = os.path.join(os.path.dirname(os.path.abspath(__file__)), '../issue31-before/quality.csv')
orc = {}
for r in csv.DictReader(open(Q)):
    if r['method'] == 'taubin_best' and r['model'] == 'normal' and r['seed'] == '1':
        orc[(r['mesh'], float(r['rho']))] = float(r['ratio'])

def noisy(name, rho, seed):
    C, F = S.read_obj(S.MESHES + name)
    E = S.edges(F)
    h = np.linalg.norm(C[E[:, 0]] - C[E[:, 1]], axis=1).mean()
    Nc, A = S.vnormals(C, F), S.areas(C, F)
    X = C + rho * h * np.random.default_rng(seed).standard_normal(len(C))[:, None] * Nc
    return C, F, A, X

meshes, rhos, seeds, mcf = sys.argv[1].split(','), [float(r) for r in sys.argv[2].split(',')], \
    [int(s) for s in sys.argv[3].split(',')], sys.argv[4]
variants = []
for v in sys.argv[5].split(';'):
    nm, envs = v.split('=', 1)
    variants.append((nm, dict(e.split('=', 1) for e in envs.split(',') if e)))
tmp = '/tmp/s31o4/%d' % os.getpid()
os.makedirs(tmp, exist_ok=True)
for m in meshes:
    for rho in rhos:
        for seed in seeds:
            C, F, A, X = noisy(m, rho, seed)
            e_in = S.err(X, C, A)
            S.write_obj(tmp + '/in.obj', X, F)
            out = {'mesh': m, 'rho': rho, 'seed': seed, 'taubin': orc.get((m, rho), float('nan'))}
            for nm, env in variants:
                e = dict(os.environ)
                for k in ('MCF_XN', 'MCF_XNIT', 'MCF_XFULL'):
                    e.pop(k, None)
                e.update(env)
                r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
                subprocess.run([mcf, 'smooth', '--quiet', '--threads', '1', tmp + '/in.obj', tmp + '/out.obj'],
                               check=True, env=e)
                r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
                Y = S.read_obj(tmp + '/out.obj')[0]
                ratio = S.err(Y, C, A) / e_in
                out[nm] = round(ratio, 5)
                out[nm + '_t'] = round(ratio / out['taubin'], 4)
                out[nm + '_cpu'] = round(r1.ru_utime + r1.ru_stime - r0.ru_utime - r0.ru_stime, 3)
                if nm == variants[0][0]:  # the first variant's heights moved along the CLEAN normals (an oracle rule)
                    Nc = S.vnormals(C, F)
                    Xo = X + Nc * np.sum(Nc * (Y - X), 1)[:, None]
                    out[nm + '_cleanN'] = round(S.err(Xo, C, A) / e_in, 5)
                    dn, dt = S.split(Y, C, A, Nc)
                    out[nm + '_errN'], out[nm + '_errT'] = round(dn / e_in, 5), round(dt / e_in, 5)
            print(json.dumps(out), flush=True)
