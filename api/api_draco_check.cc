/* SPDX-License-Identifier: MIT */
/*
 * api_draco_check.cc - the count pre-check of a Draco stream (libdraco
 * allocates by the counts a stream declares before it reads their data;
 * see below).
 */
#include <cstring>

#include "api_draco_internal.h"

namespace api_draco {

/* ------------------------------------------------------ count pre-check */

/* libdraco sizes its tables from the counts in the stream before it reads
 * the data they describe: a 300-byte edgebreaker stream declaring a billion
 * faces makes it reserve 4 GB, a v2.0 stream with a huge hole-event count
 * grows a vector without end, and its metadata reader allocates an entry's
 * declared size and recurses without a depth bound. So the counts are read
 * here first, along the bitstream layout of Draco's decoders (header,
 * metadata, then the sequential or edgebreaker connectivity header), and
 * checked against the limits and the input size. Parsing stops quietly
 * where the input ends: Draco fails there too, before allocating. */
struct cursor {
    const uint8_t *p, *end;
    bool u8(uint32_t *v)
    {
        if (p >= end)
            return false;
        *v = *p++;
        return true;
    }
    bool u32(uint32_t *v)
    {
        if (end - p < 4)
            return false;
        *v = static_cast<uint32_t>(p[0]) | static_cast<uint32_t>(p[1]) << 8 |
             static_cast<uint32_t>(p[2]) << 16 | static_cast<uint32_t>(p[3]) << 24;
        p += 4;
        return true;
    }
    /* Draco's DecodeVarint<uint32_t>: at most 5 bytes, least significant
     * group first, assembled in 32-bit arithmetic. */
    bool varint(uint32_t *v)
    {
        uint8_t b[5];
        int n = 0;
        do {
            if (n == 5 || p >= end)
                return false;
            b[n] = *p++;
        } while (b[n++] & 0x80);
        uint32_t x = b[n - 1];
        for (int i = n - 2; i >= 0; i--)
            x = (x << 7) | (b[i] & 0x7fu);
        *v = x;
        return true;
    }
    /* u32 before bitstream 2.0, varint from then on (Draco's pattern). */
    bool count(int ver, uint32_t *v) { return ver < 0x200 ? u32(v) : varint(v); }
    size_t left() const { return static_cast<size_t>(end - p); }
};

/* A count of metadata items (a varint) that the bytes left can hold, each
 * item taking at least one; what names the items in the message. */
static mcf_status item_count(cursor *c, const char *what, uint32_t *n, mcf_error *err)
{
    if (!c->varint(n))
        return api__fail(err, MCF_EDECODE, "draco: truncated metadata");
    if (*n > c->left())
        return api__fail(err, MCF_EDECODE, "draco: metadata declares %u %s in %zu bytes", *n,
                         what, c->left());
    return MCF_OK;
}

/* Skips a metadata name (a length byte, then the bytes); false when the
 * input ends first. */
static bool skip_name(cursor *c)
{
    uint32_t name;
    if (!c->u8(&name) || name > c->left())
        return false;
    c->p += name;
    return true;
}

/* Skips one metadata block (MetadataDecoder::DecodeMetadata) strictly. */
static mcf_status skip_metadata(cursor *c, int depth, mcf_error *err)
{
    uint32_t n, len = 0, k;
    mcf_status rc;
    if (depth > 32)
        return api__fail(err, MCF_EDECODE, "draco: metadata nested deeper than 32 levels");
    if ((rc = item_count(c, "entries", &n, err)) != MCF_OK)
        return rc;
    for (k = 0; k < n; k++) {
        if (!skip_name(c))
            return api__fail(err, MCF_EDECODE, "draco: truncated metadata");
        if (!c->varint(&len) || len == 0 || len > c->left())
            return api__fail(err, MCF_EDECODE,
                             "draco: metadata entry of %u bytes in %zu", len,
                             c->left());
        c->p += len;
    }
    if ((rc = item_count(c, "sub-metadata", &n, err)) != MCF_OK)
        return rc;
    for (k = 0; k < n; k++) {
        if (!skip_name(c))
            return api__fail(err, MCF_EDECODE, "draco: truncated metadata");
        if ((rc = skip_metadata(c, depth + 1, err)) != MCF_OK)
            return rc;
    }
    return MCF_OK;
}

/* The metadata section (bitstream 1.3 on, header flag 0x8000): the
 * attributes' blocks, each behind its attribute id, then the file's. */
static mcf_status skip_all_metadata(cursor *c, mcf_error *err)
{
    uint32_t n, k, id;
    mcf_status rc;
    if ((rc = item_count(c, "attribute blocks", &n, err)) != MCF_OK)
        return rc;
    for (k = 0; k < n; k++) {
        if (!c->varint(&id))
            return api__fail(err, MCF_EDECODE, "draco: truncated metadata");
        if ((rc = skip_metadata(c, 0, err)) != MCF_OK)
            return rc;
    }
    return skip_metadata(c, 0, err);
}

/* The counts a connectivity header declares; read is false when the input
 * ends before they are all read (Draco fails there too, before
 * allocating, so the check passes it on quietly). */
struct counts {
    uint32_t nfaces = 0, nverts = 0, extra = 0;
    bool read = false;
};

/* Streams before 2.1 carry a hole-event count that Draco trusts: found
 * behind the topology splits (c at the traversal's size, before 2.2, or at
 * the splits) and bounded by the bytes left (each event takes at least
 * one). read as in counts. */
static mcf_status check_hole_events(cursor c, int ver, uint32_t nfaces, bool *read,
                                    mcf_error *err)
{
    cursor e = c;
    uint32_t nsplits, nholes = 0, size, v;
    *read = false;
    if (ver < 0x202) {
        if (!c.count(ver, &size) || size == 0 || size > c.left())
            return MCF_OK;
        e.p = c.p + size;
    }
    if (!e.count(ver, &nsplits) || nsplits > nfaces)
        return MCF_OK;
    for (uint32_t k = 0; k < nsplits; k++) {
        if (ver < 0x102) {
            if (e.left() < 9)
                return MCF_OK;
            e.p += 9;
        } else if (!e.varint(&v) || !e.varint(&v)) {
            return MCF_OK;
        }
    }
    if (ver >= 0x102 && nsplits > 0) {
        size_t bytes = (static_cast<size_t>(nsplits) * 2 + 7) / 8;
        if (bytes > e.left())
            return MCF_OK;
        e.p += bytes;
    }
    if (!e.count(ver, &nholes))
        return MCF_OK;
    if (nholes > e.left())
        return api__fail(err, MCF_EDECODE, "draco: %u hole events in %zu bytes", nholes,
                         e.left());
    *read = true;
    return MCF_OK;
}

/* The sequential connectivity header: faces, points. */
static void sequential_counts(cursor *c, int ver, counts *n)
{
    n->read = (ver < 0x202 ? c->u32(&n->nfaces) : c->varint(&n->nfaces)) &&
              (ver < 0x202 ? c->u32(&n->nverts) : c->varint(&n->nverts));
}

/* The edgebreaker connectivity header: its counts, split symbols no more
 * than faces, and (within the limits, before 2.1) the hole events. */
static mcf_status edgebreaker_counts(cursor *c, int ver, const api_limits *lim, counts *n,
                                     mcf_error *err)
{
    uint32_t v, nattr, nsym, nsplit;
    if (!c->u8(&v) || (ver < 0x202 && !c->count(ver, &n->extra)))
        return MCF_OK;
    if (!c->count(ver, &n->nverts) || !c->count(ver, &n->nfaces) || !c->u8(&nattr) ||
        !c->count(ver, &nsym) || !c->count(ver, &nsplit))
        return MCF_OK;
    if (nsplit > n->nfaces)
        return api__fail(err, MCF_EDECODE, "draco: %u split symbols for %u faces", nsplit,
                         n->nfaces);
    if (n->nfaces <= static_cast<uint32_t>(lim->max_faces) &&
        n->nverts <= static_cast<uint32_t>(lim->max_vertices) && ver < 0x201)
        return check_hole_events(*c, ver, n->nfaces, &n->read, err);
    n->read = true;
    return MCF_OK;
}

mcf_status check_counts(const uint8_t *buf, size_t len, const api_limits *lim,
                        mcf_error *err, uint32_t *declared)
{
    cursor c{buf, buf + len};
    counts n;
    mcf_status rc;
    if (len < 11)
        return MCF_OK; /* Draco's header check reports it */
    const int ver = buf[5] << 8 | buf[6];
    const int method = buf[8];
    const unsigned flags = buf[9] | buf[10] << 8;
    c.p += 11;
    if (ver >= 0x103 && (flags & 0x8000) && (rc = skip_all_metadata(&c, err)) != MCF_OK)
        return rc;
    if (method == 0) {
        sequential_counts(&c, ver, &n);
    } else if (method == 1) {
        if ((rc = edgebreaker_counts(&c, ver, lim, &n, err)) != MCF_OK)
            return rc;
    } else {
        return MCF_OK; /* Draco refuses unknown methods */
    }
    if (!n.read)
        return MCF_OK;
    const uint32_t nv = n.nverts > n.extra ? n.nverts : n.extra;
    if (declared) { /* what the memory estimate sizes (api_estimate.c) */
        declared[0] = nv;
        declared[1] = n.nfaces;
    }
    if (n.nfaces > static_cast<uint32_t>(lim->max_faces))
        return api__fail(err, MCF_ELIMIT,
                         "draco: header declares %u faces, more than max_faces (%d)",
                         n.nfaces, lim->max_faces);
    /* libdraco sizes its corner table from the declared faces before it
     * reads them (about 24 B a face): 26 bytes declaring 9,999,999 faces
     * took 243 MB in `mcf info` (issue 28). The densest stream we made, a
     * flat 1000 x 1000 grid at 1-bit quantization, holds 684 faces a
     * byte (600 x 600: 496); 16,384 a byte, plus 4,096, is far above
     * any real stream (scans: under 1 a byte) and lets 26 bytes ask for
     * 14 MB at most. */
    if (n.nfaces > 4096 + 16384 * static_cast<uint64_t>(len))
        return api__fail(err, MCF_ELIMIT,
                         "draco: header declares %u faces in a %zu-byte stream, more "
                         "than 16384 a byte: refused before decoding",
                         n.nfaces, len);
    if (nv > static_cast<uint32_t>(lim->max_vertices))
        return api__fail(err, MCF_ELIMIT,
                         "draco: header declares %u vertices, more than "
                         "max_vertices (%d)",
                         nv, lim->max_vertices);
    return MCF_OK;
}

} // namespace api_draco
