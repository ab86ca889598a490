#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""join.py OUT.csv NEW1.csv [NEW2.csv ...]: the new runs' default rows, and the stored
anchors (issue31-before/quality.csv: every method but default) for the cases the new
runs have; one CSV for bench_quality --tables-from."""
import csv, sys
ANCH = 'lab/results/quality/issue31-before/quality.csv'  # run from the repository root
out, news = sys.argv[1], sys.argv[2:]
rows, hdr = {}, None
key = lambda r: (r['mesh'], r['model'], r['rho'], r['seed'])
have = set()
for p in news:
    with open(p) as f:
        rd = csv.DictReader(f); hdr = hdr or rd.fieldnames
        for r in rd:
            if r['method'] == 'default':
                rows[key(r)] = r; have.add(key(r))  # a case run twice: the later file's
with open(ANCH) as f:
    rd = csv.DictReader(f)
    anch = [r for r in rd if r['method'] != 'default' and key(r) in have]
with open(out, 'w', newline='') as f:
    w = csv.DictWriter(f, fieldnames=hdr, quoting=csv.QUOTE_MINIMAL, lineterminator='\n')
    w.writeheader()
    for r in anch + list(rows.values()):
        w.writerow({k: r.get(k, '') for k in hdr})
print(f'{len(rows)} default rows, {len(anch)} anchor rows, {len(have)} cases')
