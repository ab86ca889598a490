#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""cmp.py - the default rows of two bench_quality CSV files side by side (error over the input, faces against the clean mesh, CPU)."""
import csv,sys
def load(p):
    d={}
    for r in csv.DictReader(open(p)):
        if r['method']=='default': d[(r['mesh'],r['model'],float(r['rho']))]=(float(r['ratio']),int(r['flips0']),int(r['flips']),float(r['cpu_s']))
    return d
b=load(sys.argv[1]); a=load(sys.argv[2])
print('| mesh | model | rho | error/input before -> after | faces against clean: input: before -> after | cpu s before, after |\n|---|---|---|---|---|---|')
for k in sorted(a):
    if k in b: print('| %s | %s | %.2f | %.4f -> %.4f | %d: %d -> %d | %.2f, %.2f |'%(k[0],k[1],k[2],b[k][0],a[k][0],a[k][1],b[k][2],a[k][2],b[k][3],a[k][3]))
