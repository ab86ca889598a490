#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""grpc_client.py - a short client of mcfd's gRPC door (api/mcfd.proto).

Smooths a mesh file through mcfd.v1.Smoother/Smooth: sends the header with
typed parameters, then the file in 64 KiB chunks; prints the progress,
writes the result and, with --metrics, the metrics document.

    /usr/bin/python3 examples/grpc_client.py IN OUT [--addr 127.0.0.1:50051]
        [--scheme desbrun2] [--iterations 10] [--strength 0.5|auto]
        [--format obj|draco|ply|stl|off] [--metrics FILE] [--token TOKEN]

Needs Debian's python3-grpcio (on /usr/bin/python3) and protobuf-compiler-grpc:
the Python stubs are generated from the proto at first use into a cache
folder with protoc and grpc_python_plugin (python3-grpc-tools' bundled
protoc 3.5 predates proto3 `optional`). bench/bench_grpc.py imports stubs() and smooth() from here.
"""
import argparse
import hashlib
import os
import subprocess
import sys
import tempfile

PROTO = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "api", "mcfd.proto")
CHUNK = 64 * 1024


def stubs(proto=PROTO):
    """(mcfd_pb2, mcfd_pb2_grpc), generated with protoc once per
    version of the proto into $TMPDIR/mcfd-stubs-<hash>."""
    with open(proto, "rb") as f:
        tag = hashlib.sha256(f.read()).hexdigest()[:12]
    out = os.path.join(tempfile.gettempdir(), "mcfd-stubs-" + tag)
    if not os.path.exists(os.path.join(out, "mcfd_pb2_grpc.py")):
        tmp = tempfile.mkdtemp(prefix="mcfd-stubs-")
        subprocess.check_call(["protoc", "--plugin=protoc-gen-grpc_python=/usr/bin/grpc_python_plugin",
                               "-I" + os.path.dirname(proto), "--python_out=" + tmp,
                               "--grpc_python_out=" + tmp, os.path.basename(proto)])
        try:
            os.rename(tmp, out)
        except OSError:         # another process made it first
            pass
    sys.path.insert(0, out)
    import mcfd_pb2
    import mcfd_pb2_grpc
    return mcfd_pb2, mcfd_pb2_grpc


def requests(pb, data, params, output_format=None, filename=None):
    """The upload: one header, then the mesh in chunks."""
    h = pb.SmoothHeader(params=params, total_size=len(data))
    if output_format:
        h.output_format = output_format
    if filename:
        h.filename = filename
    yield pb.SmoothRequest(header=h)
    for i in range(0, len(data), CHUNK):
        yield pb.SmoothRequest(chunk=data[i:i + CHUNK])


def smooth(stub, pb, data, params, on_progress=None, metadata=None, timeout=None, **kw):
    """Smooths data (a mesh file's bytes); returns (result bytes, metrics
    JSON text, ResultHeader). Raises grpc.RpcError with the daemon's
    status and message (INVALID_ARGUMENT names the parameter)."""
    metrics, header, chunks = None, None, []
    for r in stub.Smooth(requests(pb, data, params, **kw), metadata=metadata, timeout=timeout):
        part = r.WhichOneof("part")
        if part == "progress" and on_progress:
            on_progress(r.progress)
        elif part == "metrics":
            metrics = r.metrics
        elif part == "result_header":
            header = r.result_header
        elif part == "result_chunk":
            chunks.append(r.result_chunk)
    return b"".join(chunks), metrics, header


def main():
    import grpc
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("input")
    ap.add_argument("output")
    ap.add_argument("--addr", default="127.0.0.1:50051")
    ap.add_argument("--scheme")
    ap.add_argument("--iterations", type=int)
    ap.add_argument("--strength")
    ap.add_argument("--format", dest="output_format")
    ap.add_argument("--metrics")
    ap.add_argument("--token")
    a = ap.parse_args()
    pb, pb_grpc = stubs()
    params = pb.Params()
    if a.scheme:
        params.scheme = a.scheme
    if a.iterations is not None:
        params.iterations = a.iterations
    if a.strength == "auto":
        params.strength.auto = True
    elif a.strength:
        params.strength.number = float(a.strength)
    with open(a.input, "rb") as f:
        data = f.read()
    md = [("authorization", "Bearer " + a.token)] if a.token else None
    with grpc.insecure_channel(a.addr) as ch:
        try:
            result, metrics, header = smooth(
                pb_grpc.SmootherStub(ch), pb, data, params, metadata=md,
                output_format=a.output_format, filename=os.path.basename(a.input),
                on_progress=lambda p: print("step %d t=%.3g energy=%.6g" % (p.step, p.t, p.energy)))
        except grpc.RpcError as e:
            print("grpc_client: %s: %s" % (e.code().name, e.details()), file=sys.stderr)
            return 1
    with open(a.output, "wb") as f:
        f.write(result)
    if a.metrics:
        with open(a.metrics, "w") as f:
            f.write(metrics)
    print("job %s: %s, %d bytes -> %s" % (header.job_id, header.format, len(result), a.output))
    return 0


if __name__ == "__main__":
    sys.exit(main())
