#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""test_contract.py - the three descriptions of the API agree, and hold.

The job parameters are described three times: the table in api/api_params.c
(which validates them; `mcf params` prints it), api/openapi.yaml (REST's
Params schema) and api/mcfd.proto (gRPC's Params message). They are kept
apart on purpose (each file is a hand-written contract, read by people and
served as it is) and held equal here: names, types, choices, ranges and
defaults, field by field, so a change to one that misses another fails with
the field named. Also:
- api/openapi.yaml passes @redocly/cli lint (the version pinned in
  package-lock.json, `make deps` installs it; api/redocly.yaml: the
  recommended rules) with no error and no warning, and the linter does
  catch a broken file;
- one version (mcf, mcfd, openapi.yaml, the Python client) and one licence
  (LICENSE, openapi.yaml's SPDX identifier, the Python client's);
- the Python client's committed gRPC stubs are what api/mcfd.proto gives
  (clients/python/gen_stubs.sh; `make python-stubs` refreshes them).
"""
import json
import os
import re
import subprocess
import sys

import yaml

import testlib
from testlib import BUILD, ROOT, TMP

OPENAPI = os.path.join(ROOT, "api", "openapi.yaml")
PROTO = os.path.join(ROOT, "api", "mcfd.proto")
REDOCLY = os.path.join(ROOT, "node_modules", ".bin", "redocly")


def table():
    r = subprocess.run([os.path.join(BUILD, "mcf"), "params"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


def openapi():
    with open(OPENAPI) as f:
        return yaml.safe_load(f)


def lint(path):
    """(errors, warnings, problems) of redocly lint on path."""
    assert os.access(REDOCLY, os.X_OK), "%s is missing: run make deps (npm ci)" % REDOCLY
    r = subprocess.run([REDOCLY, "lint", "--config", os.path.join(ROOT, "api", "redocly.yaml"),
                        "--format=json", path], capture_output=True, text=True, cwd=TMP)
    doc = json.loads(r.stdout)
    t = doc["totals"]
    assert (r.returncode != 0) == (t["errors"] > 0), (r.returncode, t)
    return t["errors"], t["warnings"], ["%s: %s" % (p["ruleId"], p["message"]) for p in doc["problems"]]


def fmt_num(x):
    return "%g" % x


# ------------------------------------------------------------------ tests

def test_openapi_lint():
    """No error and no warning under redocly's recommended rules."""
    errors, warnings, problems = lint(OPENAPI)
    assert errors == 0 and warnings == 0, "\n".join(problems)


def test_lint_catches_a_broken_file():
    """The linter fails on the mistake the file had: an unquoted comma in a
    flow mapping's description, which YAML splits into a junk key."""
    with open(OPENAPI) as f:
        text = f.read()
    at = text.index("\n  schemas:\n") + len("\n  schemas:\n")
    broken = (text[:at] + "    Broken:\n      type: object\n      properties:\n"
              "        x: {type: string, description: one thing, and another}\n" + text[at:])
    assert "Broken" in yaml.safe_load(broken)["components"]["schemas"]
    path = os.path.join(TMP, "broken.yaml")
    with open(path, "w") as f:
        f.write(broken)
    errors, _, problems = lint(path)
    assert errors >= 1 and any("and another" in p for p in problems), problems


def _branches(prop):
    """(the schema of the value, whether "auto" is allowed) of a Params
    property: oneOf [value, {const: auto}] or a plain schema."""
    if "oneOf" not in prop:
        return prop, False
    vals = [b for b in prop["oneOf"] if not (b.get("const") == "auto" or b.get("enum") == ["auto"])]
    return vals[0], len(vals) < len(prop["oneOf"])


def test_params_openapi():
    """openapi.yaml's Params: the table's names, types, choices, ranges,
    defaults."""
    props = openapi()["components"]["schemas"]["Params"]["properties"]
    rows = table()
    assert [r["name"] for r in rows] == list(props), (
        "names differ: the table has %s, openapi.yaml %s" % ([r["name"] for r in rows], list(props)))
    for r in rows:
        name, prop = r["name"], props[r["name"]]
        assert r.get("help"), "%s: no line in api_params.c's docs[] (its help, unit, default)" % name
        val, auto = _branches(prop)
        assert auto == r["auto"], "%s: 'auto' accepted by the table: %s, by openapi.yaml: %s" % (
            name, r["auto"], auto)
        if r["type"] == "array":
            assert val.get("type") == "array", (name, val)
        else:
            assert val.get("type") == r["type"], "%s: type %s in the table, %s in openapi.yaml" % (
                name, r["type"], val.get("type"))
        assert val.get("enum") == r.get("enum"), "%s: choices %s in the table, %s in openapi.yaml" % (
            name, r.get("enum"), val.get("enum"))
        for bound in ("minimum", "exclusiveMinimum", "maximum"):
            assert val.get(bound) == r.get(bound), "%s: %s %s in the table, %s in openapi.yaml" % (
                name, bound, r.get(bound), val.get(bound))
        want, have = r.get("default"), prop.get("default")
        if want == [] and have is None:     # an empty list: nothing to state
            continue
        assert have == want, "%s: default %r in the table, %r in openapi.yaml" % (name, want, have)


# Parameters mcfd.proto keeps outside Params: the output format is the
# upload header's (SmoothHeader.output_format), beside the input's `format`.
PROTO_ELSEWHERE = {"format": ("SmoothHeader", "output_format")}


def proto_fields(message="Params"):
    """{name: (type, [comment lines])} of a message of mcfd.proto."""
    with open(PROTO) as f:
        text = f.read()
    body = re.search(r"\nmessage %s \{\n(.*?)\n\}\n" % message, text, re.S).group(1)
    fields, comments = {}, []
    for line in body.splitlines():
        line = line.strip()
        if line.startswith("//"):
            comments.append(line[2:].strip())
            continue
        m = re.match(r"(optional |repeated )?(\w+) (\w+) = \d+;", line)
        if m:
            fields[m.group(3)] = (((m.group(1) or "").strip() + " " + m.group(2)).strip(), comments)
            comments = []
    return fields


def proto_line(r):
    """The last comment line the table gives a Params field in mcfd.proto."""
    d = r.get("default", r.get("default_text"))
    d = ("true" if d else "false") if isinstance(d, bool) else "none" if d == [] else \
        fmt_num(d) if isinstance(d, (int, float)) else d
    if r.get("enum"):
        return "One of %s; default: %s." % (", ".join(r["enum"]), d)
    if r["type"] in ("number", "integer"):
        lo = ("(%s" % fmt_num(r["exclusiveMinimum"]) if "exclusiveMinimum" in r
              else "[%s" % fmt_num(r["minimum"]))
        hi = ("%s]" % fmt_num(r["maximum"]) if "maximum" in r
              else "%s]" % r["maximum_limit"] if "maximum_limit" in r
              else "2^64)" if r.get("format") == "uint64" else "inf)")
        return "Range %s, %s%s; default: %s." % (lo, hi, " or auto" if r["auto"] else "", d)
    return "Default: %s." % d


def test_params_proto():
    """mcfd.proto's Params (and SmoothHeader.output_format): the table's
    names and types, each field's last comment line its range (or choices)
    and default."""
    fields = proto_fields()
    rows = table()
    names = [r["name"] for r in rows if r["name"] not in PROTO_ELSEWHERE]
    assert names == list(fields), (
        "names differ: the table has %s, mcfd.proto %s" % (names, list(fields)))
    for r in rows:
        if r["name"] in PROTO_ELSEWHERE:
            message, field = PROTO_ELSEWHERE[r["name"]]
            ptype, comments = proto_fields(message)[field]
        else:
            ptype, comments = fields[r["name"]]
        want = ("NumberOrAuto" if r["auto"] else "repeated uint32" if r["type"] == "array"
                else "optional " + {"number": "double", "boolean": "bool", "string": "string",
                                    "integer": "uint64" if r.get("format") == "uint64"
                                    else "int32"}[r["type"]])
        assert ptype == want, "%s: %s in mcfd.proto, the table's type wants %s" % (
            r["name"], ptype, want)
        line = proto_line(r)
        assert comments and comments[-1] == line, (
            "%s: mcfd.proto's comment should end with\n  // %s\nbut ends with\n  // %s" % (
                r["name"], line, comments[-1] if comments else "(no comment)"))


def test_one_version_one_licence():
    doc = openapi()
    mcf = subprocess.run([os.path.join(BUILD, "mcf"), "--version"], capture_output=True,
                         text=True).stdout.split()
    mcfd = subprocess.run([os.path.join(BUILD, "mcfd"), "--version"], capture_output=True,
                          text=True).stdout.split()
    sys.path.insert(0, os.path.join(ROOT, "clients", "python"))
    import mcfd_client
    with open(os.path.join(ROOT, "clients", "python", "pyproject.toml")) as f:
        pyproject = f.read()
    version = doc["info"]["version"]
    assert mcf[:2] == ["mcf", version] and mcfd[:2] == ["mcfd", version], (mcf, mcfd, version)
    assert mcfd_client.__version__ == version
    assert '\nversion = "%s"\n' % version in pyproject
    with open(os.path.join(ROOT, "LICENSE")) as f:
        assert f.readline() == "MIT License\n"
    assert doc["info"]["license"] == {"name": "MIT", "identifier": "MIT"}, doc["info"]["license"]
    assert 'license = {text = "MIT"}' in pyproject
    with open(os.path.join(ROOT, "package.json")) as f:
        assert json.load(f)["license"] == "MIT"


def test_python_stubs_current():
    """clients/python's committed stubs are what api/mcfd.proto gives now."""
    out = os.path.join(TMP, "stubs")
    r = subprocess.run([os.path.join(ROOT, "clients", "python", "gen_stubs.sh"), out],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    for name in ("mcfd_pb2.py", "mcfd_pb2_grpc.py"):
        with open(os.path.join(out, name), "rb") as a, \
                open(os.path.join(ROOT, "clients", "python", "mcfd_client", "_proto", name), "rb") as b:
            assert a.read() == b.read(), ("clients/python/mcfd_client/_proto/%s is not what "
                                          "api/mcfd.proto gives: run make python-stubs" % name)


if __name__ == "__main__":
    sys.exit(testlib.run_tests([v for k, v in list(globals().items())
                                if k.startswith("test_") and callable(v)]))
