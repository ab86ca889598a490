/* SPDX-License-Identifier: MIT */
/*
 * fuzz_common.h - what the libFuzzer targets of tests/fuzz/ share: the
 * entry point's prototype (-Wmissing-prototypes) and the harness of the
 * single-format decoder targets.
 *
 * A decoder target runs one api_*_decode on the fuzzer's bytes under the
 * default limits (the fuzzer meets the same bounds as production) and
 * inspects a decoded mesh too, so core's validation sees odd meshes:
 *
 *     int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
 *     {
 *         return fuzz_decode(api_obj_decode, data, size);
 *     }
 *
 * A header, not a .c file: the Makefile builds every tests/fuzz/fuzz_*.c
 * into a target of its own and links it with the libraries only.
 */
#ifndef FUZZ_COMMON_H
#define FUZZ_COMMON_H

#include <stddef.h>
#include <stdint.h>

#include "api.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* The signature shared by api_obj_decode, api_off_decode, api_ply_decode,
 * api_stl_decode and api_draco_decode. */
typedef mcf_status (*fuzz_decoder)(const void *buf, size_t len,
                                   const api_limits *lim, mcf_mesh **out,
                                   mcf_error *err);

/* Decodes data with dec; a mesh that comes out is inspected and freed.
 * Returns 0, as libFuzzer wants (a crash or sanitizer report is the
 * finding). */
static inline int fuzz_decode(fuzz_decoder dec, const uint8_t *data, size_t size)
{
    api_limits lim;
    mcf_mesh *m = NULL;
    mcf_error err;
    mcf_mesh_info info;

    api_limits_default(&lim);
    if (dec(data, size, &lim, &m, &err) == MCF_OK) {
        (void)mcf_mesh_inspect(m, &info, &err);
        mcf_mesh_free(m);
    }
    return 0;
}

/* The attribute-returning decoders (api_obj_decode_attrs, api_ply_...,
 * api_draco_...): the same, and every attribute's corner indices are
 * checked against its value count (a bad one would be a decoder bug). */
typedef mcf_status (*fuzz_attrs_decoder)(const void *buf, size_t len,
                                         const api_limits *lim, mcf_mesh **out,
                                         api_attrs **attrs, mcf_error *err);

static inline int fuzz_decode_attrs(fuzz_attrs_decoder dec, const uint8_t *data,
                                    size_t size)
{
    api_limits lim;
    mcf_mesh *m = NULL;
    api_attrs *a = NULL;
    mcf_error err;
    mcf_mesh_info info;
    int k;

    api_limits_default(&lim);
    if (dec(data, size, &lim, &m, &a, &err) == MCF_OK) {
        for (k = 0; k < API_ATTR_KINDS; k++) {
            int n, nv, c;
            const double *v;
            const int32_t *cr;
            if (!api_attrs_get(a, (api_attr_kind)k, &n, &nv, &v, &cr))
                continue;
            for (c = 0; c < 3 * mcf_mesh_nfaces(m); c++)
                if (cr[c] < 0 || cr[c] >= nv)
                    __builtin_trap();
        }
        (void)mcf_mesh_inspect(m, &info, &err);
        mcf_mesh_free(m);
        api_attrs_free(a);
    }
    return 0;
}

#endif /* FUZZ_COMMON_H */
