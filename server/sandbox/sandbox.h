/* SPDX-License-Identifier: MIT */
/*
 * sandbox.h - decoding untrusted meshes in a child process with CPU,
 * memory and wall-clock limits (sandbox.c says why and how).
 */
#ifndef SANDBOX_H
#define SANDBOX_H

#include "service.h"

/* argv[1] of the hidden decode mode: main() hands such a process to
 * sandbox_child before anything else. */
#define SANDBOX_ARG "--sandbox-decode"

/* The child: reads the bytes on stdin, decodes them under the limits of
 * its argv and writes the answer on stdout. Returns the exit status. */
int sandbox_child(int argc, char **argv);

typedef struct {
    double cpu_s;              /* RLIMIT_CPU of the child */
    size_t mem_bytes;          /* address space beyond its start-up */
    double wall_s;             /* the parent kills it after this */
} sandbox_limits;

/* How a sandboxed decode ended, beyond its mcf_status. */
typedef enum {
    SANDBOX_OK = 0,        /* the child answered (decoded or refused) */
    SANDBOX_CPU,           /* stopped by its CPU limit */
    SANDBOX_MEMORY,        /* its allocations met the memory limit */
    SANDBOX_WALL,          /* killed at the wall-clock deadline */
    SANDBOX_CANCELED,      /* killed: the job's cancel flag was set */
    SANDBOX_PROTOCOL       /* died otherwise, or answered nonsense */
} sandbox_why;

/* The limits for an input the estimator sized: CPU cpu_floor + 1 us per
 * declared face, memory twice the estimated decode peak (at least
 * mem_floor), wall clock 10 x CPU + 5 s. */
void sandbox_limits_for(const api_mem_estimate *est, double cpu_floor,
                        size_t mem_floor, sandbox_limits *out);

/* Whether an input decodes in the sandbox: when decoding it runs libdraco
 * (a Draco stream, a glTF with KHR_draco_mesh_compression), the only
 * decoder that is not ours and not bounded by our own checks. */
int sandbox_wanted(const api_mem_estimate *est);

/* api_mesh_decode_attrs in a child process under sl (attrs may be NULL).
 * ELIMIT (detail names the limit: "needs more than 2 s of CPU") when a
 * limit stopped it; ECANCELED when *cancel became set; the decoder's own
 * status and message otherwise. Never leaves a child or a descriptor. */
mcf_status sandbox_decode(const void *buf, size_t len,
                          const api_limits *lim,
                          const sandbox_limits *sl,
                          const mcf_cancel_flag *cancel, mcf_mesh **out,
                          api_attrs **attrs, api_format *fmt,
                          sandbox_why *why, mcf_error *err);

/* The job runner's decode of an upload (api_job_hooks.decode): Draco in
 * the sandbox with limits from the input's declared counts and cfg
 * (decode_cpu, decode_memory), other formats in this thread. A sandbox
 * limit met sets *stage to API_JOB_RUN (the input's cost: REST 422, not
 * 413); ECANCELED when *cancel became set. */
mcf_status sandbox_decode_upload(const void *buf, size_t len,
                                 const svc_config *cfg,
                                 const mcf_cancel_flag *cancel, mcf_mesh **out,
                                 api_attrs **attrs, api_format *fmt,
                                 api_job_stage *stage, mcf_error *err);

#endif /* SANDBOX_H */
