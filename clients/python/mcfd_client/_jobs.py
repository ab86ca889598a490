# SPDX-License-Identifier: MIT
"""mcfd_client._jobs - the asynchronous job handle (submit) and the batch
helper (smooth_files) of the remote client.

A Job follows a job the daemon has queued, through the door it was
submitted to: its state is REST's Job document (openapi.yaml, Job) on both
doors (gRPC's Job message is converted to it), waiting polls that state
(REST GET /v1/jobs/{id}, gRPC GetJob) with a delay growing from 50 ms to
1 s, and the result comes back in the kind the mesh was given, as from
smooth().
"""
import json
import os
import time

from . import errors

_DONE = ("succeeded", "failed", "canceled")
_POLL_FIRST, _POLL_MAX = 0.05, 1.0


class Job:
    """A job submitted with mcfd_client.submit(): .id, .url; status(),
    done(), wait(), result(), metrics(), cancel().

    The handle holds no connection: it may be kept, passed to another
    thread, or rebuilt later with Job(id, url) (then result() gives bytes)."""

    def __init__(self, id, url, *, token=None, timeout=600.0, _door=None, _deliver=None):
        from . import _door_for
        self.id, self.url = id, url
        self._door = _door or _door_for(url, token, timeout)
        self._deliver = _deliver or (lambda answer: answer.data)

    def __repr__(self):
        return "Job(%r, %r)" % (self.id, self.url)

    def status(self):
        """The job as the daemon has it now: a dict with status (queued,
        running, succeeded, failed, canceled), progress {step, steps, t, dt,
        energy, volume, fraction}, created/started/finished, and error
        {code, detail} when it failed or was canceled."""
        return self._door.get(self.id)

    def done(self):
        """Whether the job has finished (succeeded, failed or canceled)."""
        return self.status()["status"] in _DONE

    def wait(self, timeout=None, progress=None):
        """Waits until the job has finished and returns its state (it does
        not raise for a failed job: result() does). progress: called with
        the state's progress dict each time its step moves. timeout:
        seconds, None for no bound; past it, TimeoutError (the job goes on:
        cancel() it if it is not wanted)."""
        end = None if timeout is None else time.monotonic() + timeout
        delay, last = _POLL_FIRST, None
        while True:
            doc = self.status()
            p = doc.get("progress") or {}
            if progress and p.get("step") and p.get("step") != last:
                last = p["step"]
                progress(p)
            if doc["status"] in _DONE:
                return doc
            if end is not None and time.monotonic() + delay > end:
                raise TimeoutError("job %s still %s after %g s" % (self.id, doc["status"], timeout))
            time.sleep(delay)
            delay = min(delay * 1.5, _POLL_MAX)

    def result(self, timeout=None, progress=None, with_metrics=False):
        """Waits for the job (as wait()) and returns its result in the kind
        the mesh was submitted as (a path written as submit's `out` says,
        bytes, or a (vertices, faces) pair), with one SmoothingWarning per
        warning; with_metrics: (result, metrics). A failed or canceled job
        raises its typed error (MeshError, LimitExceeded, Canceled, ...)."""
        doc = self.wait(timeout, progress)
        if doc["status"] != "succeeded":
            err = doc.get("error") or {}
            raise errors.error_for(err.get("code") or "ECANCELED",
                                   err.get("detail") or "the job was %s" % doc["status"],
                                   status=err.get("status"), job=self.id)
        answer = self._door.result(self.id)
        if with_metrics and answer.metrics is None:
            answer.metrics = self.metrics()
        from . import _warn
        _warn(answer)
        out = self._deliver(answer)
        return (out, answer.metrics) if with_metrics else out

    def metrics(self):
        """The metrics document of a succeeded job (a dict); NotReady-like
        MCFDError (ENOTREADY) before it has finished."""
        return self._door.metrics(self.id)

    def cancel(self):
        """Cancels a queued or running job and returns its state (a running
        job stops before its next step: wait() then says canceled). A
        finished job is left as it is."""
        return self._door.cancel(self.id)


def smooth_files(paths, out_dir, url="http://127.0.0.1:8080", *, max_in_flight=4,
                 timeout=600.0, token=None, **params):
    """Smooths many files with the daemon: at most max_in_flight jobs
    submitted at once, each result written to out_dir under its input's
    name (NAME-smoothed.EXT). Returns a list, in the order of paths, of the
    written path or the error that file raised (an MCFDError, or an
    OSError for a file that cannot be read): one bad file does not stop the
    others."""
    from . import submit
    os.makedirs(out_dir, exist_ok=True)
    paths = list(paths)
    results = [None] * len(paths)
    pending, nxt = {}, 0
    while nxt < len(paths) or pending:
        while nxt < len(paths) and len(pending) < max_in_flight:
            try:
                pending[nxt] = submit(paths[nxt], url=url, out=out_dir, token=token,
                                      timeout=timeout, **params)
            except (errors.MCFDError, OSError) as e:
                results[nxt] = e
            nxt += 1
        if pending:
            i = _first_done(pending)
            try:
                results[i] = pending.pop(i).result(timeout=timeout)
            except errors.MCFDError as e:
                results[i] = e
    return results


def _first_done(pending):
    """The key of a finished job among pending, polling them in turn."""
    delay = _POLL_FIRST
    while True:
        for i, job in pending.items():
            if job.done():
                return i
        time.sleep(delay)
        delay = min(delay * 1.5, _POLL_MAX)


def grpc_job_doc(job):
    """REST's Job document (a dict) from gRPC's Job message."""
    p = job.progress
    prog = {"step": p.step, "fraction": p.fraction}
    for key in ("steps", "t", "dt", "energy", "volume"):
        prog[key] = getattr(p, key) if p.HasField(key) else None
    doc = {"id": job.id, "status": job.Status.Name(job.status).lower(), "progress": prog,
           "created": job.created, "cancel_requested": job.cancel_requested,
           "started": job.started if job.HasField("started") else None,
           "finished": job.finished if job.HasField("finished") else None}
    if job.params:
        doc["params"] = json.loads(job.params)
    if job.input_format:
        doc["input_format"] = job.input_format
    if job.HasField("metrics"):
        doc["metrics"] = json.loads(job.metrics)
    if job.HasField("error") and job.error.code:
        doc["error"] = {"code": job.error.code, "detail": job.error.detail}
    return doc
