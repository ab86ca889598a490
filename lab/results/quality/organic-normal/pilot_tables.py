#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""pilot_tables.py - the markdown table of the s31p section (pilot_sure.py's JSON lines): each figure
divided by make quality's stored Taubin oracle on the same mesh and level (study2_tables.py's rule),
medians over the cases with an anchor, then the per-level / per-mesh summary.
Usage: pilot_tables.py PILOT.jsonl [quality.csv]"""
import sys
import study2_tables as T
from study_tables import anchors, rows

if __name__ == '__main__':
    tb = anchors(sys.argv[2] if len(sys.argv) > 2 else 'lab/results/quality/issue31-before/quality.csv')
    T.table(rows(sys.argv[1]), [('default', 'default'), ('SURE-LET along n0', 'let_n0'), ('along p', 'let_p'),
                                ('3D', 'let_3d'), ('along p, guarded', 'g_p'), ('3D, guarded', 'g_3d'),
                                ('oracle', 'orc_fc'), ('seed-2 weights', 'orc_fc_x')], tb,
            '(5) SURE-LET over f and c, the risk along the pilot\'s normals p or in 3D')
    T.summary()
