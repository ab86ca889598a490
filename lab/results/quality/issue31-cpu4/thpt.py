# SPDX-License-Identifier: MIT
# thpt.py thp.txt: CPU medians without and with glibc.malloc.hugetlb=1, base and main.
import re,sys,collections,statistics as st
d=collections.defaultdict(list)
for l in open(sys.argv[1]):
    m=re.match(r'(\S+) (\S+) (\S+) (\S+) (\S+): .*default/input (\S+) .*cpu (\S+)',l)
    if m: d[(m.group(3),m.group(4),m.group(5))].append((m.group(1),m.group(2),float(m.group(7)),m.group(6)))
for k,v in d.items():
    g=collections.defaultdict(list); e={}
    for b,t,c,ei in v: g[(b,t)].append(c); e[(b,t)]=ei
    med={kk:st.median(x) for kk,x in g.items()}
    s='%s %s %s n=%d |'%(k+(len(g[('tmain','none')]),))
    for kk in [('tbase','none'),('tbase','huge'),('tmain','none'),('tmain','huge')]:
        if kk in g: s+=' %s/%s %.3f [%.3f-%.3f] e%s |'%(kk+(med[kk],min(g[kk]),max(g[kk]),e[kk]))
    if ('tbase','none') in med and ('tmain','none') in med and ('tmain','huge') in med and ('tbase','huge') in med:
        s+=' main/base %.2f, huge main/base %.2f, main huge/none %.2f'%(med[('tmain','none')]/med[('tbase','none')],med[('tmain','huge')]/med[('tbase','huge')],med[('tmain','huge')]/med[('tmain','none')])
    print(s)
