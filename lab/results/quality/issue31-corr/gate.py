# SPDX-License-Identifier: MIT
"""gate.py MESH [MODELS] - the plated share of docs/fairing.md ("Correlated noise on plated parts") on a shared mesh (OBJ; .drc converted with `mcf convert`) clean and under issue 31's noise models drawn here in numpy (normal, corr, iso, view, out at 0.1/0.25/0.5 h, seed 1; not bench_quality's draws): A9_t8 is the share of the free vertices in regions within 8 degrees of their seed on the normals of 9 graph averages, each >= 2% of the free vertices; coarse the first-order reading in mean edges along the normals of 10 Taubin passes (uncalibrated; the product reads along those of the 9 averages). The study that chose the gate; all.txt its output (2026-11-29)."""
import numpy as np, scipy.sparse as sp, sys, os
def load_obj(p):
    V=[];F=[]
    for l in open(p):
        if l.startswith('v '): V.append([float(x) for x in l.split()[1:4]])
        elif l.startswith('f '):
            idx=[int(x.split('/')[0])-1 for x in l.split()[1:]]
            for k in range(1,len(idx)-1): F.append([idx[0],idx[k],idx[k+1]])
    return np.array(V),np.array(F,dtype=np.int64)
def setup(X,F):
    nv=len(X)
    i=np.r_[F[:,0],F[:,1],F[:,2],F[:,1],F[:,2],F[:,0]]; j=np.r_[F[:,1],F[:,2],F[:,0],F[:,0],F[:,1],F[:,2]]
    A=sp.coo_matrix((np.ones(len(i)),(i,j)),shape=(nv,nv)).tocsr(); A.data[:]=1
    deg=np.asarray(A.sum(1)).ravel()
    e=np.sort(np.c_[i,j],axis=1); e=np.unique(e,axis=0)
    # boundary: edge used by one face
    fe=np.sort(np.r_[F[:,[0,1]],F[:,[1,2]],F[:,[2,0]]],axis=1)
    u,c=np.unique(fe,axis=0,return_counts=True)
    fixed=np.zeros(nv,bool); fixed[u[c==1].ravel()]=True; fixed[deg==0]=True
    h=np.mean(np.linalg.norm(X[e[:,0]]-X[e[:,1]],axis=1))
    return A,deg,fixed,h
def vnormals(X,F):
    n=np.cross(X[F[:,1]]-X[F[:,0]],X[F[:,2]]-X[F[:,0]]); N=np.zeros_like(X)
    for k in range(3): np.add.at(N,F[:,k],n)
    return N/np.maximum(np.linalg.norm(N,axis=1),1e-300)[:,None]
def avg(A,deg,Y):
    d=np.where(deg>0,deg,1); return (A@Y)/d[:,None] if Y.ndim==2 else (A@Y)/d
def taubin(A,deg,fixed,X,passes=10):
    P=X.copy()
    for _ in range(passes):
        for lam in (0.5,-0.53):
            Q=P+lam*(avg(A,deg,P)-P); Q[fixed]=P[fixed]; P=Q
    return P
def noisy(X,F,A,deg,fixed,h,model,rho,seed=1):
    rng=np.random.default_rng(seed*1000+('normal','iso','view','corr','out').index(model)); n=vnormals(X,F); s=rho*h; nv=len(X); mv=~fixed
    Y=X.copy()
    if model=='normal': Y[mv]+=s*rng.standard_normal(nv)[mv,None]*n[mv]
    elif model=='iso': Y[mv]+=s*rng.standard_normal((nv,3))[mv]
    elif model=='view':
        u=rng.standard_normal(3); u/=np.linalg.norm(u); Y[mv]+=s*rng.standard_normal(nv)[mv,None]*u
    elif model=='corr':
        z=rng.standard_normal(nv)
        for _ in range(9): z=(z+A@z)/(1+deg)
        z/=np.sqrt(np.mean(z[mv]**2)); Y[mv]+=s*z[mv,None]*n[mv]
    elif model=='out':
        Y[mv]+=s*rng.standard_normal(nv)[mv,None]*n[mv]
        idx=np.flatnonzero(mv); K=max(1,round(0.01*len(idx))); pick=rng.choice(idx,K,replace=False)
        Y[pick]+=(rng.uniform(3,5,K)*h*rng.choice([-1,1],K))[:,None]*n[pick]
    return Y
def regions(A,N,fixed,cos_t):
    nv=len(N); lab=-np.ones(nv,int); sizes=[]
    indptr,ind=A.indptr,A.indices
    for s0 in range(nv):
        if lab[s0]>=0 or fixed[s0]: continue
        r=len(sizes); lab[s0]=r; q=[s0]; ns=N[s0]; cnt=0
        while q:
            v=q.pop(); cnt+=1
            for w in ind[indptr[v]:indptr[v+1]]:
                if lab[w]<0 and not fixed[w] and N[w]@ns>=cos_t: lab[w]=r; q.append(w)
        sizes.append(cnt)
    return lab,np.array(sizes)
def stats(Y,F,A,deg,fixed,h):
    nfree=(~fixed).sum()
    out={}
    Z=Y.copy()
    for _ in range(9): Z=avg(A,deg,Z)
    for nm,P in (('A9',Z),):
      N=vnormals(P,F)
      for th in (8,):
        lab,sz=regions(A,N,fixed,np.cos(np.radians(th)))
        for fr in (0.02,):
            out['%s_t%d'%(nm,th)]=sz[sz>=fr*nfree].sum()/nfree
    P=taubin(A,deg,fixed,Y); N=vnormals(P,F)
    # coarse reading: n.(Y - Avg^9 Y), MAD
    Z=Y.copy()
    for _ in range(9): Z=avg(A,deg,Z)
    d=((Y-Z)*N).sum(1)[(~fixed)&(deg>=3)]
    out['coarse']=1.4826*np.median(np.abs(d-np.median(d)))/h
    return out
m=sys.argv[1]; X,F=load_obj(os.path.join(os.environ.get('MESH_DIR', '/work/shared/meshes'), m)); A,deg,fixed,h=setup(X,F)
cases=[('clean',0)]+[(mo,r) for mo in ('normal','corr','iso','view','out') for r in (0.1,0.25,0.5)]
if len(sys.argv)>2: cases=[c for c in cases if c[0] in sys.argv[2].split(',')]
for mo,r in cases:
    Y=X if mo=='clean' else noisy(X,F,A,deg,fixed,h,mo,r)
    o=stats(Y,F,A,deg,fixed,h)
    print(m,mo,r,' '.join('%s=%.3f'%(k,v) for k,v in o.items()),flush=True)
