#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""ridgegate_tables.py - the s31o4 section's table of the ridge toward the default gated by the
noise level (ridgecv_study.py JSON lines): per case the default, the ridge with L by block
cross-validation (cv_block) and the gated form (cv_block below GATE h, default from it on),
each over Taubin's stored oracle (outrule_tables.py's anchors: issue31-before, then this
folder's baseline-*.csv), then medians and wins / losses against the default (by more than 0.1%).
BAR=1: only the cases issue31-before has an anchor for (the bar's 17 organic cases).
Usage: ridgegate_tables.py FILE.jsonl [GATE (0.4)] [COL (cv_block)]"""
import json, sys
import numpy as np
import os
from outrule_tables import anchor, in_before

def main():
    gate = float(sys.argv[2]) if len(sys.argv) > 2 else 0.4
    col = sys.argv[3] if len(sys.argv) > 3 else 'cv_block'
    recs = [json.loads(l) for l in open(sys.argv[1])]
    keys = in_before if os.environ.get('BAR') else anchor  # BAR=1: issue31-before's cases only
    recs = [r for r in recs if (r['mesh'] + '.obj', round(r['rho'], 2)) in keys]
    print('| mesh | rho | default | ridge, L by block CV (L) | gated at %g h |' % gate)
    print('|---|---|---|---|---|')
    d, c, g = [], [], []
    for r in recs:
        a = anchor[(r['mesh'] + '.obj', round(r['rho'], 2))]
        d.append(r['default'] / a)
        c.append(r[col] / a)
        g.append((r[col] if r['rho'] < gate else r['default']) / a)
        print('| %s | %g | %.3f | %.3f (%s) | %.3f |' % (r['mesh'], r['rho'], d[-1], c[-1], r['L_block'], g[-1]))
    d, c, g = map(np.array, (d, c, g))
    print('| **median (%d)** | | %.3f | %.3f | %.3f |' % (len(d), np.median(d), np.median(c), np.median(g)))
    print('| wins / losses | | | %d / %d | %d / %d |' % (np.sum(c < d * 0.999), np.sum(c > d * 1.001),
                                                         np.sum(g < d * 0.999), np.sum(g > d * 1.001)))
    print('| worst / default | | | %.3f | %.3f |' % (np.max(c / d), np.max(g / d)))

if __name__ == '__main__':
    main()
