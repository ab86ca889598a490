/* SPDX-License-Identifier: MIT */
/*
 * fuzz_off.c - libFuzzer target: api_off_decode on arbitrary bytes, a
 * decoded mesh inspected too (the harness: fuzz_common.h).
 * Build and run: make fuzz FUZZ_TIME=30 (seeds in corpus_off/, off.dict).
 */
#include "fuzz_common.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return fuzz_decode(api_off_decode, data, size);
}
