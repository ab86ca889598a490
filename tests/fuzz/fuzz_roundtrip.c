/* SPDX-License-Identifier: MIT */
/*
 * fuzz_roundtrip.c - libFuzzer target: api_mesh_decode (format detected
 * from the bytes) -> api_mesh_encode in the same format -> decode again.
 * Every writer is exact for what its reader produced, so the second mesh
 * must equal the first bit for bit (positions and faces), not only in its
 * counts; abort() otherwise. The encodings chosen are the exact ones:
 * Draco lossless sequential (keeps order), PLY ascii or binary (last byte
 * of the input picks), STL ASCII (%.17g; binary STL would round to float
 * and may weld more), OBJ and OFF (%.17g). Then once more with the
 * input's attributes (api_mesh_decode_attrs, o.attrs) and the default
 * Draco settings: the output must decode, with its attributes, to the same
 * number of faces (points split at attribute seams, and positions may be
 * rounded to float32 or quantized, so counts of faces are what must hold),
 * less at most the faces with a repeated vertex, which Draco's edgebreaker
 * drops.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz_common.h"

static void die(const char *what, const char *msg)
{
    fprintf(stderr, "fuzz_roundtrip: %s: %s\n", what, msg);
    abort();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    api_limits lim;
    mcf_mesh *m = NULL, *m2 = NULL;
    api_attrs *a = NULL, *a2 = NULL;
    mcf_error err;
    api_format fmt = API_FMT_UNKNOWN, fmt2 = API_FMT_UNKNOWN;
    api_encode_opts o;
    api_buf out;
    mcf_status rc;
    int nv, nf, repeated = 0;

    api_limits_default(&lim);
    if (api_mesh_decode_attrs(data, size, &lim, &m, &a, &fmt, &err) != MCF_OK)
        return 0;
    api_encode_opts_init(&o);
    o.format = fmt;
    o.quantization_bits = 0;
    o.preserve_order = 1;
    o.stl_binary = 0;
    o.ply_binary = size > 0 && (data[size - 1] & 1);
    api_buf_init(&out, lim.max_input_bytes);
    rc = api_mesh_encode(m, &o, &out, &err);
    if (rc != MCF_OK) {
        /* The only acceptable refusal: output beyond the input limit. */
        if (rc != MCF_ELIMIT)
            die("encode", err.msg);
        goto done;
    }
    if (api_mesh_decode(out.data, out.len, &lim, &m2, &fmt2, &err) != MCF_OK)
        die("second decode", err.msg);
    if (fmt2 != fmt)
        die("format", api_format_name(fmt2));
    nv = mcf_mesh_nvertices(m);
    nf = mcf_mesh_nfaces(m);
    if (mcf_mesh_nvertices(m2) != nv || mcf_mesh_nfaces(m2) != nf)
        die("counts", api_format_name(fmt));
    if (memcmp(mcf_mesh_positions(m), mcf_mesh_positions(m2),
               sizeof(double) * 3 * (size_t)nv) != 0)
        die("positions", api_format_name(fmt));
    if (memcmp(mcf_mesh_faces(m), mcf_mesh_faces(m2),
               sizeof(int32_t) * 3 * (size_t)nf) != 0)
        die("faces", api_format_name(fmt));

    /* With the attributes, default Draco options. Faces with a repeated
     * vertex are counted: edgebreaker drops them (and refuses a mesh of
     * nothing else). */
    {
        const int32_t *F = mcf_mesh_faces(m);
        int f;
        for (f = 0; f < nf; f++)
            repeated += F[3 * f] == F[3 * f + 1] || F[3 * f + 1] == F[3 * f + 2]
                        || F[3 * f] == F[3 * f + 2];
    }
    mcf_mesh_free(m2);
    m2 = NULL;
    api_buf_free(&out);
    api_buf_init(&out, lim.max_input_bytes);
    api_encode_opts_init(&o);
    o.format = fmt;
    o.attrs = a;
    o.ply_binary = size > 0 && (data[size - 1] & 1);
    rc = api_mesh_encode(m, &o, &out, &err);
    if (rc != MCF_OK) {
        /* Output too large, or a coordinate past the float range for
         * quantized Draco: nothing else may refuse. */
        if (rc != MCF_ELIMIT && !(fmt == API_FMT_DRACO && rc == MCF_EINVAL)
            && !(fmt == API_FMT_DRACO && rc == MCF_EMESH && repeated == nf))
            die("encode with attributes", err.msg);
        goto done;
    }
    if (api_mesh_decode_attrs(out.data, out.len, &lim, &m2, &a2, &fmt2, &err) != MCF_OK)
        die("decode with attributes", err.msg);
    if (mcf_mesh_nfaces(m2) > nf
        || mcf_mesh_nfaces(m2) < nf - (fmt == API_FMT_DRACO ? repeated : 0))
        die("faces with attributes", api_format_name(fmt));
done:
    api_attrs_free(a);
    api_attrs_free(a2);
    mcf_mesh_free(m2);
    mcf_mesh_free(m);
    api_buf_free(&out);
    return 0;
}
