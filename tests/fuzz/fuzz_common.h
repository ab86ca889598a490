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

#endif /* FUZZ_COMMON_H */
