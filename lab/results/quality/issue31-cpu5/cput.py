#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""cput.py RUNFILE BASE MAIN NEW: CPU medians [ranges] per case, per-rep ratios (same rep, interleaved)."""
import re,sys,statistics as S
f,B,M,N=sys.argv[1:5]
cpu={}; order=[]; info={}
for l in open(f):
    if not l.startswith('t') or ' cpu ' not in l: continue
    b,rest=l.split(' ',1); k=rest.split(':')[0]
    if k not in order: order.append(k)
    cpu.setdefault(k,{}).setdefault(b,[]).append(float(re.search(r'cpu ([0-9.]+)',rest).group(1)))
    e=re.search(r'default/input ([0-9.]+)',rest).group(1); fe=re.search(r'\| feature (\w+)',rest)
    info.setdefault(k,{})[b]=(e, fe.group(1) if fe else '-')
def md(x): return '%.3f [%.3f-%.3f]'%(S.median(x),min(x),max(x))
def rt(a,b): r=[x/y for x,y in zip(a,b)]; return '%.2f [%.2f-%.2f]'%(S.median(r),min(r),max(r))
print('| case | error / input (854694c, main, this) | stage | CPU s 854694c | main | this | main / 854694c | this / 854694c | this / main |')
print('|---|---|---|---|---|---|---|---|---|')
for k in order:
    c=cpu[k]
    if not all(x in c for x in (B,M,N)): continue
    print('| %s | %s, %s, %s | %s | %s | %s | %s | %s | %s | %s |'%(k,info[k][B][0],info[k][M][0],info[k][N][0],info[k][N][1],md(c[B]),md(c[M]),md(c[N]),rt(c[M],c[B]),rt(c[N],c[B]),rt(c[N],c[M])))
