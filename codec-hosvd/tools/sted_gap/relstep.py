"""Steps proportional to the local edge length: U1 quantized with per-vertex steps
2^(γ·class/2), class = half-octaves of the vertex's RMS incident edge length against the median;
bytes (rate proxy as in meanrm.py) at STED_s 0.045 / 0.05 / 0.06 per γ.

usage: python3 relstep.py NAME V F   (e.g. horse-gallop 8 24; samba 14 40)
"""
import sys
import numpy as np
from common import load, mesh, H, hosvd, sted_parts
name=sys.argv[1]; v=int(sys.argv[2]); f=int(sys.argv[3])
A,faces=load(name); F,V,_=A.shape
E,Adj,deg,Lap=mesh(faces,V)
T=A.transpose(1,2,0)
U1,U3,C=hosvd(T,v,f); gain=np.linalg.norm(C.reshape(v,-1),axis=1)
# per-vertex RMS incident edge length over frames
L2=((A[:,E[:,0]]-A[:,E[:,1]])**2).sum(-1).mean(0)
s=np.zeros(V); c=np.zeros(V); np.add.at(s,E[:,0],L2); np.add.at(s,E[:,1],L2); np.add.at(c,E[:,0],1); np.add.at(c,E[:,1],1)
Lv=np.sqrt(s/np.maximum(c,1)); Lv=np.where(c>0,Lv,np.median(Lv))
cls=np.clip(np.round(2*np.log2(Lv/np.median(Lv))),-8,2)   # half-octave classes
def code(scale,gamma):
    m=2.0**(gamma*cls/2); bits=0; U=np.zeros_like(U1)
    for i in range(v):
        d=scale/gain[i]*m
        q=np.round(U1[:,i]/d); U[:,i]=q*d
        # rate proxy: residual of neighbour-average prediction in units of the local step
        bits+=H(np.round((Lap@U1[:,i])/d))
    rec=np.einsum('icl,vi,fl->fvc',C,U,U3)
    return bits/8, sted_parts(A,rec,faces)[0]
print("class hist", {int(k):int(n) for k,n in zip(*np.unique(cls,return_counts=True))}, "side-info H0 bytes %.0f"%(H(cls)/8), "cond-nb proxy %.0f"%(H(np.round(Lap@cls))/8))
for gamma in [0,0.5,0.75,1.0]:
    pts=[code(sc,gamma) for sc in np.geomspace(0.001,0.02,10)]
    b=np.array([p[0] for p in pts]); st=np.array([p[1] for p in pts])
    # bytes at STED targets (log interp)
    out=[]
    for t in [0.045,0.05,0.06]:
        i=np.where(st<=t)[0]
        if len(i)==0 or i.max()==len(st)-1: out.append(float('nan')); continue
        j=i.max(); k=j+1
        tt=(np.log(t)-np.log(st[j]))/(np.log(st[k])-np.log(st[j])); out.append(np.exp(np.log(b[j])+tt*(np.log(b[k])-np.log(b[j]))))
    print("gamma",gamma,"bytes at STED_s 0.045/0.05/0.06:", " ".join("%.0f"%x for x in out))
