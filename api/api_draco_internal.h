/* SPDX-License-Identifier: MIT */
/*
 * api_draco_internal.h - what the Draco bridge's files share (C++ only,
 * never included outside api_draco*.cc): the count pre-check before
 * libdraco reads a stream (api_draco_check.cc), the decoder
 * (api_draco_decode.cc), the encoder (api_draco_encode.cc) and its
 * round-trip measurement (api_draco_measure.cc); api_draco.cc wraps them
 * in the extern "C" entry points of api.h and api_internal.h.
 */
#ifndef API_DRACO_INTERNAL_H
#define API_DRACO_INTERNAL_H

#include <cstddef>
#include <cstdint>

#include "draco/mesh/mesh.h"

#include "api.h"
extern "C" {
#include "api_internal.h"
}

namespace api_draco {

/* api_draco_check.cc: the counts a stream's header declares, against lim
 * and the input's size, before libdraco allocates by them; declared: the
 * vertex and face counts read. */
mcf_status check_counts(const uint8_t *buf, size_t len, const api_limits *lim,
                        mcf_error *err, uint32_t *declared = nullptr);

/* api_draco_decode.cc */
/* The checks before libdraco decodes a stream: magic, a triangle mesh
 * (not a point cloud), the header's counts within lim. */
mcf_status check_stream(const void *buf, size_t len, const api_limits *lim,
                        mcf_error *err);
/* The 3 components of value v of attribute a as doubles (bound-checked). */
bool read_position(const draco::PointAttribute *a, uint32_t v, double out[3]);
/* The quantization of attribute a (of a mesh decoded with the transforms
 * skipped): its bits (0: stored raw) and, for a quantized one, the grid. */
int transform_bits(const draco::PointAttribute *a, float origin[4], float *range);
mcf_status decode(const void *buf, size_t len, const api_limits *lim,
                  mcf_mesh **out, api_attrs **attrs, mcf_error *err);
mcf_status prim_decode(const void *buf, size_t len, const api_limits *lim,
                       api__draco_prim *out, mcf_error *err);

/* api_draco_encode.cc */
mcf_status encode(const mcf_mesh *m, const api_encode_opts *o, api_buf *out,
                  double *max_quant_err, mcf_error *err);
mcf_status prim_encode(const api__draco_prim *p, int level, api_buf *out,
                       mcf_error *err);

/* api_draco_measure.cc: every input face against its decoded counterpart
 * in dm within tol (*maxerr: the largest corner distance); false and
 * *worst_face when a face has none. */
bool measure(int nv, const double *X, int nf, const int32_t *F,
             const draco::Mesh &dm, double tol, double *maxerr,
             int *worst_face);

} // namespace api_draco

#endif
