# SPDX-License-Identifier: MIT
# cmp.py RUN.txt A B: per case, are error / input, flips and the stage pick of builds A and B the same
import re,sys
L=open(sys.argv[1]).read().splitlines()
A,B=sys.argv[2],sys.argv[3]
rows={}
for l in L:
    m=re.match(r'(\S+) (\S+) (\S+) ([\d.]+): input \S+ default/input (\S+) flips (\d+) -> (\d+) cpu (\S+)(.*)',l)
    if not m: continue
    b,mesh,mod,rho,r,fi,fo,cpu,rest=m.groups()
    f=re.search(r'\| feature (\S+) sigma_r (\S+) (\S+) z (\S+)',rest)
    rows.setdefault((mesh,mod,rho),{})[b]=(r,fi,fo,cpu,f.groups() if f else None)
nd=0
for k,v in rows.items():
    if A in v and B in v:
        a,b=v[A],v[B]
        same = a[0]==b[0] and a[2]==b[2] and a[4]==b[4]
        nd+= not same
        print(*k, 'SAME' if same else 'DIFF', 'err',a[0],b[0],'flips',a[1],'->',a[2],b[2],'cpu',a[3],b[3],'%.2f'%(float(b[3])/float(a[3])),a[4], '' if same else b[4])
print('cases',len([1 for v in rows.values() if A in v and B in v]),'differing',nd)
