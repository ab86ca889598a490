# SPDX-License-Identifier: MIT
# share_table.py FILE: per case and build, the default's CPU over the default without its explicit
# run (total / (total - ce)), median over the runs (range), and the median over the cases
import sys, statistics as S
rows = {}
for l in open(sys.argv[1]):
    f = l.split()
    if len(f) != 5: continue
    b, m, r, ce, tot = f[0], f[1], f[2], float(f[3]), float(f[4])
    rows.setdefault((m, r), {}).setdefault(b, []).append((ce, tot))
builds = sorted({b for v in rows.values() for b in v})
meds = {b: [] for b in builds}
print("| mesh | h | " + " | ".join("%s: explicit run CPU s, default / without it (range)" % b for b in builds) + " |")
print("|---|---|" + "---|" * len(builds))
for (m, r), v in rows.items():
    cells = []
    for b in builds:
        x = v.get(b, [])
        if not x: cells.append("-"); continue
        rat = [t / (t - c) for c, t in x]
        ce = S.median(c for c, t in x)
        meds[b].append(S.median(rat))
        cells.append("%.4f, %.3f (%.3f-%.3f)" % (ce, S.median(rat), min(rat), max(rat)))
    print("| %s | %s | %s |" % (m, r, " | ".join(cells)))
for b in builds:
    print("%s: median over %d cases %.3f" % (b, len(meds[b]), S.median(meds[b])))
