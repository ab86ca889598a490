/*
 * admit.h - memory admission of jobs (admit.c says how).
 */
#ifndef ADMIT_H
#define ADMIT_H

#include "srv.h"

/* 1 and a 422 in p when one job's estimate exceeds --max-job-memory. */
int srv_admit_refuse(const srv_config *cfg, double estimate, srv_problem *p);
/* Reserves estimate bytes when they fit in --max-memory beside the
 * running jobs' (or no job holds any): 1; else 0 and nothing held. */
int srv_admit_try(const srv_config *cfg, double estimate);
/* Grows a reservation *held to estimate (no-op when not larger), waiting
 * for others to release when it does not fit. 0, or -1 when *cancel was
 * set while waiting (*held unchanged). */
int srv_admit_grow(const srv_config *cfg, double *held, double estimate,
                   const mcf_cancel_flag *cancel);
/* Gives a reservation back and wakes the waiting grows. */
void srv_admit_release(double held);
/* Bytes reserved by the running jobs now. */
double srv_admit_used(void);

#endif /* ADMIT_H */
