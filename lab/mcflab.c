/* SPDX-License-Identifier: MIT */
/*
 * mcflab.c - the lab's program: studies of the flow on meshes (study.h),
 * as CSV files and gnuplot figures. Built by lab/Makefile, never by the
 * product's `make`, never shipped.
 *
 *   mcflab dt-sweep|stability|order|sphere --out DIR [options]
 */
#include <stdio.h>
#include <string.h>

#include "study.h"

static const char usage[] =
    "usage:\n"
    "%s"
    "  mcflab --help\n"
    "Studies of mcfd's flows for the lab (lab/README.md): CSV files and figures in DIR.\n";

int main(int argc, char **argv)
{
    xopts o;
    int rc;

    lab_prog = "mcflab";
    if (argc < 2)
        return lab_fail(LAB_EXIT_USAGE, "missing study: dt-sweep, stability, order or sphere (try mcflab --help)");
    for (int i = 1; i < argc; i++)
        if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h") || !strcmp(argv[i], "help")) {
            printf(usage, study_usage);
            return fflush(stdout) == 0 ? 0 : 1;
        }
    if (!strcmp(argv[1], "adaptive"))
        return study_adaptive(argc, argv);
    if ((rc = study_parse(argc, argv, &o)) != 0)
        return rc;
    if ((rc = lab_mkdir_p(o.out)) != 0)
        return rc;
    switch (o.study) {
    case ST_DTSWEEP:
        return study_dt_sweep(&o);
    case ST_STABILITY:
        return study_stability(&o);
    case ST_ORDER:
        return study_order(&o);
    case ST_SPHERE:
        return study_sphere(&o);
    }
    return 1;
}
