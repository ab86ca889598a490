#!/bin/sh
# SPDX-License-Identifier: MIT
# clients/python/gen_stubs.sh [OUTDIR] - the Python stubs of api/mcfd.proto
# (mcfd_pb2.py, mcfd_pb2_grpc.py) into OUTDIR (default: the package's
# mcfd_client/_proto, where they are committed: `make python-stubs`).
#
# Made with Debian's protoc 3.21 (protobuf-compiler) and gRPC's Python plugin
# (protobuf-compiler-grpc), the tools the C++ build already uses, and
# committed, so that installing or running the client needs no protoc:
# python3-grpc-tools would be the other way, but it bundles protoc 3.5.1,
# which predates proto3 `optional` (mcfd.proto's Params need it). The
# edits: the gRPC module imports its messages relative to the package; both
# start with the SPDX line.
# tests/test_contract.py regenerates them and fails when the committed
# copies differ from what the proto gives.
set -eu
here=$(cd "$(dirname "$0")" && pwd)
top=$(cd "$here/../.." && pwd)
out=${1:-$here/mcfd_client/_proto}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
protoc -I"$top/api" --python_out="$tmp" --grpc_python_out="$tmp" \
    --plugin=protoc-gen-grpc_python="$(command -v grpc_python_plugin)" mcfd.proto
mkdir -p "$out"
# the stubs carry the proto's licence line, as every source file does
{ echo '# SPDX-License-Identifier: MIT'; cat "$tmp/mcfd_pb2.py"; } > "$out/mcfd_pb2.py"
{ echo '# SPDX-License-Identifier: MIT'
  sed 's/^import mcfd_pb2 as mcfd__pb2$/from . import mcfd_pb2 as mcfd__pb2/' "$tmp/mcfd_pb2_grpc.py"; } \
    > "$out/mcfd_pb2_grpc.py"
