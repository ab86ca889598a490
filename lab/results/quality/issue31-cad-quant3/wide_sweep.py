#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""wide_sweep.py - the flips repair (core/mcf_flips.c) redone in numpy on its own inputs, with the
grid rule of the input normal over k rings (union of the rings of the face corners) at several cosines:
error over the input and faces against the clean mesh per variant. Inputs: per case folder, the
repair's inputs dumped by flips_dump.diff (H5_DUMP=DIR/dump) and bench_quality's clean/noisy/default
raw meshes copied by a --render-script (copy_render.py). Usage: wide_sweep.py CASEDIR...
"""
import numpy as np, glob, os, sys
# bench_quality's raw meshes, read as lab/bench/render_quality.py reads them
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "bench"))
from render_quality import read_raw  # noqa: E402
def read_dump(path):
    b = open(path,'rb').read()
    nv, nf, grid = np.frombuffer(b[:12], dtype=np.int32)
    o = 12
    def arr(n, dt, o):
        a = np.frombuffer(b[o:o+n*np.dtype(dt).itemsize], dtype=dt); return a.copy(), o+n*np.dtype(dt).itemsize
    X, o = arr(3*nv, np.float64, o); Xin, o = arr(3*nv, np.float64, o); fld, o = arr(3*nv, np.float64, o); F, o = arr(3*nf, np.int32, o)
    return X.reshape(-1,3), Xin.reshape(-1,3), fld.reshape(-1,3), F.reshape(-1,3), grid
def fn(X, F):
    return np.cross(X[F[:,1]]-X[F[:,0]], X[F[:,2]]-X[F[:,0]])
def against(X, C, F):
    a = fn(X,F); c = fn(C,F)
    return np.nonzero((a*c).sum(1) < 0)[0]
import numpy as np
DEG=1e-10
def noarea(X,F):
    e1=X[F[:,1]]-X[F[:,0]]; e2=X[F[:,2]]-X[F[:,0]]; n=np.cross(e1,e2)
    s=DEG*((e1*e1).sum(1)+(e2*e2).sum(1)); return (n*n).sum(1)<=s*s, n
def repair(X, Xin, fld, F, grid, turn=None, extra=None, HALV=6, MAXR=64):
    X=X.copy(); nv=len(X)
    dg, nin = noarea(Xin,F)
    Nin=np.zeros_like(X)
    for k in range(3): np.add.at(Nin, F[:,k], nin)
    if turn is None: turn = 0.75 if grid else 0.5
    fsum = fld[F[:,0]]+fld[F[:,1]]+fld[F[:,2]]
    gsum = Nin[F[:,0]]+Nin[F[:,1]]+Nin[F[:,2]]
    judge_t = ~dg if grid else np.zeros(len(F),bool)
    rep=None
    for r in range(MAXR):
        _, n = noarea(X,F)
        atin = np.all(np.all(X[F]==Xin[F],axis=2),axis=1)
        nn=(n*n).sum(1); ff=(fsum*fsum).sum(1)
        inv = (nn>0) & (~((n*fsum).sum(1) >= turn*np.sqrt(nn*ff)) | ~((n*gsum).sum(1)>0))
        tov = ((nin*fsum).sum(1)>0) & ((n*fsum).sum(1)<0)
        bad = ~atin & ((dg & inv) | (judge_t & tov))
        if extra is not None: bad |= ~atin & extra(X, n, r)
        if r==0: rep=bad.sum()
        if not bad.any(): break
        mark=np.zeros(nv,bool); mark[F[bad].ravel()]=True
        idx=np.nonzero(mark)[0]
        if r<HALV: to=Xin[idx]+0.5*(X[idx]-Xin[idx])
        else: to=Xin[idx].copy()
        ch = np.any(X[idx]!=Xin[idx],1) & np.any(X[idx]!=to,1)
        X[idx[ch]]=to[ch]
        if not ch.any(): break
    return X, rep
import scipy.sparse as sp
def adj(F,nv):
    i=np.concatenate([F[:,0],F[:,1],F[:,2],F[:,1],F[:,2],F[:,0]]); j=np.concatenate([F[:,1],F[:,2],F[:,0],F[:,0],F[:,1],F[:,2]])
    A=sp.coo_matrix((np.ones(len(i)),(i,j)),shape=(nv,nv)).tocsr(); A.data[:]=1; return A
def ringsum(A, V, k):
    # sum of V over the k-ring (binary reach)
    nv=A.shape[0]; R=sp.identity(nv,format='csr')
    M=(A+sp.identity(nv)).tocsr(); M.data[:]=1
    for _ in range(k): R=(R@M).tocsr(); R.data[:]=1
    return R@V
def facestats(Xr, Xin, fld, F, Cl, ks=(1,2,3,4)):
    nv=len(Xin); dg,nin=noarea(Xin,F)
    Nin=np.zeros_like(Xin); [np.add.at(Nin,F[:,k],nin) for k in range(3)]
    A=adj(F,nv)
    n=fn(Xr,F); nn=np.linalg.norm(n,axis=1); u=n/np.maximum(nn,1e-300)[:,None]
    out={'kept': dg&(nn>0), 'dg':dg}
    cn=fn(Cl,F); out['clean']=(u*cn/np.linalg.norm(cn,axis=1)[:,None]).sum(1)
    for k in ks:
        R=ringsum(A,Nin,k) if k>0 else Nin
        g=R[F].sum(1); out['g%d'%k]=(u*g).sum(1)/np.maximum(np.linalg.norm(g,axis=1),1e-300)
    return out
import glob, os, sys
def load_case(d):
    C,F=read_raw(d+'/clean.bin'); N,_=read_raw(glob.glob(d+'/noisy*')[0]); D,_=read_raw(glob.glob(d+'/default*')[0])
    best=None
    for p in sorted(glob.glob(d+'/dump-*.bin')):
        X,Xin,fld,F2,g=read_dump(p)
        if len(X)!=len(C): continue
        s=np.linalg.lstsq(np.vstack([N[:,0],np.ones(len(N))]).T, Xin[:,0], rcond=None)[0][0]
        b=(Xin-s*N).mean(0)
        if np.abs(Xin-(s*N+b)).max()>1e-9*max(1,np.abs(Xin).max()): continue
        Xr,_=repair(X,Xin,fld,F,g)
        e=np.abs(Xr-(s*D+b)).max()
        if best is None or e<best[0]: best=(e,p,X,Xin,fld,g,s,b)
    e,p,X,Xin,fld,g,s,b=best
    Cl=s*C+b
    return dict(F=F,Cl=Cl,X=X,Xin=Xin,fld=fld,grid=g,match=e,dump=p,s=s)
def err(P,Cl,F):
    a=np.linalg.norm(fn(Cl,F),axis=1)/6; w=np.zeros(len(Cl)); [np.add.at(w,F[:,k],a) for k in range(3)]
    return np.sqrt((w*((P-Cl)**2).sum(1)).sum()/w.sum())
def run_variants(d, variants):
    c=load_case(d); F=c['F']; Cl=c['Cl']; Xin=c['Xin']; X=c['X']; fld=c['fld']; g=c['grid']
    nv=len(Xin); dg,nin=noarea(Xin,F)
    Nin=np.zeros_like(Xin); [np.add.at(Nin,F[:,k],nin) for k in range(3)]
    A=adj(F,nv)
    e0=err(Xin,Cl,F); fin=len(against(Xin,Cl,F))
    res={}
    for name,mk in variants.items():
        extra=mk(c,dg,Nin,A) if mk else None
        Xr,_=repair(X,Xin,fld,F,g,extra=extra)
        res[name]=(err(Xr,Cl,F)/e0, len(against(Xr,Cl,F)))
    return fin,res
def unionfield(k, thr):
    # the input's face normals summed (area-weighted, Nin) over the vertices within k rings of the face (each once)
    def mk(c,dg,Nin,A):
        if not c['grid']: return None
        F=c['F']; nv=len(Nin)
        M=(A+sp.identity(nv)).tocsr(); M.data[:]=1
        I=sp.coo_matrix((np.ones(3*len(F)),(np.repeat(np.arange(len(F)),3),F.ravel())),shape=(len(F),nv)).tocsr(); I.data[:]=1
        R=I
        for _ in range(k): R=(R@M).tocsr(); R.data[:]=1
        G=R@Nin; G/=np.maximum(np.linalg.norm(G,axis=1),1e-300)[:,None]
        def extra(X,n,r):
            nn=np.linalg.norm(n,axis=1)
            return dg & (nn>0) & ((n*G).sum(1) < thr*nn)
        return extra
    return mk
import sys, glob, os
V={'base':None}
for t in (0.4,0.45,0.5,0.55):
    V['u3>=%.2f'%t]=unionfield(3,t)
dirs=sys.argv[1:]
print('case', 'in', *V.keys())
for d in dirs:
    if not glob.glob(d+'/default*') or not glob.glob(d+'/dump-*'): continue
    try:
        fin,res=run_variants(d,V)
    except Exception as e:
        print(os.path.basename(d), 'ERR', e); continue
    b=res['base'][0]
    print(os.path.basename(d), fin, ' '.join('%.5f/%d'%(v[0],v[1]) if k=='base' else '%+.5f/%d'%(v[0]-b,v[1]) for k,v in res.items()), flush=True)
