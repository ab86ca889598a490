/*
 * mcf_experiment.h - `mcf experiment STUDY`, the article's experiments
 * done properly (../shared/MATH.md): dt sweeps against a clean target,
 * stability limits, temporal order and the shrinking sphere, as CSV files
 * and gnuplot plots. Part of the mcf tool (cli/), a client of api and core.
 */
#ifndef MCF_EXPERIMENT_H
#define MCF_EXPERIMENT_H

/* The usage lines of `mcf experiment`, for the tool's --help. */
extern const char mcf_experiment_usage[];

/* Runs `mcf experiment ...`: argv[1] is "experiment", argv[2] the study.
 * Writes its CSV files (and plots when gnuplot is on the PATH) into the
 * --out folder, creating it. Returns the process exit status: 0, 2 for a
 * usage error, 1 for anything else, after one "mcf: ..." line on stderr.
 * A run of the flow that fails (instability, no convergence, a limit) is
 * a data point written with its status, not an error of the study. */
int mcf_experiment_main(int argc, char **argv);

#endif /* MCF_EXPERIMENT_H */
