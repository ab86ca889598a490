/*
 * fuzz_ply.c - libFuzzer target: api_ply_decode on arbitrary bytes, under
 * the default limits (the fuzzer meets the same bounds as production).
 * A decoded mesh is inspected too, so core's validation sees odd meshes.
 * Build and run: make fuzz FUZZ_TIME=30 (seeds in corpus_ply/).
 */
#include <stdint.h>
#include <stddef.h>

#include "api.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    api_limits lim;
    mcf_mesh *m = NULL;
    mcf_error err;
    mcf_mesh_info info;

    api_limits_default(&lim);
    if (api_ply_decode(data, size, &lim, &m, &err) == MCF_OK) {
        (void)mcf_mesh_inspect(m, &info, &err);
        mcf_mesh_free(m);
    }
    return 0;
}
