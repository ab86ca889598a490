/* SPDX-License-Identifier: MIT */
/*
 * api_fields.c - the per-vertex fields of a smoothing run, for viewers
 * (the daemon's GET /v1/jobs/{id}/fields, the page it serves): both meshes'
 * positions, the shared faces, mean and Gaussian curvature of each (the
 * core's mcf_curvature) and how far each vertex moved, in one compact
 * binary document a browser maps onto typed arrays without parsing.
 *
 * Layout (api.h, API_FIELDS_MAGIC; api/openapi.yaml, FieldsDocument):
 *   "MCFF"  u32 version  u32 header_len  header (JSON, space-padded to a
 *   multiple of 4)  data
 * Every number in the fixed part and in data is little-endian. The header
 * lists the arrays with their offset from the start of data (a multiple
 * of 4, so a Float32Array or Uint32Array views it in place), element type,
 * components and count, and for each scalar field its finite min, max and
 * 2nd/98th percentiles (a colour scale that one spike cannot flatten).
 * Positions and fields are float32: a viewer draws float32, and the 24
 * significant bits are far finer than any curvature the colours show.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "api_internal.h"

/* Appends v as 4 little-endian bytes whatever the host's byte order. */
static mcf_status put_u32(api_buf *b, uint32_t v)
{
    unsigned char x[4] = {(unsigned char)v, (unsigned char)(v >> 8),
                          (unsigned char)(v >> 16), (unsigned char)(v >> 24)};
    return api_buf_append(b, x, 4);
}

static mcf_status put_f32s(api_buf *b, const double *v, size_t n)
{
    mcf_status rc = MCF_OK;
    size_t i;
    for (i = 0; i < n && rc == MCF_OK; i++) {
        float f = (float)v[i];
        uint32_t u;
        memcpy(&u, &f, 4);
        rc = put_u32(b, u);
    }
    return rc;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* min, max and the 2nd and 98th percentiles (nearest rank) of the finite
 * values; all null when there is none. */
static cJSON *stats_json(const double *v, int n)
{
    cJSON *o = cJSON_CreateObject();
    double *s = malloc((size_t)(n > 0 ? n : 1) * sizeof *s);
    int i, k = 0;

    if (!o || !s) {
        free(s);
        cJSON_Delete(o);
        return NULL;
    }
    for (i = 0; i < n; i++)
        if (isfinite(v[i]))
            s[k++] = v[i];
    if (k == 0) {
        cJSON_AddNullToObject(o, "min");
        cJSON_AddNullToObject(o, "max");
        cJSON_AddNullToObject(o, "p02");
        cJSON_AddNullToObject(o, "p98");
    } else {
        qsort(s, (size_t)k, sizeof *s, cmp_double);
        cJSON_AddNumberToObject(o, "min", s[0]);
        cJSON_AddNumberToObject(o, "max", s[k - 1]);
        cJSON_AddNumberToObject(o, "p02", s[(int)(0.02 * (k - 1) + 0.5)]);
        cJSON_AddNumberToObject(o, "p98", s[(int)(0.98 * (k - 1) + 0.5)]);
    }
    free(s);
    return o;
}

typedef struct {
    const char *name;
    const double *v;   /* NULL: the faces */
    int comps, count;
} field;

mcf_status api_fields_encode(const mcf_mesh *before, const mcf_mesh *after,
                             api_buf *out, mcf_error *err)
{
    int nv = mcf_mesh_nvertices(before), nf = mcf_mesh_nfaces(before), i;
    const double *X0 = mcf_mesh_positions(before), *X1 = mcf_mesh_positions(after);
    const int32_t *F = mcf_mesh_faces(before);
    double *buf = NULL;
    cJSON *hdr = NULL, *arr;
    char *text = NULL;
    size_t off = 0, hlen;
    mcf_status rc;
    field f[8];
    int k;

    if (mcf_mesh_nvertices(after) != nv || mcf_mesh_nfaces(after) != nf ||
        memcmp(F, mcf_mesh_faces(after), (size_t)nf * 3 * sizeof *F) != 0)
        return mcf_error_set(err, MCF_EINVAL, "fields: the result does not "
                             "share the input's connectivity");
    /* H0 K0 H1 K1 D, nv each */
    buf = malloc((size_t)nv * 5 * sizeof *buf);
    if (!buf)
        return mcf_error_set(err, MCF_ENOMEM, "fields: out of memory for %d "
                             "vertices", nv);
    if ((rc = mcf_curvature(before, NULL, buf, buf + nv, NULL, err)) != MCF_OK ||
        (rc = mcf_curvature(after, NULL, buf + 2 * (size_t)nv,
                            buf + 3 * (size_t)nv, NULL, err)) != MCF_OK)
        goto done;
    for (i = 0; i < nv; i++) {
        const double *a = X0 + 3 * (size_t)i, *b = X1 + 3 * (size_t)i;
        buf[4 * (size_t)nv + i] = sqrt((b[0] - a[0]) * (b[0] - a[0]) +
                                       (b[1] - a[1]) * (b[1] - a[1]) +
                                       (b[2] - a[2]) * (b[2] - a[2]));
    }
    f[0] = (field){"faces", NULL, 3, nf};
    f[1] = (field){"input.positions", X0, 3, nv};
    f[2] = (field){"input.mean_curvature", buf, 1, nv};
    f[3] = (field){"input.gaussian_curvature", buf + nv, 1, nv};
    f[4] = (field){"result.positions", X1, 3, nv};
    f[5] = (field){"result.mean_curvature", buf + 2 * (size_t)nv, 1, nv};
    f[6] = (field){"result.gaussian_curvature", buf + 3 * (size_t)nv, 1, nv};
    f[7] = (field){"displacement", buf + 4 * (size_t)nv, 1, nv};

    rc = MCF_ENOMEM;
    if (!(hdr = cJSON_CreateObject()) ||
        !cJSON_AddNumberToObject(hdr, "vertices", nv) ||
        !cJSON_AddNumberToObject(hdr, "faces", nf) ||
        !(arr = cJSON_AddArrayToObject(hdr, "arrays")))
        goto nomem;
    for (k = 0; k < 8; k++) {
        cJSON *a = cJSON_CreateObject();
        if (!a || !cJSON_AddItemToArray(arr, a)) {
            cJSON_Delete(a);
            goto nomem;
        }
        if (!cJSON_AddStringToObject(a, "name", f[k].name) ||
            !cJSON_AddStringToObject(a, "type", f[k].v ? "float32" : "uint32") ||
            !cJSON_AddNumberToObject(a, "components", f[k].comps) ||
            !cJSON_AddNumberToObject(a, "count", f[k].count) ||
            !cJSON_AddNumberToObject(a, "offset", (double)off))
            goto nomem;
        if (f[k].comps == 1) {
            cJSON *s = stats_json(f[k].v, nv);
            if (!s || !cJSON_AddItemToObject(a, "stats", s)) {
                cJSON_Delete(s);
                goto nomem;
            }
        }
        off += (size_t)f[k].count * (size_t)f[k].comps * 4;
    }
    if (!(text = cJSON_PrintUnformatted(hdr)))
        goto nomem;
    hlen = (strlen(text) + 3) / 4 * 4;
    if ((rc = api_buf_append(out, API_FIELDS_MAGIC, 4)) != MCF_OK ||
        (rc = put_u32(out, API_FIELDS_VERSION)) != MCF_OK ||
        (rc = put_u32(out, (uint32_t)hlen)) != MCF_OK ||
        (rc = api_buf_append(out, text, strlen(text))) != MCF_OK ||
        (rc = api_buf_append(out, "   ", hlen - strlen(text))) != MCF_OK)
        goto nomem;
    for (i = 0; i < 3 * nf && rc == MCF_OK; i++)
        rc = put_u32(out, (uint32_t)F[i]);
    for (k = 1; k < 8 && rc == MCF_OK; k++)
        rc = put_f32s(out, f[k].v, (size_t)f[k].count * (size_t)f[k].comps);
    if (rc != MCF_OK)
        goto nomem;
    rc = MCF_OK;
    goto done;
nomem:
    rc = rc == MCF_ELIMIT
             ? mcf_error_set(err, rc, "fields: the document of %d vertices "
                             "exceeds the buffer's limit", nv)
             : mcf_error_set(err, MCF_ENOMEM, "fields: out of memory for %d "
                             "vertices", nv);
done:
    free(text);
    cJSON_Delete(hdr);
    free(buf);
    return rc;
}
