#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""picktable.py PICK.jsonl - the markdown table of pickbench.py's records: per case the
error (of the input's; clean: of the mean edge) and the median CPU of the default (pick),
of the default with the implicit filter alone (I) and with the passes alone (E), which
filter the default took, and its CPU over the better filter's alone."""
import json, statistics, sys
rows, ratios, ri = [], [], []
print("| mesh | noise (h) | error pick | I | E | pick took | CPU pick | I | E | pick / better | pick / I |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
for l in open(sys.argv[1]):
    r = json.loads(l)
    p, i, e = r["pick/default"], r["I/default"], r["E/default"]
    ref = p["in"] or p["h"]
    # the better by error; equal errors (to 1e-9 relative): the cheaper
    tie = abs(i["err"] - e["err"]) <= 1e-9 * max(i["err"], e["err"])
    better = (i if i["cpu"] <= e["cpu"] else e) if tie else i if i["err"] < e["err"] else e
    ratio = p["cpu"] / better["cpu"]
    if r["level"] != "clean":
        ratios.append(ratio)
        ri.append(p["cpu"] / i["cpu"])
    print("| %s | %s | %.4f | %.4f | %.4f | %s | %.2f | %.2f | %.2f | %.2f | %.2f |" % (
        r["mesh"], r["level"], p["err"] / ref, i["err"] / ref, e["err"] / ref,
        "E" if p["fex"] else "I", p["cpu"], i["cpu"], e["cpu"], ratio, p["cpu"] / i["cpu"]))
print("\nnoisy cases %d: pick / better filter's CPU median %.2f, range %.2f-%.2f; pick / I median %.2f, range %.2f-%.2f" % (
    len(ratios), statistics.median(ratios), min(ratios), max(ratios), statistics.median(ri), min(ri), max(ri)))
