#!/bin/sh
# SPDX-License-Identifier: MIT
A="--meshes /work/shared/meshes --no-figure --seeds 1 --methods default"
for m in blade.obj car.drc couplingdown_sub2.obj sphere_cgal.obj spot.obj fertility.obj bunny_npm_closed.obj knot1.obj stanford-bunny.obj bunny.drc armadillo.obj snowden.obj dragon_vrip_res2.obj; do
  for who in base new; do
    if [ $who = base ]; then B=/work/base-h4/build/lab/bench/bench_quality; else B=/work/wt-h4/build/lab/bench/bench_quality; fi
    OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 nice -n 10 $B $A --rho 0.1,0.25,0.5 --list $m --models normal,iso,view,corr,out,quant --out /tmp/h4/mx/$who-$m > /tmp/h4/mx/$who-$m.log 2>&1
    OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 nice -n 10 $B $A --rho 0.1 --list $m --models clean --out /tmp/h4/mx/$who-clean-$m >> /tmp/h4/mx/$who-$m.log 2>&1
  done
  echo done $m $(date -u +%H:%M:%S)
done
