/* SPDX-License-Identifier: MIT */
/*
 * eigen_peer.h - the benchmark's peer: one mean curvature flow step done
 * the way libigl's tutorial and pmp-library do it, with Eigen.
 *
 * Plain C interface so bench_core.c (C11) can call it; the implementation
 * (eigen_peer.cpp) is C++17 and catches every exception at the boundary.
 * Same conventions as libmcf (core/mcf.h): X is nv x 3 row-major, F is
 * nf x 3 int32, the cotan stiffness L is PSD (L_ij = -1/2 (cot a + cot b)),
 * M is the barycentric lumped mass. No normalization: dt is in the units
 * of X (dt_physical = dt_normalized * area for a run of libmcf with
 * normalize on, since L is scale-free and M scales like area).
 */
#ifndef EIGEN_PEER_H
#define EIGEN_PEER_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Seconds spent in the parts of one peer step (steady clock). total is
 * the whole call including copies in and out. */
typedef struct {
    double assemble;   /* triplets, setFromTriplets, M + dt L */
    double factorize;  /* SimplicialLDLT::compute = analyzePattern + factorize */
    double solve;      /* M X, the 3-column solve (explicit: L X, M^-1) */
    double total;
} peer_times;

/* One `desbrun` (linearly implicit Euler) step: builds L and M from X by
 * Eigen triplets, then solves (M + dt L) Xout = M X with
 * Eigen::SimplicialLDLT (analyzePattern + factorize every call, as the
 * libigl tutorial does). Xout (3*nv doubles) may alias X. times may be
 * NULL. Returns 0 on success, -1 when the factorization or solve fails
 * or memory runs out (Xout then unchanged). */
int peer_desbrun_step(int nv, const double *X, int nf, const int32_t *F,
                      double dt, double *Xout, peer_times *times);

/* One explicit Euler step Xout = X - dt M^-1 L X, L built by triplets.
 * Same contract as peer_desbrun_step. */
int peer_euler_step(int nv, const double *X, int nf, const int32_t *F,
                    double dt, double *Xout, peer_times *times);

/* The Eigen version the peer was compiled with, e.g. "3.4.0". */
const char *peer_eigen_version(void);

#ifdef __cplusplus
}
#endif
#endif /* EIGEN_PEER_H */
