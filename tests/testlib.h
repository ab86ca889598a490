/* SPDX-License-Identifier: MIT */
/*
 * testlib.h - helpers shared by every cmocka test binary of mcfd.
 *
 * Tests read real meshes (the small ones of tests/data/meshes, the large
 * scans of $MCF_MESHES when `make test` is given MESHES), decode them with
 * the api layer and compare numbers with an explicit tolerance. Every helper that
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
#include <sys/types.h>

#include <cmocka.h>

#include "../core/mcf.h"
#include "../api/api.h"

/* ---- Test meshes. A test names a mesh by file name; it is looked up in
 * the repository first (tests/data/meshes/NAME, or $MCF_TESTDATA/meshes/NAME;
 * see tests/data/meshes/SOURCES.md), then in $MCF_MESHES, the folder of
 * large scans that `make test` passes from MESHES (unset in a fresh clone:
 * CI sets MESHES=../shared/meshes). A test that needs a mesh neither has
 * is skipped by name, never failed: tl_need_mesh prints the reason, appends
 * a line to $MCF_SKIP_LOG (which `make test` counts) and calls cmocka's
 * skip(). */

/* The large-mesh folder: $MCF_MESHES, or "" when unset. The string is
 * owned by the environment (or static); do not free it. Prefer
 * tl_mesh_path, which also finds the in-repository copies. */
const char *tl_meshes_dir(void);

/* The in-repository test data folder: $MCF_TESTDATA, else "tests/data"
 * (`make test` runs from the top of the tree). */
const char *tl_testdata_dir(void);

/* The path of mesh NAME (see above) in one of four rotating static
 * buffers, or NULL when neither folder has a readable file of that name. */
const char *tl_mesh_path(const char *name);

/* Skips the current test (cmocka's skip()) with a reason: prints it and
 * appends "tag<TAB>why" to $MCF_SKIP_LOG, whose lines `make test` counts
 * and whose tags it lists (tl_need_mesh's tag is the mesh's name). */
void tl_skip(const char *tag, const char *why);

/* Marks the current test a long study (seconds of CPU or more): under
 * `make check` ($MCF_QUICK set) it is skipped by name with WHAT it measures,
 * so that the quick loop stays under a minute; `make test` runs it. Call it
 * before the test has allocated anything. */
void tl_long(const char *what);

/* Seeded numbers for the tests' own noise: splitmix64 in [0, 1) from the
 * state *r (advanced), and a standard Gaussian from two of them
 * (Box-Muller). */
double tl_uniform01(uint64_t *r);
double tl_gauss01(uint64_t *r);

/* 1 when mesh NAME is one of the repository's own (tests/data/meshes). */
int tl_mesh_in_repo(const char *name);

/* tl_mesh_path, or, when the mesh is not available, skips the current
 * test with the reason (MESHES unset, or the file not in it). Call it
 * before the test has allocated anything: skip() leaves the test. */
const char *tl_need_mesh(const char *name);

/* Reads a whole file into a malloc'ed buffer, NUL-terminated (the NUL is
 * not counted in *len). Returns 0 on success, -1 on failure (errno set,
 * *buf and *len unchanged). The caller free()s *buf. */
int tl_read_file(const char *path, char **buf, size_t *len);

/* Reads mesh NAME (tl_need_mesh: skips the test when it is not
 * available) and decodes it with api_mesh_decode under the default limits.
 * Returns a new mesh (mcf_mesh_free it); on any other failure the current
 * cmocka test fails with the file name and error message. */
mcf_mesh *tl_load(const char *name);

/* Writes a noisy copy of test mesh NAME (tl_load) to out_path as OBJ
 * (every double exact): mcf_mesh_add_noise with rho (mean edges, along the
 * normals) and seed, on every vertex. What a test sends the service or
 * the tool to smooth, now that injecting noise is the lab's and not a
 * job parameter. Returns out_path; fails the current test on error. */
const char *tl_write_noisy(const char *name, double rho, uint64_t seed, const char *out_path);

/* Fails the current test unless |a - b| <= tol (and both are finite, or
 * equal infinities). `what` names the quantity in the failure message. */
void tl_assert_near(double a, double b, double tol, const char *what);

/* ---- Running the mcf tool (or the lab's mcflab) as a child process (test_cli,
 * lab/tests/test_experiment).
 * One scratch directory per test binary; the harness state is static in
 * testlib.c, set by tl_mcf_setup and removed by tl_mcf_teardown. */

/* What one run of mcf left: exit status, stdout and stderr. */
typedef struct {
    int status;               /* exit status, or -1 when killed */
    char *out, *err;          /* captured, NUL-terminated */
    size_t outlen, errlen;
} tl_run_result;

/* For a cmocka group setup: resolves $MCF_BUILD/mcf (default build/mcf)
 * and the test mesh sphere_cgal.obj to absolute paths (the children run
 * inside the scratch directory) and creates that directory with mkdtemp
 * from tmpl (at most 63 characters, ending in XXXXXX). On failure prints
 * "who: no PATH (...)" to stderr and returns -1; else 0. */
int tl_mcf_setup(const char *who, const char *tmpl);
/* The same for another program of the build: prog is its path under
 * $MCF_BUILD ("lab/mcflab"); tl_run then runs it, and tl_expect_error
 * wants its name ("mcflab: ...") at the start of the line. */
int tl_prog_setup(const char *who, const char *tmpl, const char *prog);

/* For a cmocka group teardown: removes the scratch directory and all in
 * it. Returns 0, or -1 when that failed. */
int tl_mcf_teardown(void);

/* The scratch directory (absolute) and the absolute path of
 * sphere_cgal.obj; valid after tl_mcf_setup. */
const char *tl_scratch(void);
const char *tl_sphere(void);

/* The absolute path of the program tl_run runs (valid after
 * tl_mcf_setup or tl_prog_setup): for a test that runs it its own way. */
const char *tl_prog(void);

/* scratch/name in one of four rotating static buffers: up to four results
 * may be in use at once. */
const char *tl_in_scratch(const char *name);

/* Runs mcf with the NULL-terminated arguments (at most 62) inside the
 * scratch directory, stdout and stderr captured into scratch/stdout and
 * scratch/stderr; path_env, when not NULL, replaces PATH in the child.
 * Fails the current test when mcf cannot be run. tl_run_free the result. */
tl_run_result tl_run_env(const char *path_env, const char *a0, ...);
#define tl_run(...) tl_run_env(NULL, __VA_ARGS__)

/* Frees what a run captured. */
void tl_run_free(tl_run_result *r);

/* An error run: fails the current test unless the status is code and
 * stderr is exactly one line "mcf: ..." (the program's name) containing
 * want. Frees r. */
void tl_expect_error(tl_run_result *r, int code, const char *want);

/* Fails the current test unless b has a's vertex and face counts and
 * bit-identical positions and faces (a lossless round trip). */
void tl_assert_same_mesh(const mcf_mesh *a, const mcf_mesh *b);

/* A codec's decode function (api_obj_decode, api_ply_decode, ...). */
typedef mcf_status (*tl_decoder)(const void *buf, size_t len, const api_limits *lim,
                                 mcf_mesh **out, mcf_error *err);

/* Decodes len bytes of buf with fn from an exact-size heap copy (a read
 * past the end shows under AddressSanitizer; no NUL follows the data),
 * *m and err reset first. */
mcf_status tl_decode_copy(tl_decoder fn, const void *buf, size_t len,
                          const api_limits *lim, mcf_mesh **m, mcf_error *err);

/* ---- Child processes that must not outlive the test binary (the
 * daemons of test_server), whatever fails: each runs in its own process
 * group, and every group still alive is SIGKILLed by tl_kill_children
 * (call it from a test's teardown), at exit, and on SIGINT, SIGTERM,
 * SIGHUP, SIGQUIT and SIGABRT (then the signal is re-raised). */

/* In the child, between fork and exec: a process group of its own. */
void tl_child_own_group(void);

/* In the parent, right after fork: records the child (and sets its group
 * too, so no signal can race the child's own call). The first call
 * installs the atexit and signal handlers. At most 64 children at once;
 * a reaped one stops counting by itself. */
void tl_track_child(pid_t pid);

/* SIGKILLs the process group of every tracked child that is still running
 * (not reaped, other than keep; pass 0 to keep none) and reaps it. Returns
 * how many it killed. */
int tl_kill_children(pid_t keep);

/* ---- Polygons (issue 20): a 7 x 7 grid of bumpy vertices and its 6 x 6
 * quads, in OBJ-like order (counter-clockwise seen from +z): fills
 * X[147] and Q[144] (0-based indices). */
void tl_quad_grid(double X[147], int Q[144]);

/* Smooths m a little (2 implicit steps): every vertex moves, the
 * connectivity stays. Fails the test when the flow fails. */
void tl_smooth_a_little(mcf_mesh *m);

/* ---- Folds: the faces of X (nf faces F over nv vertices) folded
 * against X0, written out as docs/fairing.md defines them (what
 * mcf_flow_stats.folded_faces counts): turned by more than 90 degrees
 * against X0's same face and lying backwards in their neighbourhood of X
 * (the normal against the sum of the three vertices' summed face
 * normals, or within rounding of perpendicular to it: 1e-10 of the face
 * normal's length times the squared edges of the faces summed); faces
 * degenerate in X or X0 (a normal below 1e-10 of the squared edges) are
 * not judged. mask (nf, may be NULL) gets 1 on each.
 * Returns the count. */
int tl_folds_against(const double *X, const double *X0, const int32_t *F, int nf, int nv,
                     unsigned char *mask);

/* ---- Flips against the clean mesh (make quality's, lab/bench/
 * quality_geom.c's qg_flips): the faces of x whose normal ((b - a) x
 * (c - a)) points against the same face's of clean (dot < 0; a face
 * without area in either is not counted). x and clean share their faces. */
int tl_flips_against(const mcf_mesh *x, const mcf_mesh *clean);

/* ---- A third-party reader: Debian's assimp (assimp-utils, installed by
 * make deps) runs `assimp info` on the bytes, written to $TMPDIR/name (the
 * extension tells assimp the format). Fails the current test unless it
 * loads them and, when nv or nf is not 0, counts that many vertices and
 * faces (assimp's counts: Draco points, line segments as faces). */
void tl_assimp_reads(const void *bytes, size_t len, const char *name, int nv, int nf);

#endif /* TESTLIB_H */
