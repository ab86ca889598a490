# SPDX-License-Identifier: MIT
"""mcfd_client._rest - one smoothing job through the REST door (urllib only).

POST /v1/smooth with a multipart body: the mesh, the parameters as the JSON
`params` field (types kept: booleans, numbers, the fixed_vertices array), the
optional target. Without a progress callback the answer is the mesh; with
one, `stream=ndjson` gives one line per step or milestone and a last line
naming the result, fetched after. Warnings come from X-Warnings, metrics from the job's
metrics link. Errors are problem+json documents (openapi.yaml, Problem).
"""
import json
import urllib.error
import urllib.parse
import urllib.request
import uuid

from . import errors
from ._events import step_event, work_event


class Answer:
    """What a job returned: the mesh bytes, its format, the job ID, the
    warnings' names and (when asked) the metrics document."""

    def __init__(self, data, fmt, job, warnings, metrics=None):
        self.data, self.format, self.job = data, fmt, job
        self.warnings, self.metrics = warnings, metrics


def _multipart(fields):
    """(body, content type) of multipart/form-data; fields: (name, filename
    or None, bytes)."""
    boundary = "mcfd-" + uuid.uuid4().hex
    parts = []
    for name, filename, data in fields:
        disp = 'form-data; name="%s"' % name
        if filename is not None:
            disp += '; filename="%s"' % filename.replace('"', "_").replace("\r", "_").replace("\n", "_")
        ctype = "application/octet-stream" if filename is not None else "application/json"
        parts.append(("--%s\r\nContent-Disposition: %s\r\nContent-Type: %s\r\n\r\n"
                      % (boundary, disp, ctype)).encode() + data + b"\r\n")
    return b"".join(parts) + ("--%s--\r\n" % boundary).encode(), \
        "multipart/form-data; boundary=" + boundary


def _problem(e):
    """The typed error of an HTTP error answer."""
    body = e.read()
    try:
        doc = json.loads(body)
    except ValueError:
        doc = {}
    retry = e.headers.get("Retry-After")
    return errors.error_for(doc.get("code"), doc.get("detail") or body[:300].decode("utf-8", "replace")
                            or e.reason, status=e.code, job=doc.get("job"),
                            retry_after=float(retry) if retry and retry.isdigit() else None)


def _open(req, timeout):
    try:
        return urllib.request.urlopen(req, timeout=timeout)
    except urllib.error.HTTPError as e:
        raise _problem(e) from None
    except (urllib.error.URLError, OSError) as e:
        raise errors.Unreachable("cannot reach %s: %s" % (req.full_url, getattr(e, "reason", e))) from None


def _format_of(resp):
    """The answer's format from its file name (Content-Disposition)."""
    cd = resp.headers.get("Content-Disposition") or ""
    name = cd.rsplit("filename=", 1)[-1].strip('"; ')
    ext = name.rsplit(".", 1)[-1].lower() if "." in name else ""
    return {"drc": "draco"}.get(ext, ext or None)


def _warnings(resp):
    w = resp.headers.get("X-Warnings")
    return [x.strip() for x in w.split(",") if x.strip()] if w else []


def _upload(data, filename, params, target):
    """(body, content type) of a job's upload: the mesh, the parameters as
    JSON, the optional target."""
    fields = [("mesh", filename, data), ("params", None, json.dumps(params).encode())]
    if target is not None:
        fields.append(("target", "target", target))
    return _multipart(fields)


def smooth(base, data, filename, params, target, progress, want_metrics, timeout, headers):
    """One attempt; raises MCFDError (Busy carries retry_after)."""
    body, ctype = _upload(data, filename, params, target)
    query = "?stream=ndjson&phases=true" if progress else ""
    req = urllib.request.Request(base + "/v1/smooth" + query, data=body, method="POST",
                                 headers=dict(headers, **{"Content-Type": ctype}))
    with _open(req, timeout) as resp:
        if not progress:
            job = resp.headers.get("X-Job-Id")
            answer = Answer(resp.read(), _format_of(resp), job, _warnings(resp))
        else:
            end = None
            for line in resp:
                if not line.strip():
                    continue
                ev = json.loads(line)
                if "phase" in ev:          # openapi.yaml WorkEvent
                    progress(work_event(ev["step"], ev["phase"], ev["fraction"]))
                elif "step" in ev and "done" not in ev:   # StepEvent
                    progress(step_event(ev["step"], ev["t"], ev["dt"], ev["energy"],
                                        ev["volume"]))
                else:
                    end = ev
            if not end:
                raise errors.ServerError("the step stream ended without its last line "
                                         "(the daemon stopped?)", status=resp.status)
            if end.get("status") != "succeeded":   # failed, canceled, or not done: EDRAINING
                err = end.get("error") or {}
                raise errors.error_for(err.get("code") or "ECANCELED",
                                       err.get("detail") or "the job %s" % end.get("status"),
                                       status=err.get("status"), job=end.get("job"))
            res = urllib.request.Request(base + end["result"], headers=headers)
            with _open(res, timeout) as r2:
                answer = Answer(r2.read(), _format_of(r2), end.get("job"), _warnings(r2),
                                end.get("metrics"))
    if want_metrics and answer.metrics is None and answer.job:
        req = urllib.request.Request(base + "/v1/jobs/%s/metrics" % answer.job, headers=headers)
        with _open(req, timeout) as resp:
            answer.metrics = json.loads(resp.read())
    return answer


class Door:
    """The REST door of one daemon (base: http://HOST:PORT)."""

    def __init__(self, base, timeout, headers):
        self.base, self.timeout, self.headers = base, timeout, headers

    def _json(self, method, path, body=None, ctype=None):
        headers = dict(self.headers, **({"Content-Type": ctype} if ctype else {}))
        req = urllib.request.Request(self.base + path, data=body, method=method, headers=headers)
        with _open(req, self.timeout) as resp:
            raw = resp.read()
        return json.loads(raw) if raw else None

    def smooth(self, data, filename, params, target, progress, want_metrics):
        return smooth(self.base, data, filename, params, target, progress, want_metrics,
                      self.timeout, self.headers)

    def submit(self, data, filename, params, target):
        """POST /v1/jobs: the queued job's state."""
        body, ctype = _upload(data, filename, params, target)
        return self._json("POST", "/v1/jobs", body, ctype)

    def get(self, job_id):
        return self._json("GET", "/v1/jobs/" + urllib.parse.quote(job_id))

    def cancel(self, job_id):
        """DELETE of an unfinished job. REST's DELETE also forgets a finished
        job, which cancel() must not: the state is read first; a job that
        finishes between that read and the DELETE is forgotten by it (204),
        and None is returned."""
        doc = self.get(job_id)
        if doc["status"] in ("succeeded", "failed", "canceled"):
            return doc
        return self._json("DELETE", "/v1/jobs/" + urllib.parse.quote(job_id))

    def result(self, job_id):
        req = urllib.request.Request(self.base + "/v1/jobs/%s/result" % urllib.parse.quote(job_id),
                                     headers=self.headers)
        with _open(req, self.timeout) as resp:
            return Answer(resp.read(), _format_of(resp), job_id, _warnings(resp))

    def metrics(self, job_id):
        return self._json("GET", "/v1/jobs/%s/metrics" % urllib.parse.quote(job_id))
