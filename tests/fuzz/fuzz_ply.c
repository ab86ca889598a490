/* SPDX-License-Identifier: MIT */
/*
 * fuzz_ply.c - libFuzzer target: api_ply_decode_attrs on arbitrary bytes, a
 * decoded mesh inspected too (the harness: fuzz_common.h).
 * Build and run: make fuzz FUZZ_TIME=30 (seeds in corpus_ply/, ply.dict).
 */
#include "fuzz_common.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    /* With the attributes: the plain decoder is this one without them. */
    return fuzz_decode_attrs(api_ply_decode_attrs, data, size);
}
