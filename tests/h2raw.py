# SPDX-License-Identifier: MIT
"""h2raw.py - a raw HTTP/2 client for the attack tests of mcfd's gRPC door.

Frames are written by hand (RFC 9113) and header blocks are HPACK literals
without indexing or Huffman coding (RFC 7541 6.2.2), so a test can send what
no gRPC client would: a header block that never ends, thousands of HEADERS +
RST_STREAM, streams that never send their message, a compressed message of
any size, a connection that stops after the preface. It reads the server's
frames only as far as their headers (type, flags, stream): what the tests
judge is whether the daemon closed, refused or reset, and what it cost.
"""
import socket
import struct
import time
import zlib

PREFACE = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n"
DATA, HEADERS, RST_STREAM, SETTINGS, PING, GOAWAY, WINDOW_UPDATE, CONTINUATION = \
    0, 1, 3, 4, 6, 7, 8, 9
END_STREAM = ACK = 0x1
END_HEADERS = 0x4
CANCEL = 8


def frame(kind, flags, stream, payload=b""):
    return (struct.pack(">I", len(payload))[1:] + bytes((kind, flags)) +
            struct.pack(">I", stream & 0x7FFFFFFF) + payload)


def _int(v, bits, first=0):
    """An HPACK integer with a `bits`-bit prefix (RFC 7541 5.1)."""
    m = (1 << bits) - 1
    if v < m:
        return bytes((first | v,))
    out, v = [first | m], v - m
    while v >= 128:
        out.append(v & 127 | 128)
        v >>= 7
    out.append(v)
    return bytes(out)


def literal(name, value):
    """A literal header field without indexing, new name (RFC 7541 6.2.2)."""
    return b"\x00" + _int(len(name), 7) + name + _int(len(value), 7) + value


def literal_prefix(name, value_len):
    """The start of a literal whose value of value_len bytes follows."""
    return b"\x00" + _int(len(name), 7) + name + _int(value_len, 7)


def request_headers(path, extra=()):
    """The header block of a gRPC request to path (b"/mcfd.v1.Smoother/GetJob")."""
    hs = [(b":method", b"POST"), (b":scheme", b"http"), (b":path", path),
          (b":authority", b"mcfd"), (b"content-type", b"application/grpc"),
          (b"te", b"trailers")] + list(extra)
    return b"".join(literal(n, v) for n, v in hs)


def message(payload, compressed=False):
    """A gRPC length-prefixed message."""
    return bytes((1 if compressed else 0,)) + struct.pack(">I", len(payload)) + payload


def gzip_bomb(inflated):
    """A gzip stream of `inflated` zero bytes (about 1/1000 of that)."""
    z = zlib.compressobj(9, zlib.DEFLATED, 31)
    block = bytes(1 << 20)
    out = [z.compress(block) for _ in range(inflated >> 20)]
    out.append(z.compress(bytes(inflated & ((1 << 20) - 1))))
    out.append(z.flush())
    return b"".join(out)


class Conn:
    """One connection: the client preface and an empty SETTINGS at once
    (unless preface=False), then whatever the test sends."""

    def __init__(self, port, host="127.0.0.1", preface=True, timeout=10, src=None):
        """src: the client's own address (another loopback one, 127.0.0.N,
        is another client to the daemon's per-address bounds)."""
        self.s = socket.create_connection((host, port), timeout=timeout,
                                          source_address=(src, 0) if src else None)
        self.buf = b""
        self.next_stream = 1
        if preface:
            self.s.sendall(PREFACE + frame(SETTINGS, 0, 0))

    def send(self, *frames):
        self.s.sendall(b"".join(frames))

    def stream(self):
        sid = self.next_stream
        self.next_stream += 2
        return sid

    def frames(self, timeout=5.0, until=None):
        """The server's frames as (type, flags, stream, payload) until
        until(frame) is true, the connection closes or timeout passes.
        Acknowledges the server's SETTINGS and PINGs, as a client must."""
        out, end = [], time.time() + timeout
        while time.time() < end:
            while len(self.buf) >= 9:
                n = int.from_bytes(self.buf[:3], "big")
                if len(self.buf) < 9 + n:
                    break
                f = (self.buf[3], self.buf[4], int.from_bytes(self.buf[5:9], "big") & 0x7FFFFFFF,
                     self.buf[9:9 + n])
                self.buf = self.buf[9 + n:]
                out.append(f)
                try:
                    if f[0] == SETTINGS and not f[1] & ACK:
                        self.s.sendall(frame(SETTINGS, ACK, 0))
                    elif f[0] == PING and not f[1] & ACK:
                        self.s.sendall(frame(PING, ACK, 0, f[3]))
                except OSError:
                    pass            # closed: the frames read so far still count
                if until and until(f):
                    return out
            self.s.settimeout(max(0.01, end - time.time()))
            try:
                b = self.s.recv(65536)
            except socket.timeout:
                break
            except OSError:
                return out + [None]
            if not b:
                return out + [None]     # None: the server closed
            self.buf += b
        return out

    def closed_within(self, timeout):
        """Seconds until the server closed the connection (reading and
        discarding), or None when it is still open after timeout."""
        t0, end = time.time(), time.time() + timeout
        while time.time() < end:
            self.s.settimeout(max(0.01, end - time.time()))
            try:
                b = self.s.recv(1 << 20)
            except socket.timeout:
                return None
            except OSError:
                return time.time() - t0
            if not b:
                return time.time() - t0
        return None

    def close(self):
        try:
            self.s.close()
        except OSError:
            pass


def goaway_text(frames):
    """The debug text of the GOAWAY among frames, or None."""
    for f in frames:
        if f and f[0] == GOAWAY:
            return f[3][8:].decode(errors="replace")
    return None


def wait_closed(conns, timeout):
    """Reads and discards on every connection until the server closes it
    or timeout passes: how many it closed."""
    import selectors
    sel = selectors.DefaultSelector()       # epoll: descriptors past 1024
    for c in conns:
        sel.register(c.s, selectors.EVENT_READ)
    left, closed, end = len(conns), 0, time.time() + timeout
    while left and time.time() < end:
        for key, _ in sel.select(max(0.0, min(0.2, end - time.time()))):
            try:
                b = key.fileobj.recv(1 << 16)
            except OSError:
                b = b""
            if not b:
                sel.unregister(key.fileobj)
                left -= 1
                closed += 1
    sel.close()
    return closed


def flood(host, port, n, seconds):
    """Opens n connections that send the preface and an empty SETTINGS and
    nothing more (the attack of issue 17 item 1), holds them `seconds`,
    closes them; says what the server did."""
    import resource
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft < hard:
        resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))
    n = min(n, max(hard, soft) - 64)
    conns, failed = [], 0
    for _ in range(n):
        try:
            conns.append(Conn(port, host=host, timeout=5))
        except OSError:
            failed += 1
    t0 = time.time()
    refused = wait_closed(conns, seconds)
    time.sleep(max(0.0, seconds - (time.time() - t0)))
    for c in conns:
        c.close()
    print("%d connections (%d could not connect), %d closed by the server within %g s"
          % (len(conns), failed, refused, seconds))


if __name__ == "__main__":
    import sys
    if len(sys.argv) == 6 and sys.argv[1] == "flood":
        flood(sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), float(sys.argv[5]))
    else:
        sys.exit("usage: h2raw.py flood HOST PORT CONNECTIONS SECONDS")
