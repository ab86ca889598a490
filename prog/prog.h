/* SPDX-License-Identifier: MIT */
/*
 * prog.h - what the programs (cli/ mcf and server/ mcfd) do first in main,
 * before any work; kept out of the libraries, which never touch the
 * process's environment. lab/ and tests/ do not use it.
 */
#ifndef PROG_H
#define PROG_H

/* First thing in main: sets the BLAS thread counts to 1
 * (OPENBLAS_NUM_THREADS and its kin: one thread per job, the policy of
 * prog_threads.c), each unless the environment sets it; then, if it set
 * one, executes argv again once (/proc/self/exe, marked by MCF_REEXECED)
 * so that the BLAS, which reads them when it is loaded, sees them. Returns
 * (without effect) when the environment sets them all or that is
 * impossible; does not return after a successful exec. */
void prog_bound_blas_threads(char **argv);

#endif
