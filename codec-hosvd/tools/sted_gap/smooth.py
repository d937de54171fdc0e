"""Does a smooth basis help U1? STED of hosvd's truncated operator when each mode-1 factor
column is replaced by its projection onto the NB lowest mesh-Laplacian eigenvectors, and at
equal quantization scale (A = per-vertex quantization, B = spectral coefficients).

usage: python3 smooth.py NAME V F NB SCALE [SCALE ...]   (e.g. horse-gallop 8 24 300 0.002 0.004)
"""
import numpy as np, sys, time, scipy.sparse as sp, scipy.sparse.linalg as sla
import os
SHARED=os.environ.get('ANIMCODEC_SHARED', os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', '..', '..', 'shared'))
sys.path.insert(0, os.path.join(SHARED, 'peers'))
from sted_np import sted_parts
from anim import load_pc2, load_obj_faces
name=sys.argv[1]; v=int(sys.argv[2]); f=int(sys.argv[3]); NB=int(sys.argv[4])
A=load_pc2(f'{SHARED}/data/{name}/{name}.pc2'); A=np.asarray(A[0] if isinstance(A,tuple) else A,float)
faces=np.asarray(load_obj_faces(f'{SHARED}/data/{name}/{name}.obj'))
F,V,_=A.shape
T=A.transpose(1,2,0)  # V x 3 x F
U1=np.linalg.svd(T.reshape(V,3*F),full_matrices=False)[0][:,:v]
U3=np.linalg.svd(T.transpose(2,0,1).reshape(F,3*V),full_matrices=False)[0][:,:f]
C=np.einsum('vcf,vi,fl->icl',T,U1,U3)
def recon(U1q): return np.einsum('icl,vi,fl->fvc',C,U1q,U3)
S0,_,_=sted_parts(A,recon(U1),faces); print("truncation STED_s %.4f"%S0)
# mesh graph
E=np.unique(np.sort(np.concatenate([faces[:,[0,1]],faces[:,[1,2]],faces[:,[2,0]]]),axis=1),axis=0)
Adj=sp.coo_matrix((np.ones(2*len(E)),(np.r_[E[:,0],E[:,1]],np.r_[E[:,1],E[:,0]])),shape=(V,V)).tocsr()
deg=np.asarray(Adj.sum(1)).ravel()
gain=np.linalg.norm(C.reshape(v,-1),axis=1)
def H(q):
    _,c=np.unique(q,return_counts=True); p=c/c.sum(); return -(c*np.log2(p)).sum()
# A: rate proxy of the codec's coding: residual of x minus mean of neighbours (noncausal proxy of prediction residual)
Lap=sp.identity(V)-sp.diags(1/np.maximum(deg,1))@Adj
def code_A(scale):
    bits=0; U=np.zeros_like(U1)
    for i in range(v):
        d=scale/gain[i]
        q=np.round(U1[:,i]/d); U[:,i]=q*d
        r=np.round(Lap@U1[:,i]/d)  # proxy rate: entropy of quantized Laplacian residual
        bits+=H(r)
    return bits,U
t=time.time()
# lowest NB eigenvectors of the combinatorial Laplacian D - A (shift-invert just below 0)
vals,vecs=sla.eigsh((sp.diags(deg)-Adj).astype(float),k=NB,sigma=-1e-6,which='LM')
print("eig %d in %.1fs"%(NB,time.time()-t))
coef=vecs.T@U1  # NB x v
resid=U1-vecs@coef
print("spectral truncation only STED_s %.4f"%sted_parts(A,recon(vecs@coef),faces)[0])
def code_B(scale):
    bits=0; U=np.zeros_like(U1)
    for i in range(v):
        d=scale/gain[i]
        q=np.round(coef[:,i]/d)
        for b in range(0,NB,max(NB//16,1)): bits+=H(q[b:b+max(NB//16,1)])
        U[:,i]=vecs@(q*d)
    return bits,U
for scale in [float(x) for x in sys.argv[5:]]:
    ba,Ua=code_A(scale); sa=sted_parts(A,recon(Ua),faces)[0]
    bb,Ub=code_B(scale); sb=sted_parts(A,recon(Ub),faces)[0]
    print("scale %.3g  A: %.0f B STED_s %.4f | B: %.0f B STED_s %.4f"%(scale,ba/8,sa,bb/8,sb))
