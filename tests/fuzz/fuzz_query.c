/* SPDX-License-Identifier: MIT */
/*
 * fuzz_query.c - libFuzzer target: api_params_parse_query on an arbitrary
 * NUL-terminated string (the bytes up to the first NUL), with the keys a
 * daemon would skip listed in `ignore`. Dictionary: json.dict (key names).
 */
#include <stdlib.h>
#include <string.h>

#include "fuzz_common.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const char *const ignore[] = {"async", "callback", NULL};
    api_limits lim;
    api_params p;
    mcf_error err;
    char *qs = malloc(size + 1);

    if (!qs)
        return 0;
    memcpy(qs, data, size);
    qs[size] = '\0';
    api_limits_default(&lim);
    api_params_init(&p);
    if (api_params_parse_query(&p, qs, ignore, &lim, &err) == MCF_OK)
        (void)api_params_finish(&p, 1000, &lim, &err);
    api_params_free(&p);
    free(qs);
    return 0;
}
