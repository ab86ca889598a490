#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""cad_table.py - the CAD parts' default / BNF oracle table (run from the repository's root)."""
import csv,sys,statistics
bnf={}
for r in csv.DictReader(open('lab/results/quality/issue31-before/quality.csv')):
    if r['method']=='bnf_best': bnf[(r['mesh'],r['model'],float(r['rho']))]=float(r['ratio'])
rows={}
for f in sys.argv[1:]:
    for r in csv.DictReader(open(f)):
        if r['method']=='default' and r['ok']=='1': rows[(r['mesh'],r['model'],float(r['rho']))]=(float(r['ratio']),r['flips0'],r['flips'])
allr=[]
print('| model | cases | median | worst | per case (car, blade, couplingdown_sub2 at 0.1/0.25/0.5) |\n|---|---|---|---|---|')
for mo in ('normal','iso','view','corr','out','quant'):
    v=[];cells=[]
    for me in ('car.drc','blade.obj','couplingdown_sub2.obj'):
        c=[]
        for rho in (0.1,0.25,0.5):
            k=(me,mo,rho)
            if k in bnf and k in rows: x=rows[k][0]/bnf[k]; v.append(x); c.append('%.3f'%x)
            else: c.append('-')
        cells.append(' '.join(c))
    allr+=v
    if v: print('| %s | %d | %.3f | %.3f | %s |'%(mo,len(v),statistics.median(v),max(v),', '.join(cells)))
print('| all | %d | %.3f | %.3f | |'%(len(allr),statistics.median(allr),max(allr)))
print('cases <= 1:',sum(1 for x in allr if x<=1.0))
