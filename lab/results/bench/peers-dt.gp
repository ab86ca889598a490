# SPDX-License-Identifier: MIT
# bench_peers: per-step time against dt at equal work; run in this folder: gnuplot peers-dt.gp
set datafile separator ','
set logscale xy
set key outside right top box
set grid
set xlabel 'dt (unit-area mesh)'
set ylabel 'time per implicit step (ms, one thread)'
set format x '10^{%T}'
set title "Per-step time at equal work (same mesh, dt, 10 iterations)\nCGAL smooth\\_shape (BiCGSTAB + ILUT) vs mcfd desbrun2 (CHOLMOD) vs Eigen SimplicialLDLT"
set xrange [5e-07:0.002]
sel(m, c) = (strcol(1) eq m ? column(c) : 1/0)
set label "CGAL failed at call 5\n(armadillo)" at 0.001,1150.71 right offset -1,0 font ',11' noenhanced
do for [t in 'pngcairo svg'] {
  if (t eq 'svg') { set terminal svg size 1200,700 dynamic enhanced font 'DejaVu Sans,13' background rgb 'white'; set output 'peers-dt.svg' }
  else { set terminal pngcairo size 1200,700 enhanced font 'DejaVu Sans,13' background rgb 'white'; set output 'peers-dt.png' }
  plot 'peers-work.csv' skip 1 using 3:(sel('armadillo', 6)) with linespoints lw 2 pt 7 dt 1 lc rgb '#c0392b' title 'CGAL, armadillo' noenhanced, \
       'peers-work.csv' skip 1 using 3:(sel('armadillo', 4)) with linespoints lw 2 pt 5 dt 1 lc rgb '#2471a3' title 'mcfd desbrun2, armadillo' noenhanced, \
       'peers-work.csv' skip 1 using 3:(sel('armadillo', 13)) with linespoints lw 2 pt 9 dt 1 lc rgb '#1e8449' title 'Eigen peer, armadillo' noenhanced, \
       'peers-work.csv' skip 1 using 3:(sel('dragon_vrip', 6)) with linespoints lw 2 pt 7 dt 2 lc rgb '#7b241c' title 'CGAL, dragon_vrip' noenhanced, \
       'peers-work.csv' skip 1 using 3:(sel('dragon_vrip', 4)) with linespoints lw 2 pt 5 dt 2 lc rgb '#154360' title 'mcfd desbrun2, dragon_vrip' noenhanced, \
       'peers-work.csv' skip 1 using 3:(sel('dragon_vrip', 13)) with linespoints lw 2 pt 9 dt 2 lc rgb '#0b5345' title 'Eigen peer, dragon_vrip' noenhanced
  unset output
}
