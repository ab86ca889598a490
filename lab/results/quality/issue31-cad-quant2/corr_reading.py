# SPDX-License-Identifier: MIT
"""corr_reading.py MESH - a coarse first-order normal reading (robust RMS of n . (x - Avg^p x), p uniform-average passes) on the clean mesh, with issue 31 corr noise of 0.1 h (numpy draw, seed 1, interior vertices) and with white noise of 0.1 h along the normals, in mean edges. A lab probe for blade.obj corr 0.1 h; not in the product."""
import numpy as np, scipy.sparse as sp, sys
def load_obj(p):
    V=[];F=[]
    for l in open(p):
        if l.startswith('v '): V.append([float(x) for x in l.split()[1:4]])
        elif l.startswith('f '): F.append([int(x.split('/')[0])-1 for x in l.split()[1:4]])
    return np.array(V),np.array(F)
def adj(F,nv):
    i=np.r_[F[:,0],F[:,1],F[:,2],F[:,1],F[:,2],F[:,0]]; j=np.r_[F[:,1],F[:,2],F[:,0],F[:,0],F[:,1],F[:,2]]
    A=sp.coo_matrix((np.ones(len(i)),(i,j)),shape=(nv,nv)).tocsr(); A.data[:]=1; return A
def vnormals(X,F):
    n=np.cross(X[F[:,1]]-X[F[:,0]],X[F[:,2]]-X[F[:,0]]); N=np.zeros_like(X)
    for k in range(3): np.add.at(N,F[:,k],n)
    return N/np.maximum(np.linalg.norm(N,axis=1),1e-300)[:,None]
def boundary(F,nv):
    E={}
    for t in F:
        for k in range(3):
            a,b=sorted((t[k],t[(k+1)%3])); E[(a,b)]=E.get((a,b),0)+1
    bv=np.zeros(nv,bool)
    for (a,b),c in E.items():
        if c==1: bv[a]=bv[b]=True
    return bv
def reading(X,F,A,deg,passes):
    # normal high-pass of the input smoothed at scale: d = n.(x - Avg^p x) second order, robust rms
    Avg=sp.diags(1/deg)@A
    n=vnormals(X,F)
    Y=X.copy()
    for _ in range(passes): Y=Avg@Y
    d=((X-Y)*n).sum(1)
    e=d
    return 1.4826*np.median(np.abs(e-np.median(e)))
m=sys.argv[1]; X,F=load_obj('/work/shared/meshes/'+m); nv=len(X); A=adj(F,nv); deg=np.asarray(A.sum(1)).ravel()
h=np.mean(np.linalg.norm(X[F[:,1]]-X[F[:,0]],axis=1)); bv=boundary(F,nv)
rng=np.random.default_rng(1); n=vnormals(X,F)
g=rng.standard_normal(nv); g[bv]=0
Avg=sp.diags(1/deg)@A
for _ in range(9): g=Avg@g; g[bv]=0
g/=np.sqrt(np.mean(g[~bv]**2))
w=rng.standard_normal(nv); w[bv]=0
out=[m]
for p in (3,9,27):
    r0=reading(X,F,A,deg,p)/h
    rc=reading(X+(0.1*h*g)[:,None]*n,F,A,deg,p)/h
    rw=reading(X+(0.1*h*w)[:,None]*n,F,A,deg,p)/h
    out.append('p%d clean %.4f corr0.1 %.4f white0.1 %.4f'%(p,r0,rc,rw))
print(' | '.join(out))
