# SPDX-License-Identifier: MIT
# cost_table.py FILE: per case and build, default / better alone (the mode of lower error, imp or
# exp) per round (each the least CPU of REPS runs in one process), the median over the rounds
# (range); the median over the cases of those medians, and per round
import sys, re, statistics as S
rows, order = {}, []
for l in open(sys.argv[1]):
    m = re.match(r"(\S+) r(\d+) (\S+) \S+ ([\d.]+): .*\| default ([\d.]+) .*cpu ([\d.]+) \| imp ([\d.]+) .*cpu ([\d.]+) \| exp ([\d.]+) .*cpu ([\d.]+)", l)
    if not m: continue
    b, rd, mesh, h = m.group(1), int(m.group(2)), m.group(3), m.group(4)
    d, dc, i, ic, e, ec = map(float, m.group(5, 6, 7, 8, 9, 10))
    better, bc = ("imp", ic) if i <= e else ("exp", ec)
    k = (mesh, h)
    if k not in rows: order.append(k)
    rows.setdefault(k, {}).setdefault(b, []).append((rd, dc, bc, better))
builds = sorted({b for v in rows.values() for b in v})
print("| mesh | h | better alone | " + " | ".join("%s: default / better, median (range); CPU s default / better" % b for b in builds) + " |")
print("|---|---|---|" + "---|" * len(builds))
meds = {b: [] for b in builds}
perround = {}
for k in order:
    v = rows[k]
    cells = []
    for b in builds:
        x = v.get(b, [])
        r = [dc / bc for rd, dc, bc, _ in x]
        for rd, dc, bc, _ in x:
            perround.setdefault((b, rd), []).append(dc / bc)
        meds[b].append(S.median(r))
        cells.append("%.2f (%.2f-%.2f); %.3f / %.3f" % (S.median(r), min(r), max(r), S.median(dc for _, dc, _, _ in x), S.median(bc for _, _, bc, _ in x)))
    print("| %s | %s | %s | %s |" % (k[0], k[1], v[builds[0]][0][3], " | ".join(cells)))
for b in builds:
    pr = sorted((rd, S.median(r)) for (bb, rd), r in perround.items() if bb == b)
    print("%s: median over %d cases of the per-case medians %.3f; per round %s" % (b, len(meds[b]), S.median(meds[b]), ", ".join("%.3f" % m for _, m in pr)))
