#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""test_readme.py - the README's examples run as shown.

The README marks each code block: `<!-- example -->` (a shell script that
needs no daemon), `<!-- example: daemon -->` (one that talks to `make run`'s
daemon on 127.0.0.1:8080, gRPC 50051), `<!-- example: in_process -->` (one
that loads the C library into Python: under a sanitizer build, MCF_SAN set,
it is skipped and says so, as tests/test_pymcf.py is, since an instrumented
library needs its runtime preloaded into Python) or `<!-- not run: WHY -->`. This test
finds every marked block, whatever the README holds when it runs, and runs
the examples in order with bash (set -eo pipefail) from the top of a fresh
copy of the tree (the tracked files, committed into a scratch git
repository) with the environment the test was given (no PATH of its own:
an example that says `mcf` where it needs `build/mcf` fails here as it fails
for a newcomer), the copy's build/ being this build (what the README's
set-up, `make run`, leaves there), against a real daemon it starts on free
loopback ports (the blocks' 8080 and 50051 are rewritten to them). Then:
- every block exits 0;
- every mesh an example names under out/ exists, decodes (`mcf info`) and
  is worth looking at: it has the vertices (or faces) of the repository
  mesh it came from, and keeps at least half of that mesh's size and area
  (the old async example returned a sphere shrunk to a point);
- the examples left nothing but ignored files behind (`git status`);
- a block that runs one of the project's commands carries a marker.
"""
import json
import os
import re
import shutil
import subprocess
import sys

import testlib
from testlib import BUILD, ROOT, TMP, Daemon

README = os.path.join(ROOT, "README.md")
MARK = re.compile(r"^\s*<!--\s*(example(?::\s*(\w+))?|not run:.*?)\s*-->\s*$")
COMMAND = re.compile(r"^(sudo |\S+=\S+ )*(curl|mcf|mcfd|build/mcfd?|make|podman|docker|"
                     r"/usr/bin/python3|python3|out/venv/bin/\S+)(\s|$)")
MESH_OUT = re.compile(r"\bout/[\w.-]+\.(?:obj|drc|ply|stl|off)\b")
COPY = os.path.join(TMP, "clone")


def blocks(text):
    """[(line number, marker or None, code)] of every code block: fenced, or
    indented by 4 spaces (more in a list item) after a blank line."""
    lines = text.split("\n")
    out, marker, i = [], None, 0
    while i < len(lines):
        line = lines[i]
        m = MARK.match(line)
        if m:
            marker = m.group(1)
            i += 1
            continue
        fence = re.match(r"^(\s*)```", line)
        if fence:
            j = i + 1
            while j < len(lines) and not lines[j].strip().startswith("```"):
                j += 1
            body = [x[len(fence.group(1)):] for x in lines[i + 1:j]]
            out.append((i + 1, marker, "\n".join(body)))
            marker, i = None, j + 1
            continue
        ind = len(line) - len(line.lstrip(" "))
        if line.strip() and ind >= 4 and (i == 0 or not lines[i - 1].strip()):
            j = i
            while j < len(lines) and (not lines[j].strip() or lines[j].startswith(" " * ind)):
                j += 1
            while not lines[j - 1].strip():
                j -= 1
            out.append((i + 1, marker, "\n".join(x[ind:] for x in lines[i:j])))
            marker, i = None, j
            continue
        if line.strip():
            marker = None if not m else marker
        i += 1
    return out


def fresh_copy():
    """The tracked files as they are now, committed into a new repository."""
    r = subprocess.run(["git", "-C", ROOT, "ls-files", "-z"], capture_output=True)
    if r.returncode == 0:
        for f in r.stdout.decode().split("\0"):
            if f and os.path.isfile(os.path.join(ROOT, f)):
                os.makedirs(os.path.dirname(os.path.join(COPY, f)), exist_ok=True)
                shutil.copy2(os.path.join(ROOT, f), os.path.join(COPY, f))
    else:                                   # not a git checkout: all but what builds make
        shutil.copytree(ROOT, COPY, ignore=shutil.ignore_patterns(
            "build*", "var", "node_modules", "*.o", "*.d", ".git"))
        for f in os.listdir(os.path.join(COPY, "out")):
            if f != ".gitignore":
                shutil.rmtree(os.path.join(COPY, "out", f), ignore_errors=True)
    git = ["git", "-c", "user.name=t", "-c", "user.email=t@t", "-C", COPY]
    for args in (["init", "-q"], ["add", "-A"], ["commit", "-q", "-m", "copy"]):
        subprocess.run(git + args, check=True, capture_output=True)


def info(path):
    r = subprocess.run([os.path.join(BUILD, "mcf"), "info", path], capture_output=True, text=True)
    assert r.returncode == 0, "%s does not decode: %s" % (path, r.stderr)
    return json.loads(r.stdout)


def size(i):
    lo, hi = i["bbox"]["min"], i["bbox"]["max"]
    return sum((b - a) ** 2 for a, b in zip(lo, hi)) ** 0.5


def test_examples_run():
    with open(README) as f:
        found = blocks(f.read())
    unmarked = [(n, code.split("\n")[0]) for n, mark, code in found
                if mark is None and any(COMMAND.match(x) for x in code.split("\n"))]
    assert not unmarked, ("README blocks with commands but no marker (add <!-- example -->, "
                          "<!-- example: daemon --> or <!-- not run: why --> before them): %s"
                          % unmarked)
    examples = [(n, mark, code) for n, mark, code in found if mark and mark.startswith("example")]
    assert len(examples) >= 5, examples
    fresh_copy()
    os.symlink(os.path.abspath(BUILD), os.path.join(COPY, "build"))
    env = dict(os.environ)
    if os.environ.get("MCF_SAN"):
        # a sanitizer build has no libmcfpy.so: `pip install ./clients/python`
        # would run `make pylib` in the copy, whose build/ is this build
        # directory (the symlink above), for minutes; the package installs
        # without the in-process library, as the in_process example is not run
        env["MCF_LIBRARY"] = os.path.join(TMP, "no-libmcfpy-under-san.so")
    daemon = Daemon("readme", "--workers", "2")
    try:
        for n, mark, code in list(examples):
            if mark.endswith("in_process") and os.environ.get("MCF_SAN"):
                print("README line %d (%s): not run under MCF_SAN=%s (an instrumented "
                      "libmcfpy.so needs its runtime preloaded into Python)"
                      % (n, mark, os.environ["MCF_SAN"]), flush=True)
                examples.remove((n, mark, code))
                continue
            if mark.endswith("daemon"):
                code = re.sub(r"\b(127\.0\.0\.1|localhost):8080\b", "127.0.0.1:%d" % daemon.port, code)
                code = re.sub(r"\b(127\.0\.0\.1|localhost):50051\b", "127.0.0.1:%d" % daemon.gport,
                              code)
            r = subprocess.run(["bash", "-c", "set -eo pipefail\n" + code], cwd=COPY, env=env,
                               capture_output=True, text=True, timeout=300)
            print("README line %d (%s): exit %d" % (n, mark, r.returncode), flush=True)
            assert r.returncode == 0, "README line %d exits %d:\n%s\nstdout:\n%s\nstderr:\n%s" % (
                n, r.returncode, code, r.stdout[-2000:], r.stderr[-2000:])
    finally:
        daemon.stop()
    # the meshes the examples write, against the repository's meshes they came from
    repo = [info(os.path.join(COPY, "tests", "data", "meshes", f))
            for f in sorted(os.listdir(os.path.join(COPY, "tests", "data", "meshes")))
            if f.endswith((".obj", ".drc", ".ply", ".stl", ".off"))]
    named = sorted(set(m for _, _, code in examples for m in MESH_OUT.findall(code)))
    assert named, "no example writes a mesh into out/"
    for rel in named:
        path = os.path.join(COPY, rel)
        assert os.path.exists(path), "%s: named by an example, not written" % rel
        got = info(path)
        src = [m for m in repo if m["vertices"] == got["vertices"] or m["faces"] == got["faces"]]
        assert src, "%s: %d vertices, %d faces: of no repository mesh" % (
            rel, got["vertices"], got["faces"])
        ratio = max(size(got) / size(m) for m in src)
        area = max(got["area"] / m["area"] for m in src)
        print("  %s: %d vertices, size x %.3f, area x %.3f" % (rel, got["vertices"], ratio, area))
        assert ratio > 0.5 and area > 0.5, "%s: shrunk to x %.3g of its size, x %.3g of its area" % (
            rel, ratio, area)
    r = subprocess.run(["git", "-C", COPY, "status", "--porcelain"], capture_output=True, text=True)
    assert r.stdout == "", "the examples left files git does not ignore:\n" + r.stdout


if __name__ == "__main__":
    sys.exit(testlib.run_tests([test_examples_run]))
