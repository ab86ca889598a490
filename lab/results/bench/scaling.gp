# SPDX-License-Identifier: MIT
# bench_peers: per-step time against vertex count (icospheres); run in this folder: gnuplot scaling.gp
set datafile separator ','
set logscale xy
set key top left box opaque
set grid
set xlabel 'vertices'
set ylabel 'time per step (ms, one thread)'
set format x '10^{%T}'
set title "mcfd per-step time on icospheres level 5..9 (one thread)\nfitted time ∝ n^{p}: euler p = 1.09, desbrun2 p = 1.26"
fe(x) = exp(-11.368616) * x**1.086716
fd(x) = exp(-9.013706) * x**1.260184
do for [t in 'pngcairo svg'] {
  if (t eq 'svg') { set terminal svg size 1000,650 dynamic enhanced font 'DejaVu Sans,13' background rgb 'white'; set output 'scaling.svg' }
  else { set terminal pngcairo size 1000,650 enhanced font 'DejaVu Sans,13' background rgb 'white'; set output 'scaling.png' }
  plot 'scaling.csv' skip 1 using 2:5 with points pt 7 ps 1.5 lc rgb '#c0392b' title 'desbrun2 (factorize + solve per step)', \
       fd(x) with lines lc rgb '#c0392b' dt 2 title sprintf('desbrun2 fit, p = %.2f', 1.2602), \
       'scaling.csv' skip 1 using 2:3 with points pt 5 ps 1.5 lc rgb '#2471a3' title 'euler (marginal step)', \
       fe(x) with lines lc rgb '#2471a3' dt 2 title sprintf('euler fit, p = %.2f', 1.0867)
  unset output
}
