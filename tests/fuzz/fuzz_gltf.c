/* SPDX-License-Identifier: MIT */
/*
 * fuzz_gltf.c - libFuzzer target: api_gltf_decode_attrs on arbitrary bytes
 * (GLB or .gltf: the checks, tinygltf, the accessor reads, Draco
 * primitives, the weld), then what the daemon does next with a decoded
 * document: its record through the sandbox's pack and back, and the
 * rewrite into a GLB, which must decode again to the same counts (the
 * positions did not move, so the weld is the same; abort() otherwise).
 * Build and run: make fuzz FUZZ_TIME=30 (seeds in corpus_gltf/, gltf.dict).
 */
#include <stdio.h>
#include <stdlib.h>

#include "fuzz_common.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    api_limits lim;
    mcf_mesh *m = NULL, *m2 = NULL, *m3 = NULL;
    api_attrs *a = NULL, *a2 = NULL;
    mcf_error err;
    api_encode_opts o;
    api_buf pack, out;

    api_limits_default(&lim);
    if (api_gltf_decode_attrs(data, size, &lim, &m, &a, &err) != MCF_OK)
        return 0;
    api_buf_init(&pack, (size_t)-1);
    api_buf_init(&out, lim.max_input_bytes);
    if (api_mesh_pack(m, a, &pack, &err) != MCF_OK ||
        api_mesh_unpack(pack.data, pack.len, &lim, &m2, &a2, &err) != MCF_OK) {
        fprintf(stderr, "fuzz_gltf: pack: %s\n", err.msg);
        abort();
    }
    api_encode_opts_init(&o);
    o.format = API_FMT_GLB;
    o.attrs = a2;
    if (api_mesh_encode(m2, &o, &out, &err) == MCF_OK) {
        if (api_gltf_decode_attrs(out.data, out.len, &lim, &m3, NULL, &err) != MCF_OK ||
            mcf_mesh_nvertices(m3) != mcf_mesh_nvertices(m) ||
            mcf_mesh_nfaces(m3) != mcf_mesh_nfaces(m)) {
            fprintf(stderr, "fuzz_gltf: the rewritten document: %s\n", err.msg);
            abort();
        }
    }
    mcf_mesh_free(m);
    mcf_mesh_free(m2);
    mcf_mesh_free(m3);
    api_attrs_free(a);
    api_attrs_free(a2);
    api_buf_free(&pack);
    api_buf_free(&out);
    return 0;
}
