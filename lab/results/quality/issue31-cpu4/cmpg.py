# SPDX-License-Identifier: MIT
# cmpg.py FILE BUILD...: per case each build's error / input, flips, CPU and the stage's pick.
import sys,re,collections
f=sys.argv[1]; builds=sys.argv[2:]
rows=collections.OrderedDict()
for l in open(f):
    m=re.match(r'(\S+) (\S+) (\S+) (\S+): input \S+ default/input (\S+) flips (\d+) -> (\d+) cpu (\S+).*?(\| feature (.*))?$',l.strip())
    if not m: continue
    b,mesh,mod,rho,ei,fi,fo,cpu,_,feat=m.groups()
    rows.setdefault((mesh,mod,rho),{}).setdefault(b,[]).append((float(ei),int(fo),float(cpu),(feat or '').replace('sigma_r ','').replace(' noise','')))
for k,v in rows.items():
    base=v.get(builds[0])
    if not base: continue
    e0=base[0][0]
    s='%-22s %-6s %s'%k
    for b in builds:
        if b in v:
            e=v[b][0][0]; c=sorted(x[2] for x in v[b]); 
            s+=' | %s %.4f%s f%d cpu %.2f %s'%(b,e,('' if b==builds[0] else ' (%+.4f)'%(e-e0)),v[b][0][1],c[len(c)//2],v[b][0][3][:28])
    print(s)
