"""Does a smooth basis help U1? STED of hosvd's truncated operator when each mode-1 factor
column is replaced by its projection onto the NB lowest mesh-Laplacian eigenvectors, and at
equal quantization scale (A = per-vertex quantization, B = spectral coefficients).

usage: python3 smooth.py NAME V F NB SCALE [SCALE ...]   (e.g. horse-gallop 8 24 300 0.002 0.004)
"""
import sys, time
import numpy as np, scipy.sparse as sp, scipy.sparse.linalg as sla
from common import load, mesh, H, hosvd, sted_parts
name=sys.argv[1]; v=int(sys.argv[2]); f=int(sys.argv[3]); NB=int(sys.argv[4])
A,faces=load(name); F,V,_=A.shape
T=A.transpose(1,2,0)  # V x 3 x F
U1,U3,C=hosvd(T,v,f)
def recon(U1q): return np.einsum('icl,vi,fl->fvc',C,U1q,U3)
S0,_,_=sted_parts(A,recon(U1),faces); print("truncation STED_s %.4f"%S0)
E,Adj,deg,Lap=mesh(faces,V)
gain=np.linalg.norm(C.reshape(v,-1),axis=1)
# A: rate proxy of the codec's coding: entropy of the quantized neighbour-average residual
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
