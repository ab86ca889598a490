#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""join.py - issue 31, organic meshes, normal noise: the default's error over Taubin's oracle
before and after, per case, from bench_quality CSV files of the same inputs (seed 1): BASE holds
taubin_best and the default before, NEW the default after (its own CSV rows). Prints a markdown
table and the medians per level. Usage: join.py BASE.csv[,BASE2.csv] NEW.csv[,NEW2.csv]
"""
import csv, sys, statistics as S
def load(paths):
    rows = []
    for p in paths.split(','):
        rows += list(csv.DictReader(open(p)))
    return rows
base, new = load(sys.argv[1]), load(sys.argv[2])
tb = {(r['mesh'], r['model'], r['rho']): float(r['ratio']) for r in base if r['method'] == 'taubin_best'}
d0 = {(r['mesh'], r['model'], r['rho']): (float(r['ratio']), float(r['cpu_s'])) for r in base if r['method'] == 'default'}
hold = set(sys.argv[3].split(',')) if len(sys.argv) > 3 else set()
out = {}
for r in new:
    if r['method'] != 'default': continue
    k = (r['mesh'], r['model'], r['rho'])
    if k not in tb: continue
    out[k] = (float(r['ratio']), float(r['cpu_s']), float(r['base_cpu_s']) if r['base_cpu_s'] not in ('', 'nan') else float('nan'), r['note'])
print('| mesh | rho | default/input before -> after | / taubin_best before -> after | CPU after / issue31-before | note |')
print('|---|---|---|---|---|---|')
rb, ra, cr = {}, {}, []
for k in sorted(out, key=lambda k: (k[0], float(k[2]))):
    a, cpu, bc, note = out[k]
    b = d0[k][0]
    rb.setdefault(k[2], []).append(b / tb[k]); ra.setdefault(k[2], []).append(a / tb[k]); cr.append(cpu / bc)
    print('| %s | %s | %.3f -> %.3f | %.3f -> **%.3f** | %.2f | %s |' % (k[0], k[2], b, a, b / tb[k], a / tb[k], cpu / bc, note))
allb = sum(rb.values(), []); alla = sum(ra.values(), [])
for r in sorted(rb):
    print('rho %s: median before %.3f after %.3f (worst %.3f -> %.3f), n=%d' % (r, S.median(rb[r]), S.median(ra[r]), max(rb[r]), max(ra[r]), len(ra[r])))
print('all: median before %.3f after %.3f (worst %.3f), n=%d; CPU ratio median %.2f worst %.2f' % (S.median(allb), S.median(alla), max(alla), len(alla), S.median(cr), max(cr)))
