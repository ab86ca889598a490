#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""make_h2gate_seeds.py - regenerates tests/fuzz/corpus_h2gate/: what gRPC
clients (and the attacks of tests/test_grpc.py) send to the gRPC door,
written with tests/h2raw.py, each behind the three control bytes
fuzz_h2gate.c reads (bounds, pieces, the stand-in server's manners, one
connection or two).
Run from the top of the tree: /usr/bin/python3 tests/fuzz/make_h2gate_seeds.py
"""
import os
import shutil
import struct
import sys

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
import h2raw  # noqa: E402
from h2raw import (CONTINUATION, DATA, END_HEADERS, END_STREAM, HEADERS, PING,  # noqa: E402
                   PREFACE, RST_STREAM, SETTINGS, WINDOW_UPDATE, frame)

OUT = os.path.join(os.path.dirname(__file__), "corpus_h2gate")
GETJOB = h2raw.request_headers(b"/mcfd.v1.Smoother/GetJob")
SMOOTH = h2raw.request_headers(b"/mcfd.v1.Smoother/Smooth", [(b"grpc-timeout", b"5S")])
START = PREFACE + frame(SETTINGS, 0, 0, struct.pack(">HI", 3, 100)) + \
    frame(WINDOW_UPDATE, 0, 0, struct.pack(">I", 1 << 20))


def call(sid, block, msg=b"\x0a\x03abc", parts=1):
    """A unary call: its header block in `parts` frames, one message."""
    step = -(-len(block) // parts)
    pieces = [block[i:i + step] for i in range(0, len(block), step)]
    out = frame(HEADERS, END_HEADERS if len(pieces) == 1 else 0, sid, pieces[0])
    for j, p in enumerate(pieces[1:]):
        out += frame(CONTINUATION, END_HEADERS if j == len(pieces) - 2 else 0, sid, p)
    return out + frame(DATA, END_STREAM, sid, h2raw.message(msg))


SEEDS = {
    "unary": START + call(1, GETJOB),
    "two_calls_settings_ack": START + frame(SETTINGS, 1, 0) + call(1, GETJOB) + call(3, SMOOTH),
    "continuations": START + call(1, SMOOTH, parts=4),
    "padded_data": START + frame(HEADERS, END_HEADERS, 1, GETJOB) +
    frame(DATA, END_STREAM | 0x8, 1, b"\x03" + h2raw.message(b"\x0a\x01x") + b"\0\0\0"),
    "message_in_pieces": START + frame(HEADERS, END_HEADERS, 1, SMOOTH) +
    frame(DATA, 0, 1, h2raw.message(b"m" * 300)[:7]) +
    frame(DATA, 0, 1, h2raw.message(b"m" * 300)[7:200]) +
    frame(DATA, END_STREAM, 1, h2raw.message(b"m" * 300)[200:]),
    "ping_and_window": START + frame(PING, 0, 0, b"12345678") +
    frame(WINDOW_UPDATE, 0, 1, struct.pack(">I", 100)) + call(1, GETJOB),
    "rapid_reset": START + b"".join(
        frame(HEADERS, END_HEADERS, s, GETJOB) + frame(RST_STREAM, 0, s, b"\0\0\0\x08")
        for s in range(1, 40, 2)),
    "abandoned": START + b"".join(frame(HEADERS, END_HEADERS, s, GETJOB) for s in range(1, 24, 2)),
    "header_flood": START + frame(HEADERS, 0, 1, GETJOB + h2raw.literal_prefix(b"x-junk", 1 << 30)) +
    frame(CONTINUATION, 0, 1, b"a" * 600) * 4,
    "gzip_message": START + frame(HEADERS, END_HEADERS, 1, h2raw.request_headers(
        b"/mcfd.v1.Smoother/Smooth", [(b"grpc-encoding", b"gzip")])) +
    frame(DATA, END_STREAM, 1, h2raw.message(h2raw.gzip_bomb(1 << 16), compressed=True)),
    "trickled_block": START + frame(HEADERS, 0, 1, GETJOB[:40]) +
    b"".join(frame(CONTINUATION, 0, 1, GETJOB[i:i + 1]) for i in range(40, 70)) +
    frame(CONTINUATION, END_HEADERS, 1, GETJOB[70:]),
    "preface_only": PREFACE,
    "not_http2": b"GET / HTTP/1.1\r\nHost: mcfd\r\n\r\n",
}
# control bytes: bounds, pieces and server (fuzz_h2gate.c's setup()), then
# one connection (0), two from two addresses (1) or from one (3)
CONTROLS = [b"\x86\x00", b"\x80\x10", b"\xa9\x25", b"\x55\xb3", b"\x82\x2a"]
PAIRS = {  # two clients at once: an attacker and a legitimate caller
    "pair_rapid_reset_unary": (b"\x9a\x20\x03", "rapid_reset", "unary"),
    "pair_abandoned_unary": (b"\xb9\x30\x03", "abandoned", "two_calls_settings_ack"),
    "pair_flood_continuations": (b"\x82\x00\x01", "header_flood", "continuations"),
}


def main():
    shutil.rmtree(OUT, ignore_errors=True)
    os.makedirs(OUT)
    seeds = {}
    for name, data in SEEDS.items():
        for i, c in enumerate(CONTROLS):
            seeds["%s_%d" % (name, i)] = c + b"\0" + data
    for name, (c, a, b) in PAIRS.items():
        seeds[name] = c + SEEDS[a] + SEEDS[b]
    for name, data in sorted(seeds.items()):
        with open(os.path.join(OUT, name), "wb") as f:
            f.write(data)
    print("%d seeds in %s" % (len(seeds), OUT))


if __name__ == "__main__":
    main()
