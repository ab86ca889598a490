/* SPDX-License-Identifier: MIT */
/*
 * prog.h - what the programs (cli/ mcf and server/ mcfd) do first in main
 * (the BLAS's threads, the heap's pages),
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

/* First thing in main, before prog_bound_blas_threads (prog_heap.c): the
 * heap on transparent huge pages (GLIBC_TUNABLES gains
 * glibc.malloc.hugetlb=1 unless it names that tunable already). Returns 1
 * when it set it: glibc reads its tunables when the process starts, so
 * main then calls prog_reexec after prog_bound_blas_threads (which does
 * not return when it executed the program itself). 0: nothing to do
 * (set already, or not glibc). */
int prog_heap_huge_pages(void);
/* Executes the program again with argv (/proc/self/exe); returns only
 * when that is impossible. */
void prog_reexec(char **argv);

#endif
