# SPDX-License-Identifier: MIT
# ana.py: sure18.txt as tables, SURE / s^2 of every candidate and where the noise reading's least and most lie.
import re,sys,math
cases=[];cur=None
for l in open('sure18.txt'):
    if l.startswith('CASE'):
        cur={'name':l.split(None,1)[1].strip(),'c':{},'res':''}; cases.append(cur)
    elif l.startswith('H6 pick'):
        t=l.split(); cur['pick']=int(t[2]); cur['sf']=float(t[4])
    elif l.startswith('H6 '):
        t=l.split(); cur['c'][int(t[1])]=(float(t[2]),int(t[3]),int(t[4]),float(t[6]),float(t[8]))
    elif ': input' in l and cur: cur['res']=l.strip()
for c in cases:
    if 'pick' not in c: print(c['name'],'no stage'); continue
    C=c['c']; p=c['pick']
    # narrow kernel table: rows ni, cols vi
    print(c['name'], 'pick', C[p][:3], 'sf %.4g'%c['sf'], c['res'].split('|')[-1] if '|' in c['res'] else '')
    for si in (0,1):
        rows=[]
        for ni in range(3):
            rows.append(' '.join('%8.4f'%(C[si*9+ni*3+vi][3]/c['sf']**2) for vi in range(3)))
        print('   s%d SURE'%si, ' | '.join(rows))
    vs=[C[9+j][4] for j in range(9)]
    lo=min(vs);hi=max(vs)
    print('   wide v: lo at',vs.index(lo),'hi at',vs.index(hi))
