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

/* Skips one metadata block (MetadataDecoder::DecodeMetadata) strictly. */
static mcf_status skip_metadata(cursor *c, int depth, mcf_error *err)
{
    uint32_t n, len = 0, k;
    if (depth > 32)
        return api__fail(err, MCF_EDECODE, "draco: metadata nested deeper than 32 levels");
    if (!c->varint(&n))
        return api__fail(err, MCF_EDECODE, "draco: truncated metadata");
    if (n > c->left())
        return api__fail(err, MCF_EDECODE,
                         "draco: metadata declares %u entries in %zu bytes", n,
                         c->left());
    for (k = 0; k < n; k++) {
        uint32_t name;
        if (!c->u8(&name) || name > c->left())
            return api__fail(err, MCF_EDECODE, "draco: truncated metadata");
        c->p += name;
        if (!c->varint(&len) || len == 0 || len > c->left())
            return api__fail(err, MCF_EDECODE,
                             "draco: metadata entry of %u bytes in %zu", len,
                             c->left());
        c->p += len;
    }
    if (!c->varint(&n))
        return api__fail(err, MCF_EDECODE, "draco: truncated metadata");
    if (n > c->left())
        return api__fail(err, MCF_EDECODE,
                         "draco: metadata declares %u sub-metadata in %zu bytes", n,
                         c->left());
    for (k = 0; k < n; k++) {
        uint32_t name;
        if (!c->u8(&name) || name > c->left())
            return api__fail(err, MCF_EDECODE, "draco: truncated metadata");
        c->p += name;
        mcf_status rc = skip_metadata(c, depth + 1, err);
        if (rc != MCF_OK)
            return rc;
    }
    return MCF_OK;
}

mcf_status check_counts(const uint8_t *buf, size_t len, const api_limits *lim,
                        mcf_error *err, uint32_t *declared)
{
    cursor c{buf, buf + len};
    if (len < 11)
        return MCF_OK; /* Draco's header check reports it */
    const int ver = buf[5] << 8 | buf[6];
    const int method = buf[8];
    const unsigned flags = buf[9] | buf[10] << 8;
    c.p += 11;
    if (ver >= 0x103 && (flags & 0x8000)) {
        uint32_t n, k, id;
        if (!c.varint(&n))
            return api__fail(err, MCF_EDECODE, "draco: truncated metadata");
        if (n > c.left())
            return api__fail(err, MCF_EDECODE,
                             "draco: metadata declares %u attribute blocks in %zu "
                             "bytes",
                             n, c.left());
        for (k = 0; k < n; k++) {
            if (!c.varint(&id))
                return api__fail(err, MCF_EDECODE, "draco: truncated metadata");
            mcf_status rc = skip_metadata(&c, 0, err);
            if (rc != MCF_OK)
                return rc;
        }
        mcf_status rc = skip_metadata(&c, 0, err);
        if (rc != MCF_OK)
            return rc;
    }
    uint32_t nfaces = 0, nverts = 0, extra = 0, v;
    if (method == 0) { /* sequential: faces, points */
        if (!(ver < 0x202 ? c.u32(&nfaces) : c.varint(&nfaces)) ||
            !(ver < 0x202 ? c.u32(&nverts) : c.varint(&nverts)))
            return MCF_OK;
    } else if (method == 1) { /* edgebreaker */
        uint32_t nattr, nsym, nsplit;
        if (!c.u8(&v))
            return MCF_OK;
        if (ver < 0x202) {
            if (!c.count(ver, &extra))
                return MCF_OK;
        }
        if (!c.count(ver, &nverts) || !c.count(ver, &nfaces) || !c.u8(&nattr) ||
            !c.count(ver, &nsym) || !c.count(ver, &nsplit))
            return MCF_OK;
        if (nsplit > nfaces)
            return api__fail(err, MCF_EDECODE,
                             "draco: %u split symbols for %u faces", nsplit, nfaces);
        if (nfaces <= static_cast<uint32_t>(lim->max_faces) &&
            nverts <= static_cast<uint32_t>(lim->max_vertices) && ver < 0x201) {
            /* Streams before 2.1 carry a hole-event count that Draco trusts:
             * find it behind the topology splits and bound it by the bytes
             * left (each event takes at least one). */
            cursor e = c;
            uint32_t nsplits, nholes = 0, size;
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
                return api__fail(err, MCF_EDECODE,
                                 "draco: %u hole events in %zu bytes", nholes,
                                 e.left());
        }
    } else {
        return MCF_OK; /* Draco refuses unknown methods */
    }
    if (declared) { /* what the memory estimate sizes (api_estimate.c) */
        declared[0] = nverts > extra ? nverts : extra;
        declared[1] = nfaces;
    }
    if (nfaces > static_cast<uint32_t>(lim->max_faces))
        return api__fail(err, MCF_ELIMIT,
                         "draco: header declares %u faces, more than max_faces (%d)",
                         nfaces, lim->max_faces);
    if (nverts > static_cast<uint32_t>(lim->max_vertices) ||
        extra > static_cast<uint32_t>(lim->max_vertices))
        return api__fail(err, MCF_ELIMIT,
                         "draco: header declares %u vertices, more than "
                         "max_vertices (%d)",
                         nverts > extra ? nverts : extra, lim->max_vertices);
    return MCF_OK;
}

} // namespace api_draco
