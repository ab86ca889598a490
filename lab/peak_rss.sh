#!/bin/sh
# SPDX-License-Identifier: MIT
# peak_rss.sh - the calibration of api/api_estimate.c: peak resident size of
# `mcf smooth` (decode, metrics, flow, encode: the daemon's job) per mesh and
# scheme, into lab/results/memory/peak_rss.csv. Run from anywhere after `make`, with
# the team's meshes beside the checkout (../shared/meshes) or MESHES=DIR.
# One run at a time (about 40 min on 2 shared cores; a run over 300 s is
# stopped and left without a figure).
cd "$(dirname "$0")/.." || exit 1
M=${MESHES:-../shared/meshes}
T=$(mktemp -d) || exit 1
OUT=lab/results/memory/peak_rss.csv
echo "mesh,bytes,scheme,extra,nv,nf,maxrss_kb,wall_s" > $OUT
for mesh in tests/data/meshes/test_nm.obj $M/sphere_cgal.obj $M/bunny.drc $M/knot1.obj $M/spot.obj \
            $M/fertility.obj $M/stanford-bunny.obj $M/armadillo.obj $M/dragon_vrip.drc $M/dragon_vrip_res2.obj; do
  for s in "desbrun2" "euler" "ros2" "richardson" "implicit" "cmcf" "taubin" "desbrun2 --strength auto" "desbrun2 --adaptive"; do
    set -- $s; sch=$1; shift; extra="$*"
    ext=${mesh##*.}
    rm -f $T/t $T/m.json
    OPENBLAS_NUM_THREADS=1 OMP_THREAD_LIMIT=1 timeout -s KILL 300 /usr/bin/time -f "%M %e" -o $T/t \
      build/mcf smooth $mesh $T/out.$ext --scheme $sch $extra --metrics $T/m.json --quiet >/dev/null 2>&1
    rss=; wall=; [ -s $T/m.json ] && read rss wall < $T/t
    nvnf=$(python3 -c "import json; i=json.load(open('$T/m.json'))['input']['info']; print(i['vertices'], i['faces'])" 2>/dev/null || echo "? ?")
    set -- $nvnf
    echo "$(basename $mesh),$(stat -c %s $mesh),$sch,$extra,$1,$2,$rss,$wall" >> $OUT
  done
done
rm -rf $T
