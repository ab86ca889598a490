/* SPDX-License-Identifier: MIT */
/*
 * api_draco.cc - Google Draco (.drc) decoder and encoder: a thin extern "C"
 * bridge over Debian's libdraco 1.5.5 (api.h's api_draco_*, and
 * api_internal.h's primitives for glTF).
 *
 * Files (sharing api_draco_internal.h): api_draco_check.cc (the counts a
 * stream declares, checked before libdraco allocates by them),
 * api_draco_decode.cc (decoder, attributes, primitives), api_draco_encode.cc
 * (encoder, primitives), api_draco_measure.cc (the encoder's
 * *max_quant_err, measured on the decoded stream).
 *
 * Primitives (api__draco_prim_decode / _encode, for glTF's
 * KHR_draco_mesh_compression): every attribute as it came, by unique id,
 * its points' values as raw bytes of their data type and its quantization
 * (bits and grid, from the same second decode), and back: the same ids,
 * types and quantization (a grid reused where the values still lie on
 * it), edgebreaker, through the ExpertEncoder's per-attribute options.
 *
 * Every entry point catches all C++ exceptions: std::bad_alloc becomes
 * ENOMEM, anything else EDECODE (decoder) or EMESH (encoder). No C++ type
 * or exception crosses api.h.
 */
#include <cstdlib>
#include <cstring>
#include <new>

#include "api_draco_internal.h"

using namespace api_draco;

extern "C" mcf_status api_draco_decode(const void *buf, size_t len,
                                       const api_limits *lim, mcf_mesh **out,
                                       mcf_error *err)
{
    return api_draco_decode_attrs(buf, len, lim, out, nullptr, err);
}

extern "C" mcf_status api_draco_decode_attrs(const void *buf, size_t len,
                                             const api_limits *lim,
                                             mcf_mesh **out, api_attrs **attrs,
                                             mcf_error *err)
{
    try {
        return decode(buf, len, lim, out, attrs, err);
    } catch (const std::bad_alloc &) {
        return api__fail(err, MCF_ENOMEM, "draco: out of memory while decoding");
    } catch (...) {
        return api__fail(err, MCF_EDECODE, "draco: the decoder failed (exception)");
    }
}

extern "C" mcf_status api_draco_encode(const mcf_mesh *m,
                                       const api_encode_opts *o, api_buf *out,
                                       double *max_quant_err, mcf_error *err)
{
    try {
        return encode(m, o, out, max_quant_err, err);
    } catch (const std::bad_alloc &) {
        return api__fail(err, MCF_ENOMEM, "draco: out of memory while encoding");
    } catch (...) {
        return api__fail(err, MCF_EMESH, "draco: the encoder failed (exception)");
    }
}

extern "C" int api__draco_declared(const void *buf, size_t len, uint32_t *nv,
                                   uint32_t *nf)
{
    api_limits lim;
    uint32_t d[2] = {0, 0};
    if (len < 11 || memcmp(buf, "DRACO", 5) != 0)
        return 0;
    api_limits_default(&lim);
    lim.max_faces = lim.max_vertices = 0x7fffffff;
    try {
        check_counts(static_cast<const uint8_t *>(buf), len, &lim, nullptr, d);
    } catch (...) {
        return 0;
    }
    *nv = d[0];
    *nf = d[1];
    return d[1] > 0;
}

extern "C" void api__draco_prim_free(api__draco_prim *p)
{
    if (!p)
        return;
    for (int i = 0; i < p->nattr; i++)
        std::free(p->attr[i].data);
    std::free(p->attr);
    std::free(p->faces);
    std::memset(p, 0, sizeof *p);
}

extern "C" mcf_status api__draco_prim_decode(const void *buf, size_t len,
                                             const api_limits *lim,
                                             api__draco_prim *out, mcf_error *err)
{
    api_limits def;
    if (!lim) {
        api_limits_default(&def);
        lim = &def;
    }
    std::memset(out, 0, sizeof *out);
    try {
        return prim_decode(buf, len, lim, out, err);
    } catch (const std::bad_alloc &) {
        return api__fail(err, MCF_ENOMEM, "draco: out of memory while decoding");
    } catch (...) {
        return api__fail(err, MCF_EDECODE, "draco: the decoder failed (exception)");
    }
}

extern "C" mcf_status api__draco_prim_encode(const api__draco_prim *p, int level,
                                             api_buf *out, mcf_error *err)
{
    if (level < 0 || level > 10)
        return api__fail(err, MCF_EINVAL,
                         "draco: compression_level %d out of range (0..10)", level);
    try {
        return prim_encode(p, level, out, err);
    } catch (const std::bad_alloc &) {
        return api__fail(err, MCF_ENOMEM, "draco: out of memory while encoding");
    } catch (...) {
        return api__fail(err, MCF_EMESH, "draco: the encoder failed (exception)");
    }
}
