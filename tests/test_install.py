#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""test_install.py - `make install` and `make uninstall` into a DESTDIR: mcf
and mcfd land in PREFIX/bin with their man pages (made from their --help)
and the licence and API contracts in PREFIX/share/doc/mcfd; the installed
programs run by their bare names from PATH (mcf smooths a mesh, mcfd serves
its embedded OpenAPI document); uninstall leaves nothing behind.

The sub-make uses this build ($MCF_BUILD, $MCF_SAN as `make test` passes
them), so nothing is rebuilt but the man pages.
"""
import os
import subprocess
import sys
import urllib.request

import testlib
from testlib import BUILD, DATA, ROOT, TMP, Daemon
from noisy import noisy_obj

DEST = os.path.join(TMP, "root")
PREFIX = "/opt/mcfd-test"


def make(*targets):
    env = {k: v for k, v in os.environ.items() if k not in ("MAKEFLAGS", "MFLAGS", "MAKELEVEL")}
    args = ["make", "-s", "--no-print-directory", "B=" + os.path.relpath(BUILD, ROOT),
            "DESTDIR=" + DEST, "PREFIX=" + PREFIX, *targets]
    if os.environ.get("MCF_SAN"):
        args.append("SAN=" + os.environ["MCF_SAN"])
    r = subprocess.run(args, cwd=ROOT, env=env, capture_output=True, text=True)
    assert r.returncode == 0, "make %s: %s%s" % (" ".join(targets), r.stdout, r.stderr)


def installed():
    return sorted(os.path.relpath(os.path.join(d, f), DEST)
                  for d, _, fs in os.walk(DEST) for f in fs)


def test_install_run_uninstall():
    make("install")
    want = ["opt/mcfd-test/bin/mcf", "opt/mcfd-test/bin/mcfd",
            "opt/mcfd-test/share/doc/mcfd/LICENSE", "opt/mcfd-test/share/doc/mcfd/mcfd.proto",
            "opt/mcfd-test/share/doc/mcfd/openapi.yaml",
            "opt/mcfd-test/share/doc/mcfd/three.js-LICENSE",
            "opt/mcfd-test/share/man/man1/mcf.1", "opt/mcfd-test/share/man/man1/mcfd.1"]
    assert installed() == want, installed()
    bindir = DEST + PREFIX + "/bin"
    for prog in ("mcf", "mcfd"):
        assert os.access(os.path.join(bindir, prog), os.X_OK), prog
    env = dict(os.environ, PATH=bindir + ":/usr/bin:/bin")
    # `mcf` as the README writes it: a bare command from PATH
    r = subprocess.run(["mcf", "--version"], env=env, capture_output=True, text=True)
    assert r.returncode == 0 and r.stdout.startswith("mcf "), (r.stdout, r.stderr)
    out = os.path.join(TMP, "s.obj")
    # noise to remove: on the clean sphere the automatic amount runs no step
    noisy = os.path.join(TMP, "noisy.obj")
    with open(noisy, "wb") as f:
        f.write(noisy_obj(os.path.join(DATA, "meshes", "sphere_cgal.obj"), 0.25, 1))
    r = subprocess.run(["mcf", "smooth", noisy, out], env=env, capture_output=True, text=True, cwd=TMP)
    assert r.returncode == 0, r.stderr
    # the default request: the fairing filter (a clean sphere: no noise to remove)
    assert "812 vertices, fairing " in r.stderr, r.stderr
    r = subprocess.run(["mcfd", "--version"], env=env, capture_output=True, text=True)
    assert r.returncode == 0 and r.stdout.startswith("mcfd "), r.stdout
    # the installed daemon needs no file beside it: its OpenAPI document is embedded
    d = Daemon("installed", binary=os.path.join(bindir, "mcfd"))
    try:
        with urllib.request.urlopen(d.url + "/openapi.yaml", timeout=30) as resp:
            assert resp.read().startswith(b"openapi: 3.1")
    finally:
        d.stop()
    # the man pages are the programs' --help, every command's
    with open(DEST + PREFIX + "/share/man/man1/mcf.1") as f:
        page = f.read()
    assert page.startswith(".TH mcf 1 ")
    for cmd in ("smooth", "info", "schemes", "params", "convert"):
        assert '.SH "mcf %s"' % cmd in page, cmd
    helptext = subprocess.run(["mcf", "smooth", "--help"], env=env, capture_output=True,
                              text=True).stdout
    for line in helptext.splitlines():
        if line and not line.startswith((".", "'")):
            assert line.replace("\\", "\\e") in page, line
    with open(DEST + PREFIX + "/share/man/man1/mcfd.1") as f:
        assert "--max-upload" in f.read()
    make("uninstall")
    assert installed() == [], installed()


if __name__ == "__main__":
    sys.exit(testlib.run_tests([test_install_run_uninstall]))
