# SPDX-License-Identifier: MIT
"""testlib.py - what the Python tests of mcfd share (testlib.c's counterpart).

- paths: ROOT (the top of the tree), BUILD ($MCF_BUILD, default build/),
  DATA ($MCF_TESTDATA, default tests/data), TMP (a scratch folder removed
  at exit);
- Daemon: one `mcfd --bind 127.0.0.1 --port 0 --grpc-port 0` on a spool in
  TMP, in a process group of its own that is SIGKILLed whatever happens
  (atexit, signals, a failing test); stop() checks a clean exit;
- run_tests: cmocka's output format ([ RUN ], [ OK ], [ PASSED ] N test(s),
  ...), which `make test` counts; MCF_TEST_FILTER=name runs one test;
  tl_skip-like skips (SkipTest) are logged to $MCF_SKIP_LOG.

Run with Debian's /usr/bin/python3 (its numpy, grpcio and yaml).
"""
import atexit
import os
import select
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import traceback

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BUILD = os.path.abspath(os.environ.get("MCF_BUILD") or os.path.join(ROOT, "build"))
DATA = os.environ.get("MCF_TESTDATA") or os.path.join(ROOT, "tests", "data")
TMP = tempfile.mkdtemp(prefix="mcfd-pytest-")
_CHILDREN = []


def _cleanup():
    for p in _CHILDREN:
        if p.poll() is None:
            try:
                os.killpg(p.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            p.wait()
    shutil.rmtree(TMP, ignore_errors=True)


atexit.register(_cleanup)
for _s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT):
    signal.signal(_s, lambda s, f: (_cleanup(), os._exit(128 + s)))


def track(p):
    """Kills p's process group at exit (p started with start_new_session)."""
    _CHILDREN.append(p)
    return p


class SkipTest(Exception):
    """Raised by a test that cannot run here: tag and reason are logged."""

    def __init__(self, tag, why):
        super().__init__(why)
        self.tag = tag


class Daemon:
    """One mcfd (BUILD's, or binary) on loopback with free ports: .port
    (REST), .gport (gRPC), .url (http://...), .grpc_url (grpc://...)."""

    def __init__(self, name, *flags, binary=None):
        self.name = name
        self.logpath = os.path.join(TMP, name + ".log")
        with open(self.logpath, "ab") as log:
            self.p = track(subprocess.Popen(
                [binary or os.path.join(BUILD, "mcfd"), "--bind", "127.0.0.1", "--port", "0",
                 "--grpc-port", "0", "--spool", os.path.join(TMP, name), *flags],
                stdout=subprocess.PIPE, stderr=log, start_new_session=True))
        lines = self._lines(2, 30)
        try:
            self.port = int(lines[0].rsplit(":", 1)[1])
            self.gport = int(lines[1].rsplit(":", 1)[1])
        except (IndexError, ValueError):
            self.kill()
            raise AssertionError("%s did not start: stdout %r, log %s" % (name, lines, self.log_tail()))
        self.url = "http://127.0.0.1:%d" % self.port
        self.grpc_url = "grpc://127.0.0.1:%d" % self.gport

    def _lines(self, n, timeout):
        buf, end = b"", time.time() + timeout
        fd = self.p.stdout.fileno()
        while buf.count(b"\n") < n and time.time() < end:
            if select.select([fd], [], [], 0.2)[0]:
                chunk = os.read(fd, 4096)
                if not chunk:
                    break
                buf += chunk
        return buf.decode(errors="replace").splitlines()

    def log_tail(self):
        with open(self.logpath, "rb") as f:
            return f.read()[-2000:].decode(errors="replace")

    def stop(self, timeout=40):
        self.p.send_signal(signal.SIGTERM)
        try:
            rc = self.p.wait(timeout)
        except subprocess.TimeoutExpired:
            self.kill()
            raise AssertionError("%s did not exit within %d s of SIGTERM" % (self.name, timeout))
        assert rc == 0, "%s exited with %d after SIGTERM: %s" % (self.name, rc, self.log_tail())

    def kill(self):
        try:
            os.killpg(self.p.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        self.p.wait()


def run_tests(tests, setup=None, teardown=None):
    """Runs the test functions in cmocka's format; returns the exit status.
    setup() runs first (its failure fails every test), teardown() last."""
    flt = os.environ.get("MCF_TEST_FILTER")
    tests = [t for t in tests if not flt or t.__name__ == flt]
    print("[==========] Running %d test(s)." % len(tests), flush=True)
    failed, skipped = [], []
    try:
        if setup:
            setup()
    except Exception:  # noqa: BLE001
        traceback.print_exc(file=sys.stdout)
        print("[  FAILED  ] %d test(s), listed below:" % len(tests))
        for t in tests:
            print("[  FAILED  ] %s" % t.__name__)
        return 1
    for t in tests:
        print("[ RUN      ] %s" % t.__name__, flush=True)
        t0 = time.time()
        try:
            t()
            print("[       OK ] %s (%.1f s)" % (t.__name__, time.time() - t0), flush=True)
        except SkipTest as e:
            print("%s: skipped: %s" % (t.__name__, e), flush=True)
            print("[  SKIPPED ] %s" % t.__name__, flush=True)
            skipped.append(t.__name__)
            log = os.environ.get("MCF_SKIP_LOG")
            if log:
                with open(log, "a") as f:
                    f.write("%s\t%s\n" % (e.tag, e))
        except Exception:  # noqa: BLE001
            traceback.print_exc(file=sys.stdout)
            print("[  FAILED  ] %s" % t.__name__, flush=True)
            failed.append(t.__name__)
    try:
        if teardown:
            teardown()
    except Exception as e:  # noqa: BLE001
        print("[  ERROR   ] %s" % e)
        failed.append("teardown")
    print("[==========] %d test(s) run." % len(tests))
    print("[  PASSED  ] %d test(s)." % (len(tests) - len(skipped) -
                                      len([f for f in failed if f != "teardown"])))
    if skipped:
        print("[  SKIPPED ] %d test(s), listed below:" % len(skipped))
        for s in skipped:
            print("[  SKIPPED ] %s" % s)
    if failed:
        print("[  FAILED  ] %d test(s), listed below:" % len(failed))
        for f in failed:
            print("[  FAILED  ] %s" % f)
    return 1 if failed else 0
