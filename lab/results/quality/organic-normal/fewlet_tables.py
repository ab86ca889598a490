#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""fewlet_tables.py - the markdown tables of the s31o3 section (fewlet_study.py, ridgecv_study.py,
wiener_study.py JSON lines): each figure divided by make quality's stored Taubin oracle on the same
mesh and level (study2_tables.py's rule), then per column the median over the cases with an
anchor, how many cases it beats or loses to the default, and its worst ratio to the default.
Usage: fewlet_tables.py FILE.jsonl COL[,COL..] [quality.csv]"""
import sys
import numpy as np
from study_tables import anchors, rows

if __name__ == '__main__':
    tb = anchors(sys.argv[3] if len(sys.argv) > 3 else 'lab/results/quality/issue31-before/quality.csv')
    cols = sys.argv[2].split(',')
    recs = [r for r in rows(sys.argv[1]) if (r['mesh'] + '.obj', round(r['rho'], 2)) in tb]
    print('| mesh | rho | ' + ' | '.join(cols) + ' |')
    print('|---|---|' + '---|' * len(cols))
    v = {c: [] for c in cols}
    for r in recs:
        a = tb[(r['mesh'] + '.obj', round(r['rho'], 2))]
        for c in cols:
            v[c].append(r[c] / a)
        print('| %s | %g | ' % (r['mesh'], r['rho']) + ' | '.join('%.3f' % (r[c] / a) for c in cols) + ' |')
    d = np.array(v['default'])
    for lab, f in (('median (%d with an anchor)' % len(recs), lambda x: '%.3f' % np.median(x)),
                   ('wins / losses against the default', lambda x: '%d / %d' % (np.sum(x < d - 1e-4), np.sum(x > d + 1e-4))),
                   ('worst ratio to the default', lambda x: '%.3f' % np.max(x / d))):
        print('| %s | | ' % lab + ' | '.join(f(np.array(v[c])) for c in cols) + ' |')
