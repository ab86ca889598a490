# SPDX-License-Identifier: MIT
# table.py RUN.txt NAME...: the markdown table of a cpu.sh run (first NAME the reference)
import sys,re
rows={}
order=[]
for line in open(sys.argv[1]):
    m=re.match(r'(\S+) (\S+) (\S+) (\S+): input (\S+) default/input (\S+) flips (\d+) -> (\d+) cpu (\S+) steps (\d+)(.*)',line)
    if not m: continue
    b,mesh,model,rho=m.group(1,2,3,4)
    k=(mesh,model,rho)
    if k not in rows: rows[k]={}; order.append(k)
    feat=''
    f=re.search(r'\| feature (\S+) sigma_r (\S+) (\S+) z (\S+)',m.group(11))
    if f: feat='%s z %s'%(f.group(1),f.group(4))
    rows[k][b]=dict(err=float(m.group(6)),fin=int(m.group(7)),fout=int(m.group(8)),cpu=float(m.group(9)),steps=int(m.group(10)),feat=feat)
names=sys.argv[2:]
print('| mesh | noise | rho | error / input: '+', '.join(names)+' | flips in -> out: '+', '.join(names)+' | CPU s: '+', '.join(names)+' | '+' | '.join('%s / %s'%(n,names[0]) for n in names[1:])+' | feature stage |')
print('|---|---|---|---|---|---|'+'---:|'*(len(names)-1)+'---|')
for k in order:
    r=rows[k]
    if not all(n in r for n in names): continue
    ratios=' | '.join('%.2f'%(r[n]['cpu']/r[names[0]]['cpu']) if r[names[0]]['cpu']>0 else '-' for n in names[1:])
    print('| %s | %s | %s | %s | %s | %s | %s | %s |'%(k[0],k[1],k[2],', '.join('%.4f'%r[n]['err'] for n in names),', '.join('%d->%d'%(r[n]['fin'],r[n]['fout']) for n in names),', '.join('%.3f'%r[n]['cpu'] for n in names),ratios,r[names[-1]]['feat']))
