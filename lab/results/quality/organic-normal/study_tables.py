#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""study_tables.py - the markdown tables of adaptive_study.py's and let_oracle.py's JSON lines,
each figure (error over the input's, numpy draw, seed 1) divided by make quality's stored
Taubin oracle on the same mesh and level (taubin_best / input in
lab/results/quality/issue31-before/quality.csv: the bar's definition; the draws differ, which
moves the default's figures 0-4%), and by the numpy Taubin stand-in of the same draw (/tb*).
Usage: study_tables.py adaptive.jsonl let.jsonl [quality.csv]"""
import csv, json, statistics, sys

def anchors(path):
    tb = {}
    for r in csv.DictReader(open(path)):
        if r['model'] == 'normal' and r['method'] == 'taubin_best' and r['ok'] == '1' and r['seed'] == '1':
            tb[(r['mesh'], round(float(r['rho']), 2))] = float(r['ratio'])
    return tb

def rows(path):
    return [json.loads(l) for l in open(path) if l.strip()]

def table(recs, cols, tb, title):
    print('\n' + title + '\n')
    print('| mesh | rho | ' + ' | '.join(c for c, _ in cols) + ' |')
    print('|---|---|' + '---|' * len(cols))
    meds = {c: [] for c, _ in cols}
    for r in recs:
        a = tb.get((r['mesh'], round(r['rho'], 2)))
        cells = []
        for c, f in cols:
            v = f(r)
            q = v / a if a else float('nan')
            meds[c].append(q)
            cells.append('%.3f (%.3f)' % (q, v / r['taubin']))
        print('| %s | %g | %s |' % (r['mesh'], r['rho'], ' | '.join(cells)))
    print('| median | | ' + ' | '.join('%.3f' % statistics.median([x for x in meds[c] if x == x] or [float('nan')])
                                        for c, _ in cols) + ' |')

if __name__ == '__main__':
    tb = anchors(sys.argv[3] if len(sys.argv) > 3 else 'lab/results/quality/issue31-before/quality.csv')
    ad = rows(sys.argv[1])
    table(ad, [('default', lambda r: r['default']), ('one k, SURE', lambda r: r['global_sure']),
               ('one k, oracle', lambda r: r['global_orc'])] +
          [('k per %d, %s' % (P, w), (lambda P, w: lambda r: r['P%d_%s' % (P, w)])(P, w))
           for P in (30, 100, 300) for w in ('sure', 'orc')] +
          [('default or k per 100, oracle', lambda r: r['P100_orc+def'])], tb,
          'Spatially adaptive stopping: over the stored Taubin oracle (over the numpy stand-in)')
    lt = rows(sys.argv[2])
    table(lt, [('default', lambda r: r['default/tb'] * r['taubin']), ('feature', lambda r: r['feature/tb'] * r['taubin']),
               ('oracle LET default+feature', lambda r: r['orc_def+feat/tb'] * r['taubin']),
               ('oracle LET all 9', lambda r: r['orc_all/tb'] * r['taubin']),
               ('SURE-LET default+feature (blind)', lambda r: r['let_def+feat/tb'] * r['taubin'])], tb,
          'SURE-LET over non-linear outputs: over the stored Taubin oracle (over the numpy stand-in)')
