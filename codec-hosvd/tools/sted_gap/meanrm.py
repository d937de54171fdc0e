"""Mean removal: hosvd's operator of the positions (plain) vs a per-vertex mean coded apart
plus the operator of the deviations; rate proxy = zero-order entropy of the neighbour-average
residual of each quantized column; STED's spatial part exact.

usage: python3 meanrm.py NAME
"""
import sys
import numpy as np
from common import load, mesh, H, hosvd, sted_parts
name=sys.argv[1]
A,faces=load(name); F,V,_=A.shape
E,Adj,deg,Lap=mesh(faces,V)
def codeU1(U1,gain,scale):
    bits=0; U=np.zeros_like(U1)
    for i in range(U1.shape[1]):
        d=scale/gain[i]; U[:,i]=np.round(U1[:,i]/d)*d; bits+=H(np.round(Lap@U1[:,i]/d))
    return bits,U
T=A.transpose(1,2,0)
M=T.mean(2)
for mode in ["plain","meanrm"]:
    for v,f in [(8,24),(10,24),(12,24)] if mode=="meanrm" else [(8,24)]:
        X=T-M[:,:,None] if mode=="meanrm" else T
        U1,U3,C=hosvd(X,v,f); gain=np.linalg.norm(C.reshape(v,-1),axis=1)
        base=M[None] if mode=="meanrm" else 0
        rec=lambda U: np.einsum('icl,vi,fl->fvc',C,U,U3)+base
        print(mode,v,f,"trunc STED_s %.4f"%sted_parts(A,rec(U1),faces)[0])
        for scale in [0.002,0.004,0.008]:
            b,U=codeU1(U1,gain,scale); print("   scale",scale,"U1 bytes %.0f"%(b/8),"STED_s %.4f"%sted_parts(A,rec(U),faces)[0])
# mean coding cost at steps relative to median edge length
L=np.linalg.norm(M[E[:,0]]-M[E[:,1]],axis=1); med=np.median(L)
for rel in [0.01,0.02,0.05]:
    d=rel*med; b=sum(H(np.round(Lap@M[:,c]/d)) for c in range(3))
    Mq=np.round(M/d)*d
    print("mean step %.3f*medianL bytes %.0f"%(rel,b/8))
print("--- with quantized mean")
for v,f in [(8,24),(10,24)]:
    X=T-M[:,:,None]; U1,U3,C=hosvd(X,v,f); gain=np.linalg.norm(C.reshape(v,-1),axis=1)
    for rel in [0.02,0.05,0.1]:
        d=rel*med; bm=sum(H(np.round(Lap@M[:,c]/d)) for c in range(3)); Mq=np.round(M/d)*d
        for scale in [0.004,0.006,0.008]:
            b,U=codeU1(U1,gain,scale); rec=np.einsum('icl,vi,fl->fvc',C,U,U3)+Mq[None]
            print(v,f,"rel",rel,"scale",scale,"total %.0f"%((b+bm)/8),"STED_s %.4f"%sted_parts(A,rec,faces)[0])
