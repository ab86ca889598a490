#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""outrule_tables.py - the s31o4 section's tables from outrule_study.py's JSON lines: per variant
the error over Taubin's stored oracle (issue31-before's taubin_best/input, and baseline-*.csv of
this folder for the cases issue31-before lacks: the same make quality draw, seed 1), medians per
mesh set and seed, and wins / losses against the first variant (by more than 0.1%).
Usage: outrule_tables.py FILE.jsonl[,..] VAR[,VAR..] SET=MESH:MESH..[;SET=..]"""
import csv, json, os, sys
import numpy as np

here = os.path.dirname(os.path.abspath(__file__))
anchor, in_before = {}, set()  # in_before: the cases issue31-before has (the bar's 17 organic ones)
for p in (here + '/baseline-small.csv', here + '/baseline-large.csv', here + '/../issue31-before/quality.csv'):
    for r in csv.DictReader(open(p)):
        if r['method'] == 'taubin_best' and r['model'] == 'normal' and r['seed'] == '1':
            anchor[(r['mesh'], round(float(r['rho']), 2))] = float(r['ratio'])
            if 'issue31-before' in p:
                in_before.add((r['mesh'], round(float(r['rho']), 2)))

def main():
    recs = [json.loads(l) for f in sys.argv[1].split(',') for l in open(f)]
    vs = sys.argv[2].split(',')
    sets = [(s.split('=')[0], s.split('=')[1].split(':')) for s in sys.argv[3].split(';')]
    print('| set | seed | cases | ' + ' | '.join(vs) + ' |')
    print('|---|---|---|' + '---|' * len(vs))
    for nm, ms in sets:
        for seed in sorted({r['seed'] for r in recs}):
            rs = [r for r in recs if r['seed'] == seed and r['mesh'] in ms and (r['mesh'], round(r['rho'], 2)) in anchor]
            if not rs:
                continue
            a = np.array([anchor[(r['mesh'], round(r['rho'], 2))] for r in rs])
            base = np.array([r[vs[0]] for r in rs]) / a
            cells = []
            for v in vs:
                x = np.array([r[v] for r in rs]) / a
                cells.append('%.3f' % np.median(x) + ('' if v == vs[0] else ' (%d / %d)' % (
                    np.sum(x < base * 0.999), np.sum(x > base * 1.001))))
            print('| %s | %d | %d | ' % (nm, seed, len(rs)) + ' | '.join(cells) + ' |')

if __name__ == '__main__':
    main()
