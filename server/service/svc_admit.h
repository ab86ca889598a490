/* SPDX-License-Identifier: MIT */
/*
 * svc_admit.h - memory admission of the job service's jobs (svc_admit.c
 * says how).
 */
#ifndef SVC_ADMIT_H
#define SVC_ADMIT_H

#include "service.h"

/* The estimate admission works with, from the input's bytes before they
 * are decoded: the job's (api_estimate_memory) and, with a target, its
 * copy of the input and a second mesh of the same counts; and the
 * memory of the steps (their log and progress events) the parameters
 * plan, at most lim's max_iterations. */
double svc_admit_estimate(const void *input, size_t input_len,
                          size_t target_len, const api_params *p,
                          const api_limits *lim);
/* The same from a decoded mesh's counts (polygons split, STL welded). */
double svc_admit_estimate_counts(int nv, int nf, size_t input_len,
                                 size_t target_len, const api_params *p,
                                 const api_limits *lim);
/* 1 and an ELIMIT error (REST 422) in e when one job's estimate exceeds
 * --max-job-memory; else 0. */
int svc_admit_refuse(const svc_config *cfg, double estimate, svc_error *e);
/* The service's budget (svc_internal.h), made empty; and destroyed. */
void svc_admit_init(svc_t *s);
void svc_admit_destroy(svc_t *s);
/* Reserves estimate bytes when they fit in --max-memory beside the
 * running jobs' (or no job holds any): 1; else 0 and nothing held. */
int svc_admit_try(svc_t *s, double estimate);
/* Grows a reservation *held to estimate (no-op when not larger), waiting
 * for others to release when it does not fit. 0, or -1 when *cancel was
 * set while waiting (*held unchanged). */
int svc_admit_grow(svc_t *s, double *held, double estimate,
                   const mcf_cancel_flag *cancel);
/* Grows an upload's reservation *held (0: a new one) by more bytes when
 * they fit in --max-memory beside the others' (or it is alone): 1; else
 * 0 and *held unchanged. Uploads and jobs are the holders of one budget. */
int svc_admit_more(svc_t *s, double *held, double more);
/* Gives a reservation back and wakes the waiting grows. */
void svc_admit_release(svc_t *s, double held);
/* The cores of running job j, of nv vertices, for its flow's threads:
 * from MCF_THREADS_MIN vertices on, every core no other running job
 * holds, added to the one its worker claimed (workers.c says the rule;
 * under the service's mutex, s->cores_held). Called by the runner once
 * the job is decoded; workers.c gives them back at its end. */
int svc_admit_cores(svc_job *j, int nv);

#endif /* SVC_ADMIT_H */
