#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""test_layout.py - the README's "Layout" section stays true.

The section is one indented block: an entry starts at the block's left
margin with a path (a file or a folder/), then words that describe it,
continued on lines indented further. The test holds two things:
- every path the block names exists: an entry's own path, and every file
  name or pattern in its description (api_obj.c, svc_*.[ch], bench/),
  looked up under the entry's folder (or the top of the tree);
- every source file of the product and the lab (core/, api/, cli/,
  server/, lab/: .c, .cc, .cpp, .h) is named or matched by a pattern
  there, or lies under a folder the block names (cholmod_serial/, bench/).
So a new, moved or deleted source file fails this test until the README
says where it lives. Cheap: no build, no daemon.
"""
import fnmatch
import os
import re
import subprocess
import sys

from testlib import ROOT, run_tests

README = os.path.join(ROOT, "README.md")
# a file name or pattern (has an extension) or a folder (ends with /)
NAME = re.compile(r"(?<![\w/.*\[\]-])([\w*-][\w*.-]*(?:/[\w*.-]+)*"
                  r"(?:\.(?:\[ch\]|[ch]|cc|cpp|py|mjs|js|sh|md|yaml|proto|json|css|html|svg)(?!\w)|/))")
SOURCES = ("core/", "api/", "cli/", "server/", "lab/")
SOURCE_EXT = (".c", ".cc", ".cpp", ".h")


def layout_block():
    with open(README) as f:
        text = f.read()
    m = re.search(r"^## Layout\n(.*?)^## ", text, re.S | re.M)
    assert m, "README has no Layout section"
    lines = [l for l in m.group(1).split("\n") if l.startswith("    ")]
    assert lines, "the Layout section has no indented block"
    return lines


def names(desc):
    """The file names, patterns and folders a description names (a word
    like HTTP/2 is not a folder: folders are lower case here)."""
    return [n for n in NAME.findall(desc) if not (n.endswith("/") and n != n.lower())]


def entries():
    """[(path, description)] of the block."""
    out = []
    for line in layout_block():
        body = line[4:]
        if body and not body.startswith(" "):
            path, _, desc = body.partition(" ")
            out.append([path, desc])
        else:
            assert out, "a continuation line before the first entry: %r" % line
            out[-1][1] += " " + body.strip()
    return out


def tracked():
    try:
        files = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True,
                               check=True).stdout.split()
    except (OSError, subprocess.CalledProcessError):
        files = []
    if not files:  # not a git checkout: the files on disk
        for d, _, fs in os.walk(ROOT):
            files += [os.path.relpath(os.path.join(d, f), ROOT) for f in fs]
    return [f for f in files if os.path.exists(os.path.join(ROOT, f))]


def matches(pattern, base, files):
    """The tracked files a name or pattern of the entry at base means: a
    folder/ means everything under it; a file name or pattern, any file of
    that name under base (at any depth), or that path from the top."""
    if pattern.endswith("/"):
        pre = [base + pattern, pattern]
        return [f for f in files if any(f.startswith(p) for p in pre)]
    hit = []
    for f in files:
        if not f.startswith(base):
            continue
        rel = f[len(base):]
        if fnmatch.fnmatch(rel, pattern) or fnmatch.fnmatch(os.path.basename(rel), pattern):
            hit.append(f)
    return hit or [f for f in files if fnmatch.fnmatch(f, pattern)]


def test_named_paths_exist():
    files = tracked()
    missing = []
    for path, desc in entries():
        full = os.path.join(ROOT, path)
        if path == "out/":
            continue  # made by the README's examples (ignored by git)
        if not os.path.exists(full):
            missing.append(path)
            continue
        base = path if path.endswith("/") else ""
        for name in names(desc):
            if name in ("build/gen/",) or name.startswith("out/"):
                continue  # made by the build, or by the examples
            if not matches(name, base, files) and not os.path.exists(os.path.join(ROOT, base, name)):
                missing.append("%s (under %s)" % (name, path))
    assert not missing, "the README's Layout names what does not exist: %s" % ", ".join(missing)


def test_every_source_file_is_placed():
    files = tracked()
    covered = set()
    for path, desc in entries():
        base = path if path.endswith("/") else ""
        if not path.endswith("/"):
            covered.add(path)
        for name in names(desc):
            covered.update(matches(name, base, files))
    sources = [f for f in files if f.startswith(SOURCES) and f.endswith(SOURCE_EXT)]
    assert sources, "no source files found under %s" % (SOURCES,)
    unplaced = sorted(f for f in sources if f not in covered)
    assert not unplaced, ("source files the README's Layout does not name (add them, or a "
                          "pattern that matches them): %s" % ", ".join(unplaced))


if __name__ == "__main__":
    sys.exit(run_tests([test_named_paths_exist, test_every_source_file_is_placed]))
