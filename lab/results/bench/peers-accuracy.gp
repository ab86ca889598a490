# SPDX-License-Identifier: MIT
# bench_peers: error against wall time (work-precision); run in this folder: gnuplot peers-accuracy.gp
set datafile separator ','
set logscale xy
set key outside right top box
set grid
set xlabel 'wall time of the run (s, one thread)'
set ylabel 'error at T (M-weighted RMS / sqrt(area))'
set format y '10^{%T}'
set title "Time to equal accuracy: n = 1, 2, 4, ... steps to a fixed T against a common fine reference\npoints: step counts; horizontal lines: the tolerances"
pos(m, c) = (strcol(1) eq m && column(c) > 0 ? column(c) : 1/0)
do for [t in 'pngcairo svg'] {
  if (t eq 'svg') { set terminal svg size 1200,700 dynamic enhanced font 'DejaVu Sans,13' background rgb 'white'; set output 'peers-accuracy.svg' }
  else { set terminal pngcairo size 1200,700 enhanced font 'DejaVu Sans,13' background rgb 'white'; set output 'peers-accuracy.png' }
  plot 'peers-accuracy.csv' skip 1 using (pos('spot', 6)):(pos('spot', 5)) with linespoints lw 2 pt 5 lc rgb '#2471a3' title 'mcfd desbrun2, spot' noenhanced, \
       'peers-accuracy.csv' skip 1 using (pos('spot', 8)):(pos('spot', 7)) with linespoints lw 2 pt 7 lc rgb '#c0392b' title 'CGAL, spot' noenhanced, \
       1e-05 with lines lw 2 lc rgb '#c0392b' dt 2 title 'tolerance, spot' noenhanced, \
       'peers-accuracy.csv' skip 1 using (pos('armadillo', 6)):(pos('armadillo', 5)) with linespoints lw 2 pt 5 lc rgb '#154360' title 'mcfd desbrun2, armadillo' noenhanced, \
       'peers-accuracy.csv' skip 1 using (pos('armadillo', 8)):(pos('armadillo', 7)) with linespoints lw 2 pt 7 lc rgb '#7b241c' title 'CGAL, armadillo' noenhanced, \
       0.0001 with lines lw 2 lc rgb '#7b241c' dt 2 title 'tolerance, armadillo' noenhanced
  unset output
}
