#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""pickbench.py OUT.jsonl NAME=BIN [NAME=BIN ...] - per case (in/MESH_nRHO.ply or
in/MESH_clean.ply against in/MESH_clean.ply), each `mcf` build BIN with each request of
VARS (default: the default request, `--scheme fairing`, `--scheme fairing_explicit`;
README.md ran VARS=default with three builds): the error and the filter taken from one
run with --target and --metrics, the CPU (user+sys of the child, --threads 1) the median
of REPS (3) rounds of the builds interleaved, without metrics. Env MESHES, LEVELS, REPS,
VARS narrow it. Appends one JSON record per case to OUT.jsonl."""
import json, os, subprocess, sys, statistics
out = sys.argv[1]
bins = dict(a.split("=", 1) for a in sys.argv[2:] if "=" in a)
MESHES = os.environ.get("MESHES", "armadillo stanford-bunny bunny spot fertility knot1 bunny_npm_closed sphere_cgal snowden car blade couplingdown_sub2").split()
LEVELS = os.environ.get("LEVELS", "0.1 0.25 0.5 clean").split()
REPS = int(os.environ.get("REPS", "3"))
VARS = {"default": [], "fairing": ["--scheme", "fairing"], "explicit": ["--scheme", "fairing_explicit"]}
VARS = {k: v for k, v in VARS.items() if k in os.environ.get("VARS", "default fairing explicit").split()}
def run(b, args):
    p = subprocess.Popen([b, "smooth"] + args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, st, ru = os.wait4(p.pid, 0)
    assert os.waitstatus_to_exitcode(st) in (0,), args
    return ru.ru_utime + ru.ru_stime
with open(out, "a") as fo:
    for m in MESHES:
        for lv in LEVELS:
            inp = "in/%s_clean.ply" % m if lv == "clean" else "in/%s_n%s.ply" % (m, lv)
            rec = {"mesh": m, "level": lv}
            cpu = {}
            for bn, b in bins.items():
                for vn, va in VARS.items():
                    mj = "m_%s_%s.json" % (bn, vn)
                    run(b, [inp, "o_%s.ply" % bn, "--threads", "1", "--target", "in/%s_clean.ply" % m, "--metrics", mj] + va)
                    d = json.load(open(mj))
                    fl = d["flow"]
                    rec["%s/%s" % (bn, vn)] = {"err": d["compare"]["after"]["rms_m"], "in": d["compare"]["before"]["rms_m"],
                        "h": d["input"]["info"]["edge_length"]["mean"], "filter": fl.get("filter"), "steps": fl.get("steps"),
                        "fex": fl.get("filter_explicit"), "feature": fl.get("feature")}
                    cpu["%s/%s" % (bn, vn)] = []
            for r in range(REPS):
                for k in cpu:
                    bn, vn = k.split("/")
                    cpu[k].append(run(bins[bn], [inp, "o_%s.ply" % bn, "--threads", "1"] + VARS[vn]))
            for k in cpu:
                rec[k]["cpu"] = statistics.median(cpu[k]); rec[k]["cpus"] = cpu[k]
            fo.write(json.dumps(rec) + "\n"); fo.flush()
            print(m, lv, " ".join("%s %.4f %.2fs %s" % (k, rec[k]["err"] / (rec[k]["in"] or rec[k]["h"]), rec[k]["cpu"], rec[k]["filter"]) for k in cpu), flush=True)
