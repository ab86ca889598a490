#!/bin/sh
# SPDX-License-Identifier: MIT
# interleaved A B A B A B: base (main c49c673) and new, CPU of the default request (bench_quality's cpu_s)
A="--meshes /work/shared/meshes --no-figure --seeds 1 --methods default"
for rep in 1 2 3; do
  for who in base new; do
    if [ $who = base ]; then B=/work/base-h4/build/lab/bench/bench_quality; else B=/work/wt-h4/build/lab/bench/bench_quality; fi
    OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 nice -n 10 $B $A --rho 0.1 --models clean --list sphere_cgal.obj,spot.obj,fertility.obj,bunny_npm_closed.obj,knot1.obj,stanford-bunny.obj,armadillo.obj,snowden.obj,bunny.drc,blade.obj,car.drc,couplingdown_sub2.obj --out /tmp/h4/cpu/$who-clean-$rep > /dev/null 2>&1
    OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 nice -n 10 $B $A --rho 0.1 --models corr --list blade.obj,spot.obj,fertility.obj,bunny_npm_closed.obj --out /tmp/h4/cpu/$who-corr-$rep > /dev/null 2>&1
    echo $who $rep $(date -u +%H:%M:%S) $(cat /proc/loadavg | cut -d' ' -f1)
  done
done
