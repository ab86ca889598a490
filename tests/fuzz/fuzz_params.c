/* SPDX-License-Identifier: MIT */
/*
 * fuzz_params.c - libFuzzer target: api_params_parse_json on arbitrary
 * bytes (default limits: size and depth bounded as in production). Parsed
 * parameters are finished against a small mesh size and printed back as
 * JSON, so the whole parameter path runs. Dictionary: json.dict.
 */
#include <stdlib.h>

#include "fuzz_common.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    api_limits lim;
    api_params p;
    mcf_error err;

    api_limits_default(&lim);
    api_params_init(&p);
    if (api_params_parse_json(&p, (const char *)data, size, &lim, &err) == MCF_OK) {
        cJSON *j;
        (void)api_params_finish(&p, 1000, &lim, &err);
        j = api_params_to_json(&p);
        if (j) {
            char *s = api_json_print(j, 0);
            free(s);
            cJSON_Delete(j);
        }
    }
    api_params_free(&p);
    return 0;
}
