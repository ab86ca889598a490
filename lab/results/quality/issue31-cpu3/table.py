# SPDX-License-Identifier: MIT
# table.py RUN.txt BASE MAIN NEW: the markdown table of a cpu.sh run (CPU ratios against the first)
import re,sys
L=open(sys.argv[1]).read().splitlines()
B=sys.argv[2:]
rows={}; order=[]
for l in L:
    m=re.match(r'(\S+) (\S+) (\S+) ([\d.]+): input \S+ default/input (\S+) flips (\d+) -> (\d+) cpu (\S+) steps (\d+)(.*)',l)
    if not m: continue
    b,mesh,mod,rho,r,fi,fo,cpu,steps,rest=m.groups()
    f=re.search(r'\| feature (\S+) sigma_r (\S+) (\S+) z (\S+)',rest)
    k=(mesh,mod,rho)
    if k not in rows: order.append(k)
    rows.setdefault(k,{})[b]=dict(r=r,fi=fi,fo=fo,cpu=float(cpu),f=('%s z %s'%(f.group(1),f.group(4)) if f else ''))
print('| mesh | noise | rho | error / input: %s | flips in -> out: %s | CPU s: %s | main / 854694c | this / 854694c | this / main | feature stage (this) |'%(', '.join(B),', '.join(B),', '.join(B)))
print('|---|---|---|---|---|---|---:|---:|---:|---|')
for k in order:
    v=rows[k]
    if not all(b in v for b in B): continue
    a=[v[b] for b in B]
    print('| %s | %s | %s | %s | %s | %s | %.2f | %.2f | %.2f | %s |'%(k[0],k[1],k[2],', '.join(x['r'] for x in a),', '.join('%s->%s'%(x['fi'],x['fo']) for x in a),', '.join('%.3f'%x['cpu'] for x in a),a[1]['cpu']/a[0]['cpu'],a[2]['cpu']/a[0]['cpu'],a[2]['cpu']/a[1]['cpu'],a[2]['f']))
