# SPDX-License-Identifier: MIT
# bench_quality: clean / noisy / smoothed renders of stanford-bunny.obj, normal noise at noise 0.1 (seed 2)
# run in this folder: gnuplot worst-zoom.gp (needs the render-*.dat files bench_quality
# writes and removes; rerun bench_quality to regenerate)
set terminal pngcairo size 1260,952 font 'sans,11'
set output 'worst-zoom.png'
set multiplot layout 2,3 title 'stanford-bunny.obj, normal noise, noise 0.1 mean edges (seed 2): clean, noisy, smoothed (error / noisy error)' noenhanced
set view 0,0,1.4
set view equal xy
set size ratio -1
unset border
unset tics
unset key
unset colorbox
set xrange [-0.0479803:0.0142993]
set yrange [0.0947206:0.1564542]
set pm3d depthorder lighting primary 0.45 specular 0.15 spec2 0.25
set style fill solid noborder
set title 'clean' noenhanced
splot 'render-0.dat' using 1:2:3 with polygons fc rgb '#e0d4bc'
set title 'noisy' noenhanced
splot 'render-1.dat' using 1:2:3 with polygons fc rgb '#e0d4bc'
set title 'default (7): 0.57, surface 0.63' noenhanced
splot 'render-2.dat' using 1:2:3 with polygons fc rgb '#e0d4bc'
set title 'taubin best (12): 0.55, surface 0.59' noenhanced
splot 'render-3.dat' using 1:2:3 with polygons fc rgb '#e0d4bc'
set title 'open3d best (2): 0.71, surface 0.70' noenhanced
splot 'render-4.dat' using 1:2:3 with polygons fc rgb '#e0d4bc'
unset multiplot
