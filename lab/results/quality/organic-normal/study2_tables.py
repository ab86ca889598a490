#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""study2_tables.py - the markdown tables of the s31o section (nonlin_let.py, nonlocal_study.py,
crossfit.py, pick_study.py JSON lines): each figure (error over the input's, numpy draw, seed 1)
divided by make quality's stored Taubin oracle on the same mesh and level (taubin_best / input in
lab/results/quality/issue31-before/quality.csv: the bar's definition), medians over the cases
with an anchor.
Usage: study2_tables.py NONLIN_F.jsonl NONLOCAL.jsonl CROSSFIT.jsonl PICK.jsonl [quality.csv]"""
import statistics, sys
from study_tables import anchors, rows

SUMMARY = []

def table(recs, cols, tb, title):
    print('\n' + title + '\n')
    print('| mesh | rho | ' + ' | '.join(c for c, _ in cols) + ' |')
    print('|---|---|' + '---|' * len(cols))
    meds = {c: [] for c, _ in cols}
    for r in sorted(recs, key=lambda r: (r['mesh'], r['rho'])):
        m = r['mesh'] if r['mesh'].endswith('.obj') else r['mesh'] + '.obj'
        a = tb.get((m, round(r['rho'], 2)))
        cells = []
        for c, k in cols:
            q = r[k] / a if a and k in r else float('nan')
            meds[c].append(q)
            cells.append('%.3f' % q)
        print('| %s | %g | %s |' % (m.replace('.obj', ''), r['rho'], ' | '.join(cells)))
        for (c, _), cell in zip(cols, cells):
            SUMMARY.append((title.split(')')[0] + ') ' + c, m.replace('.obj', ''), r['rho'], float(cell)))
    print('| median (%d with an anchor) | | ' % sum(q == q for q in meds[cols[0][0]]) +
          ' | '.join('%.3f' % statistics.median([x for x in meds[c] if x == x] or [float('nan')]) for c, _ in cols) + ' |')

def summary():
    """Medians over the cases with an anchor: all, per level, per mesh (over its levels)."""
    med = lambda v: '%.3f' % statistics.median(v) if v else 'nan'
    meshes = sorted({m for _, m, _, _ in SUMMARY})
    print('\nSummary: medians over the cases with an anchor (all; per level; per mesh over its levels)\n')
    print('| method | all | 0.1 h | 0.25 h | 0.5 h | ' + ' | '.join(meshes) + ' |')
    print('|---|---|---|---|---|' + '---|' * len(meshes))
    seen = []
    for k, _, _, _ in SUMMARY:
        if k not in seen:
            seen.append(k)
    for k in seen:
        v = [(m, r, q) for kk, m, r, q in SUMMARY if kk == k and q == q]
        cells = [med([q for _, _, q in v])] + [med([q for _, r, q in v if r == L]) for L in (0.1, 0.25, 0.5)]
        cells += [med([q for m, _, q in v if m == M]) for M in meshes]
        print('| %s | %s |' % (k, ' | '.join(cells)))

if __name__ == '__main__':
    tb = anchors(sys.argv[5] if len(sys.argv) > 5 else 'lab/results/quality/issue31-before/quality.csv')
    table(rows(sys.argv[1]), [('default', 'default'), ('linear bands, SURE', 'lin_sure'), ('+ non-linear, SURE', 'nl_sure'),
                              ('+ non-linear, guarded', 'nl_guard'), ('linear bands, oracle', 'lin_orc'),
                              ('+ non-linear, oracle', 'nl_orc'), ('default + all, oracle', 'def+nl_orc')], tb,
          '(1) Pointwise non-linear shrinkage of the implicit step\'s bands (family f)')
    table(rows(sys.argv[2]), [('default', 'default'), ('K 32, oracle', 'nl_oracle_32'), ('K 128, oracle', 'nl_oracle_128'),
                              ('K 32, blind', 'nl_blind_32'), ('K 128, blind', 'nl_blind_128'),
                              ('K 128, blind, shrunk', 'nl_blind_128_a')], tb,
          '(2) Non-local correction of the default by descriptor neighbours')
    table(rows(sys.argv[3]), [('default', 'default'), ('linear, held out', 'lin'), ('all, held out', 'all'),
                              ('default + all, held out', 'all+def'), ('linear, held out, guarded', 'lin_guard'),
                              ('all, held out, guarded', 'all_guard')], tb,
          '(3) Weights learned on the other meshes (leave one mesh out, same level)')
    table(rows(sys.argv[4]), [('default', 'default'), ('SURE-LET f', 'let_f'), ('SURE-LET c', 'let_c'), ('c, oracle', 'orc_c'),
                              ('default or c by SURE', 'pick_def'), ('SURE-LET f+c', 'let_fc'), ('f+c, oracle', 'orc_fc'),
                              ('f+c, weights of the seed-2 oracle', 'orc_fc_x')], tb,
          '(4) Pilot-cotan passes (family c, linear in the noise) against the default, by SURE')
    summary()
