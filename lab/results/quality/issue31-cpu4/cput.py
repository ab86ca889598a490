# SPDX-License-Identifier: MIT
# cput.py FILE BASE MAIN NEW: the CPU table, medians and ranges of fresh-process runs.
import re,sys,collections,statistics as st
d=collections.OrderedDict()
for l in open(sys.argv[1]):
    m=re.match(r'(\S+) (\S+) (\S+) (\S+): .*default/input (\S+) flips (\d+) -> (\d+) cpu (\S+)(.*feature (\S+))?',l)
    if m:
        k=(m.group(2),m.group(3),m.group(4)); d.setdefault(k,collections.defaultdict(list))[m.group(1)].append((float(m.group(8)),m.group(5),m.group(7),m.group(10) or ''))
B=sys.argv[2:]
print('| mesh | noise | rho | error / input: '+', '.join(B)+' | CPU s median [range]: '+', '.join(B)+' | '+B[1]+' / '+B[0]+' | '+B[2]+' / '+B[0]+' | '+B[2]+' / '+B[1]+' | stage |')
print('|'+'---|'*3+'---|---|---:|---:|---:|---|')
for k,v in d.items():
    med={b:st.median([x[0] for x in v[b]]) for b in B if b in v}
    if len(med)<3: continue
    e=', '.join(v[b][0][1] for b in B)
    c=', '.join('%.3f [%.3f-%.3f]'%(med[b],min(x[0] for x in v[b]),max(x[0] for x in v[b])) for b in B)
    print('| %s | %s | %s | %s | %s | %.2f | %.2f | %.2f | %s (n=%d) |'%(k+(e,c,med[B[1]]/med[B[0]],med[B[2]]/med[B[0]],med[B[2]]/med[B[1]],v[B[2]][0][3],len(v[B[2]]))))
