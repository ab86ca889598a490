#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""copy_render.py - a bench_quality --render-script that copies the raw meshes it is given (clean, noisy, default, ...) into $H5_COPY instead of rendering them."""
import sys, shutil, os
args = sys.argv[1:]
out = args[args.index('--out')+1]
d = os.environ.get('H5_COPY', '/tmp/h5/r')
os.makedirs(d, exist_ok=True)
for a in args:
    if '=' in a and a.endswith(('clean','input','default')) or ('render-' in a):
        p, lab = a.split('=', 1)
        shutil.copy(p, os.path.join(d, lab.replace(' ', '_').replace('/', '_') + '.bin'))
print(args)
