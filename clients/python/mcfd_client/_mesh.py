# SPDX-License-Identifier: MIT
"""mcfd_client._mesh - (vertices, faces) numpy arrays to and from PLY bytes.

Arrays travel as binary little-endian PLY: float or double positions as the
array has them (the daemon answers a single-precision input in float, a
double one in double, so no precision is lost either way) and int triangle
indices. The reader takes the PLY the daemon writes (binary or ASCII, with
its extra vertex properties: normals, colours, curvature) and returns the
positions and the triangles.
"""
_TYPES = {  # PLY scalar type -> numpy type code
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


def _np():
    import numpy
    return numpy


def check_arrays(vertices, faces):
    """(V, F) as contiguous numpy arrays: V float (n, 3), F integer (m, 3)."""
    np = _np()
    v = np.asarray(vertices)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3 or not np.issubdtype(v.dtype, np.number):
        raise ValueError("vertices must be an (n, 3) array of numbers, got shape %s dtype %s"
                         % (v.shape, v.dtype))
    if f.ndim != 2 or f.shape[1] != 3 or not np.issubdtype(f.dtype, np.integer):
        raise ValueError("faces must be an (m, 3) array of integers (triangles), got shape %s "
                         "dtype %s" % (f.shape, f.dtype))
    if v.dtype != np.float32:
        v = v.astype(np.float64)
    return v, f


def to_ply(vertices, faces):
    """Binary little-endian PLY bytes of the arrays."""
    np = _np()
    v, f = check_arrays(vertices, faces)
    real = "float" if v.dtype == np.float32 else "double"
    head = ("ply\nformat binary_little_endian 1.0\nelement vertex %d\n"
            "property %s x\nproperty %s y\nproperty %s z\nelement face %d\n"
            "property list uchar int vertex_indices\nend_header\n"
            % (len(v), real, real, real, len(f))).encode()
    rows = np.empty(len(f), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    rows["n"] = 3
    rows["i"] = f
    return head + v.astype(v.dtype.newbyteorder("<"), copy=False).tobytes() + rows.tobytes()


def _header(data):
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise ValueError("the answer is not a PLY file")
    body = data.index(b"\n", end) + 1
    fmt, elements = None, []
    for line in data[:end].decode("ascii", "replace").splitlines():
        t = line.split()
        if not t:
            continue
        if t[0] == "format":
            fmt = t[1]
        elif t[0] == "element":
            elements.append((t[1], int(t[2]), []))
        elif t[0] == "property" and elements:
            if t[1] == "list":
                elements[-1][2].append((t[4], "list", t[2], t[3]))
            else:
                elements[-1][2].append((t[2], t[1], None, None))
    return fmt, elements, body


def from_ply(data, float_type=None):
    """(vertices (n, 3), faces (m, 3) int32) from PLY bytes; vertices in
    float_type when given, else as the file has them."""
    np = _np()
    fmt, elements, pos = _header(data)
    if fmt not in ("binary_little_endian", "binary_big_endian", "ascii"):
        raise ValueError("PLY format %r" % fmt)
    end = "<" if fmt == "binary_little_endian" else ">"
    verts = faces = None
    text = data[pos:].decode("ascii").split() if fmt == "ascii" else None
    tpos = 0
    for name, count, props in elements:
        scalar = all(kind != "list" for _, kind, _, _ in props)
        if fmt == "ascii":
            if scalar:
                n = len(props)
                rows = np.array(text[tpos:tpos + n * count], dtype=np.float64).reshape(count, n)
                tpos += n * count
                if name == "vertex":
                    names = [p[0] for p in props]
                    verts = rows[:, [names.index(c) for c in "xyz"]]
                continue
            out = []
            for _ in range(count):
                row = []
                for _, kind, _, _ in props:
                    if kind == "list":
                        k = int(text[tpos])
                        row.append([int(float(x)) for x in text[tpos + 1:tpos + 1 + k]])
                        tpos += 1 + k
                    else:
                        tpos += 1
                out.append(row[0])
            if name == "face":
                faces = out
            continue
        if scalar:
            dt = np.dtype([(p[0], end + _TYPES[p[1]]) for p in props])
            rows = np.frombuffer(data, dtype=dt, count=count, offset=pos)
            pos += dt.itemsize * count
            if name == "vertex":
                verts = np.stack([rows[c] for c in "xyz"], axis=1)
            continue
        # A face element: the fast path when every row is one list of 3 indices.
        if len(props) == 1:
            _, _, ct, it = props[0]
            dt = np.dtype([("n", end + _TYPES[ct]), ("i", end + _TYPES[it], (3,))])
            rows = np.frombuffer(data, dtype=dt, count=count, offset=pos)
            if count == 0 or (rows["n"] == 3).all():
                pos += dt.itemsize * count
                if name == "face":
                    faces = rows["i"]
                continue
        out = []
        for _ in range(count):
            row = []
            for _, kind, ct, it in props:
                if kind != "list":
                    pos += np.dtype(_TYPES[kind]).itemsize
                    continue
                k = int(np.frombuffer(data, end + _TYPES[ct], 1, pos)[0])
                pos += np.dtype(_TYPES[ct]).itemsize
                row.append(np.frombuffer(data, end + _TYPES[it], k, pos).tolist())
                pos += np.dtype(_TYPES[it]).itemsize * k
            out.append(row[0])
        if name == "face":
            faces = out
    if verts is None or faces is None:
        raise ValueError("the PLY answer has no vertices or no faces")
    if isinstance(faces, list):
        if any(len(f) != 3 for f in faces):
            raise ValueError("the answer has faces that are not triangles")
        faces = np.array(faces, dtype=np.int32).reshape(-1, 3)
    verts = np.ascontiguousarray(verts, dtype=float_type or verts.dtype.newbyteorder("="))
    faces = np.ascontiguousarray(faces, dtype=np.int32)
    return verts, faces

