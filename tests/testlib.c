/*
 * testlib.c - the helpers of testlib.h: locating the shared meshes,
 * reading files, decoding a mesh or failing the test, and tolerance checks.
 *
 * Plain stdio on purpose: tests may run from any directory, and a missing
 * mesh folder must fail loudly with the path it tried, not crash.
 */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"
#include "../api/api.h"

const char *tl_meshes_dir(void)
{
    const char *d = getenv("MCF_MESHES");
    return (d && *d) ? d : "../shared/meshes";
}

int tl_read_file(const char *path, char **buf, size_t *len)
{
    FILE *f = fopen(path, "rb");
    char *data = NULL;
    size_t n = 0, cap = 0;
    int rc = -1;

    if (!f)
        return -1;
    for (;;) {
        size_t got;
        if (cap - n < 65536) {
            size_t ncap = cap ? cap * 2 : 131072;
            char *p = realloc(data, ncap + 1);
            if (!p) {
                errno = ENOMEM;
                goto done;
            }
            data = p;
            cap = ncap;
        }
        got = fread(data + n, 1, cap - n, f);
        n += got;
        if (got == 0) {
            if (ferror(f))
                goto done;
            break;
        }
    }
    data[n] = '\0';
    *buf = data;
    *len = n;
    data = NULL;
    rc = 0;
done:
    free(data);
    fclose(f);
    return rc;
}

mcf_mesh *tl_load(const char *name)
{
    char path[4096];
    char *buf = NULL;
    size_t len = 0;
    api_limits lim;
    mcf_error err = {MCF_OK, ""};
    mcf_mesh *m = NULL;
    mcf_status rc;

    snprintf(path, sizeof path, "%s/%s", tl_meshes_dir(), name);
    if (tl_read_file(path, &buf, &len) != 0)
        fail_msg("tl_load: cannot read %s: %s", path, strerror(errno));
    api_limits_default(&lim);
    rc = api_mesh_decode(buf, len, &lim, &m, NULL, &err);
    free(buf);
    if (rc != MCF_OK || !m)
        fail_msg("tl_load: %s: %s: %s", path, mcf_status_name(rc), err.msg);
    return m;
}

void tl_assert_near(double a, double b, double tol, const char *what)
{
    if (a == b) /* also equal infinities */
        return;
    if (!isfinite(a) || !isfinite(b) || !(fabs(a - b) <= tol))
        fail_msg("%s: %.17g vs %.17g differ by %.3g (tolerance %.3g)",
                 what ? what : "value", a, b, fabs(a - b), tol);
}
