# SPDX-License-Identifier: MIT
"""mcfd_client._grpc - one smoothing job through the gRPC door (Smooth).

The upload is a SmoothHeader with typed Params, then the mesh (and the
optional target) in chunks of 64 KiB; the answer streams one Progress per
step, the metrics, a ResultHeader and the result's chunks. The stubs are the
package's own (_proto, generated from api/mcfd.proto and shipped). A failed
call's status carries the daemon's code in the trailing metadata `mcf-code`
and, when it is worth retrying, the delay in `retry-after-ms`.
"""
import json

from . import errors
from ._events import step_event, work_event
from ._jobs import grpc_job_doc
from ._rest import Answer

CHUNK = 64 * 1024
# Params fields that take a number or "auto" (NumberOrAuto in mcfd.proto)
_AUTO = ("dt", "strength", "quantization_bits")


def _modules():
    import grpc
    from ._proto import mcfd_pb2, mcfd_pb2_grpc
    return grpc, mcfd_pb2, mcfd_pb2_grpc


def _params(pb, params):
    """pb.Params from the keyword parameters; a name or value the message
    cannot hold is InvalidParameter, as the daemon would say it."""
    p = pb.Params()
    fields = p.DESCRIPTOR.fields_by_name
    for key, value in params.items():
        if key not in fields:
            raise errors.InvalidParameter("unknown parameter '%s' (accepted: %s)"
                                          % (key, ",".join(fields)), code="EINVAL")
        try:
            if key in _AUTO:
                if value == "auto":
                    getattr(p, key).auto = True
                else:
                    getattr(p, key).number = float(value)
            elif key == "fixed_vertices":
                p.fixed_vertices.extend(int(i) for i in value)
            else:
                setattr(p, key, value)
        except (TypeError, ValueError) as e:
            raise errors.InvalidParameter("parameter '%s': %s" % (key, e), code="EINVAL") from None
    return p


def _requests(pb, data, filename, params, output_format, target, phases=False):
    h = pb.SmoothHeader(params=params, total_size=len(data), filename=filename or "mesh",
                        phases=phases)
    if output_format:
        h.output_format = output_format
    if target is not None:
        h.target_size = len(target)
    yield pb.SmoothRequest(header=h)
    for i in range(0, len(data), CHUNK):
        yield pb.SmoothRequest(chunk=data[i:i + CHUNK])
    for i in range(0, len(target or b""), CHUNK):
        yield pb.SmoothRequest(target_chunk=target[i:i + CHUNK])


def _error(grpc, e):
    """The typed error of a failed call."""
    meta = dict(e.trailing_metadata() or ())
    code = meta.get("mcf-code")
    status = e.code().name if e.code() else None
    if code is None:
        code = {"UNAVAILABLE": None, "CANCELLED": "ECANCELED",
                "DEADLINE_EXCEEDED": "ETIMEOUT", "UNAUTHENTICATED": "EAUTH",
                "NOT_FOUND": "ENOTFOUND"}.get(status)
    retry = meta.get("retry-after-ms")
    if code is None and e.code() == grpc.StatusCode.UNAVAILABLE and retry is None:
        return errors.Unreachable(e.details() or "the daemon is unreachable", status=status)
    return errors.error_for(code, e.details() or status, status=status,
                            retry_after=int(retry) / 1000.0 if retry and retry.isdigit() else None)


def _channel(grpc, target_addr, secure):
    return (grpc.secure_channel(target_addr, grpc.ssl_channel_credentials()) if secure
            else grpc.insecure_channel(target_addr))


def _read_answer(responses, progress):
    """The Answer of a Smooth or WatchJob stream: progress to the callback,
    then the metrics, the result's header and its chunks."""
    chunks, metrics, header = [], None, None
    for r in responses:
        part = r.WhichOneof("part")
        if part == "progress" and progress:
            g = r.progress
            progress(work_event(g.step, g.phase, g.fraction) if g.phase else
                     step_event(g.step, g.t, g.dt, g.energy, g.volume))
        elif part == "metrics":
            metrics = json.loads(r.metrics)
        elif part == "result_header":
            header = r.result_header
        elif part == "result_chunk":
            chunks.append(r.result_chunk)
    if header is None:
        raise errors.ServerError("the call ended without a result", status="OK")
    return Answer(b"".join(chunks), header.format, header.job_id,
                  list((metrics or {}).get("warnings") or ()), metrics)


class Door:
    """The gRPC door of one daemon: one call per method, each on its own
    channel (a Job handle holds no connection between calls)."""

    def __init__(self, target_addr, secure, timeout, metadata):
        self.addr, self.secure, self.timeout, self.metadata = target_addr, secure, timeout, metadata

    def _call(self, fn):
        grpc, pb, pb_grpc = _modules()
        channel = _channel(grpc, self.addr, self.secure)
        try:
            return fn(pb, pb_grpc.SmootherStub(channel))
        except grpc.RpcError as e:
            raise _error(grpc, e) from None
        finally:
            channel.close()

    def smooth(self, data, filename, params, target, progress, want_metrics):
        """One Smooth call; raises MCFDError (Busy carries retry_after)."""
        params = dict(params)
        output_format = params.pop("format", None)
        return self._call(lambda pb, stub: _read_answer(
            stub.Smooth(_requests(pb, data, filename, _params(pb, params), output_format, target,
                                  phases=progress is not None),
                        timeout=self.timeout, metadata=self.metadata), progress))

    def submit(self, data, filename, params, target):
        """SubmitJob: the queued job's state (REST's Job document)."""
        params = dict(params)
        output_format = params.pop("format", None)
        return self._call(lambda pb, stub: grpc_job_doc(stub.SubmitJob(
            _requests(pb, data, filename, _params(pb, params), output_format, target),
            timeout=self.timeout, metadata=self.metadata)))

    def get(self, job_id):
        return self._call(lambda pb, stub: grpc_job_doc(stub.GetJob(
            pb.GetJobRequest(id=job_id), timeout=self.timeout, metadata=self.metadata)))

    def cancel(self, job_id):
        return self._call(lambda pb, stub: grpc_job_doc(stub.CancelJob(
            pb.CancelJobRequest(id=job_id), timeout=self.timeout, metadata=self.metadata)))

    def result(self, job_id):
        """WatchJob from past the last step: the metrics and the result."""
        return self._call(lambda pb, stub: _read_answer(stub.WatchJob(
            pb.WatchJobRequest(id=job_id, from_step=2**31 - 1), timeout=self.timeout,
            metadata=self.metadata), None))

    def metrics(self, job_id):
        doc = self.get(job_id)
        if "metrics" not in doc:
            raise errors.error_for("ENOTREADY", "job %s is %s: no metrics" % (job_id, doc["status"]),
                                   status="FAILED_PRECONDITION", job=job_id)
        return doc["metrics"]
