#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""cmp.py RUNFILE A B: the printed lines of two builds case by case (CPU and timings left out) and their
outputs (o/BUILD/*.bin: byte-identical or the largest coordinate difference)."""
import re,sys,os,struct
f=sys.argv[1]; A=sys.argv[2]; B=sys.argv[3]
rows={}
for l in open(f):
    if not l.startswith('t'): continue
    b,rest=l.split(' ',1)
    rows.setdefault(rest.split(':')[0],{})[b]=rest
nd=0
for k,v in rows.items():
    if A in v and B in v:
        strip=lambda x: re.sub(r'cpu [0-9.]+|tfact [0-9.]+|tsolve [0-9.]+','',x).strip()
        a=strip(v[A]); b=strip(v[B])
        m,d,r=k.split(); fa='o/%s/%s-%s-%s.bin'%(A,m,d,r); fb='o/%s/%s-%s-%s.bin'%(B,m,d,r)
        if os.path.exists(fa) and os.path.exists(fb):
            xa=open(fa,'rb').read(); xb=open(fb,'rb').read()
            if xa==xb: bc='bytes same'
            else:
                n=len(xa)//8; pa=struct.unpack('%dd'%n,xa); pb=struct.unpack('%dd'%n,xb)
                bc='maxdiff %.3g'%max(abs(p-q) for p,q in zip(pa,pb))
        else: bc='?'
        feat=re.search(r'\| feature.*',v[B]); 
        print('%-36s %s %-14s %s'%(k,'same' if a==b else 'DIFF',bc, feat.group(0) if feat else ''))
        if a!=b:
            nd+=1; print('    ',A,a); print('    ',B,b)
print('cases',len(rows),'differing',nd)
