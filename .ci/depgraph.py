#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""depgraph.py - the graph of a source tree's files: who includes and who calls whom.

A node is a unit: a .c/.cc file together with the header of the same name
beside it (http.c + http.h), or a header with no such source (service.h).
An edge A -> B: A (its source or its header) includes B's header, or A's
object leaves a symbol undefined (nm -u) that B's object defines (a call,
or a use of B's data). Only nodes under the folders given count; the rest
(libc, other layers) are left out.

Printed: nodes, edges, levels (a leaf is level 0; a node is one above the
highest it points to, a cycle counting as one node), the edges inside a
cycle ("upward": each points to a node at the same level, which is what a
cycle's edges do; outside the cycles every edge points down), and the
cycles (strongly connected components of more than one node), with
--edges the edges inside each, with --list every edge and its levels.

    .ci/depgraph.py [--build build] [--edges] [--list] DIR...   e.g. server api
    --fail-on-cycle   exit 1 when there is a cycle (make check-graph uses it)
    --no-recurse      the folders given, without their subfolders
"""
import argparse
import os
import re
import subprocess
import sys
from collections import defaultdict

SRC_EXT = (".c", ".cc")
INC_RE = re.compile(r'^\s*#\s*include\s*"([^"]+)"', re.M)


def files_under(dirs, recurse=True):
    out = []
    for d in dirs:
        for root, subdirs, names in os.walk(d):
            if not recurse:
                subdirs[:] = []
            for n in sorted(names):
                if n.endswith(SRC_EXT + (".h",)):
                    out.append(os.path.normpath(os.path.join(root, n)))
    return sorted(set(out))


def unit_of(path):
    return os.path.splitext(path)[0]


def nm_symbols(obj):
    defined, undefined = set(), set()
    try:
        text = subprocess.run(["nm", obj], capture_output=True, text=True,
                              check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return None
    for line in text.splitlines():
        parts = line.split()
        if len(parts) == 2 and parts[0] == "U":
            undefined.add(parts[1])
        elif len(parts) == 3 and parts[1] in "TDBRVWGS":
            defined.add(parts[2])
    return defined, undefined


def build_graph(dirs, build, recurse=True):
    files = files_under(dirs, recurse)
    units = sorted({unit_of(f) for f in files})
    by_header = defaultdict(list)          # a header's name -> its units
    for f in files:
        if f.endswith(".h"):
            by_header[os.path.basename(f)].append(unit_of(f))
    edges = defaultdict(set)               # (a, b) -> {"inc", "call"}
    for f in files:
        a = unit_of(f)
        with open(f, encoding="utf-8", errors="replace") as fh:
            for inc in INC_RE.findall(fh.read()):
                for b in by_header.get(os.path.basename(inc), []):
                    if b != a:
                        edges[(a, b)].add("inc")
    syms = {}
    missing = []
    for f in files:
        if f.endswith(SRC_EXT):
            s = nm_symbols(os.path.join(build, os.path.splitext(f)[0] + ".o"))
            if s is None:
                missing.append(f)
            else:
                syms[unit_of(f)] = s
    owner = {}
    for u, (d, _) in syms.items():
        for s in d:
            owner[s] = u
    for a, (_, und) in syms.items():
        for s in und:
            b = owner.get(s)
            if b and b != a:
                edges[(a, b)].add("call")
    return units, edges, missing


def sccs(nodes, succ):
    """Tarjan's, iterative."""
    index, low, on, stack, out = {}, {}, set(), [], []
    counter = [0]
    for root in nodes:
        if root in index:
            continue
        work = [(root, iter(sorted(succ[root])))]
        index[root] = low[root] = counter[0]; counter[0] += 1
        stack.append(root); on.add(root)
        while work:
            v, it = work[-1]
            advanced = False
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter[0]; counter[0] += 1
                    stack.append(w); on.add(w)
                    work.append((w, iter(sorted(succ[w]))))
                    advanced = True
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            if advanced:
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop(); on.discard(w); comp.append(w)
                    if w == v:
                        break
                out.append(sorted(comp))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="+")
    ap.add_argument("--build", default="build")
    ap.add_argument("--list", action="store_true", help="print every edge")
    ap.add_argument("--edges", action="store_true",
                    help="print the edges inside each cycle")
    ap.add_argument("--fail-on-cycle", action="store_true")
    ap.add_argument("--no-recurse", action="store_true",
                    help="the folders' own files, not their subfolders'")
    args = ap.parse_args()
    units, edges, missing = build_graph(args.dirs, args.build,
                                        not args.no_recurse)
    if missing:
        print("depgraph: no object for %s (build first: make)" % " ".join(missing),
              file=sys.stderr)
        return 2
    succ = defaultdict(set)
    for a, b in edges:
        succ[a].add(b)
    comps = sccs(units, succ)
    comp_of = {u: i for i, c in enumerate(comps) for u in c}
    level = {}
    for i, c in enumerate(comps):          # Tarjan emits sinks first
        lv = 0
        for u in c:
            for w in succ[u]:
                j = comp_of[w]
                if j != i:
                    lv = max(lv, level[j] + 1)
        level[i] = lv
    cycles = [c for c in comps if len(c) > 1]
    inside = [(a, b) for (a, b) in edges if comp_of[a] == comp_of[b]]
    print("%s: %d nodes, %d edges, %d levels, %d upward (inside a cycle), %d cycles"
          % (" ".join(args.dirs), len(units), len(edges),
             1 + max(level.values(), default=-1), len(inside), len(cycles)))
    for c in cycles:
        print("  cycle of %d: %s" % (len(c), " ".join(c)))
        for a, b in sorted(inside) if args.edges else []:
            if a in c:
                print("    %s -> %s (%s)" % (a, b, ",".join(sorted(edges[(a, b)]))))
    if args.list:
        for (a, b) in sorted(edges):
            print("%-40s -> %-40s %s L%d->L%d" % (a, b, ",".join(sorted(edges[(a, b)])),
                                                level[comp_of[a]], level[comp_of[b]]))
    return 1 if (args.fail_on_cycle and cycles) else 0


if __name__ == "__main__":
    sys.exit(main())
