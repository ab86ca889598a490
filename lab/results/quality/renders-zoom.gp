# SPDX-License-Identifier: MIT
# bench_quality: clean / noisy / smoothed renders of stanford-bunny.obj at noise 0.25 (seed 1)
# run in this folder: gnuplot renders-zoom.gp (needs the render-*.dat files bench_quality
# writes and removes; rerun bench_quality to regenerate)
set terminal pngcairo size 1260,952 font 'sans,11'
set output 'renders-zoom.png'
set multiplot layout 2,3 title 'stanford-bunny.obj, noise 0.25 mean edges (seed 1): clean, noisy, smoothed (error / noisy error)' noenhanced
set view 0,0,1.4
set view equal xy
set size ratio -1
unset border
unset tics
unset key
unset colorbox
set xrange [-0.09469:0.00184338]
set yrange [0.09163392:0.187321]
set pm3d depthorder lighting primary 0.45 specular 0.15 spec2 0.25
set style fill solid noborder
set title 'clean' noenhanced
splot 'render-0.dat' using 1:2:3 with polygons fc rgb '#e0d4bc'
set title 'noisy (0.25 mean edges)' noenhanced
splot 'render-1.dat' using 1:2:3 with polygons fc rgb '#e0d4bc'
set title 'default (t=0.11h^2): 0.68' noenhanced
splot 'render-2.dat' using 1:2:3 with polygons fc rgb '#e0d4bc'
set title 'oracle desbrun2 t=0.30h^2: 0.52' noenhanced
splot 'render-3.dat' using 1:2:3 with polygons fc rgb '#e0d4bc'
set title 'taubin 40 passes: 0.46' noenhanced
splot 'render-4.dat' using 1:2:3 with polygons fc rgb '#e0d4bc'
unset multiplot
