# SPDX-License-Identifier: MIT
# ab.py ab_run3.txt tmain tnew2: per case the two builds' CPU medians and the per-pair ratio.
import re,sys,collections,statistics as st
d=collections.OrderedDict()
for l in open(sys.argv[1]):
    m=re.match(r'(\S+) (\S+) (\S+) (\S+): .*default/input (\S+) flips (\d+) -> (\d+) cpu (\S+)',l)
    if m: d.setdefault((m.group(2),m.group(3),m.group(4)),collections.defaultdict(list))[m.group(1)].append(float(m.group(8)))
a,b=sys.argv[2],sys.argv[3]
for k,v in d.items():
    ra=[y/x for x,y in zip(v[a],v[b])]
    print('%s %s %s: %s %.3f [%.3f-%.3f], %s %.3f [%.3f-%.3f], %s/%s per pair median %.2f [%.2f-%.2f] n=%d'%(k+(a,st.median(v[a]),min(v[a]),max(v[a]),b,st.median(v[b]),min(v[b]),max(v[b]),b,a,st.median(ra),min(ra),max(ra),len(ra))))
