/*
 * testlib.h - helpers shared by every cmocka test binary of mcfd.
 *
 * Tests read the real meshes of ../shared/meshes through the MCF_MESHES
 * environment variable that `make test` sets, decode them with the api
 * layer and compare numbers with an explicit tolerance. Every helper that
 * can fail ends the current cmocka test with a message (fail_msg), so a
 * caller never has to check a return value it cannot act on.
 *
 * Include after <cmocka.h> or on its own: it pulls in what cmocka needs.
 */
#ifndef TESTLIB_H
#define TESTLIB_H

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "../core/mcf.h"

/* The folder holding the test meshes: $MCF_MESHES, else "../shared/meshes".
 * The string is owned by the environment (or static); do not free it. */
const char *tl_meshes_dir(void);

/* Reads a whole file into a malloc'ed buffer, NUL-terminated (the NUL is
 * not counted in *len). Returns 0 on success, -1 on failure (errno set,
 * *buf and *len unchanged). The caller free()s *buf. */
int tl_read_file(const char *path, char **buf, size_t *len);

/* Reads $MCF_MESHES/name and decodes it with api_mesh_decode under the
 * default limits. Returns a new mesh (mcf_mesh_free it); on any failure
 * the current cmocka test fails with the file name and error message. */
mcf_mesh *tl_load(const char *name);

/* Fails the current test unless |a - b| <= tol (and both are finite, or
 * equal infinities). `what` names the quantity in the failure message. */
void tl_assert_near(double a, double b, double tol, const char *what);

#endif /* TESTLIB_H */
