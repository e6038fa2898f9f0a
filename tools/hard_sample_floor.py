"""The best a tracker could do on a clip with ground truth, if it got every well-seen vertex
exactly right and extrapolated the rest as-rigidly-as-possible (docs/tracker.md, "--stereo": what
bounds the hard sample).

Per frame: vertices that two cameras face at a cosine above COS (inside the image) are set to the
truth; vertices one camera faces keep the truth's position across that camera's ray (their depth
is free); the others are solved as-rigidly-as-possible from the first frame's shape (per-vertex
rotations and the mesh Laplacian, 20 local/global rounds, started from the previous frame).
Prints the RMS vertex error per frame and its mean, % of the first mesh's bounding-box diagonal.

    python3 tools/hard_sample_floor.py [SCENE_DIR] [COS]     (default: the hard sample, 0.1)

numpy only; about ten minutes for the hard sample's 565 vertices and 24 frames.
"""
import numpy as np, json, sys
H=sys.argv[1] if len(sys.argv)>1 else '../shared/footage/blender-hard-sample'
COS=float(sys.argv[2]) if len(sys.argv)>2 else 0.1
def obj(p):
    V=[];F=[]
    for l in open(p):
        if l.startswith('v '): V.append([float(x) for x in l.split()[1:4]])
        elif l.startswith('f '): F.append([int(x.split('/')[0])-1 for x in l.split()[1:4]])
    return np.array(V),np.array(F)
X0,F=obj(H+'/mesh/initial.obj')
s=json.load(open(H+'/scene-undistorted.json' if __import__('os').path.exists(H+'/scene-undistorted.json') else H+'/scene.json'))
cams=[]
for c in s['cameras']:
    K=np.array(c['K']);R=np.array(c['R']);t=np.array(c['t'])
    cams.append((K,R,t,-R.T@t,c['width'],c['height']))
n=len(X0)
E=set()
for f in F:
    for a,b in ((0,1),(1,2),(2,0)): E.add((min(f[a],f[b]),max(f[a],f[b])))
E=np.array(sorted(E))
nb=[[] for _ in range(n)]
for a,b in E: nb[a].append(b); nb[b].append(a)
L=np.zeros((n,n))
for a,b in E: L[a,a]+=1;L[b,b]+=1;L[a,b]-=1;L[b,a]-=1
def normals(X):
    N=np.zeros_like(X)
    fn=np.cross(X[F[:,1]]-X[F[:,0]],X[F[:,2]]-X[F[:,0]])
    for k in range(3): np.add.at(N,F[:,k],fn)
    return N/np.linalg.norm(N,axis=1,keepdims=True)
# orientation: outward if normals point away from centroid on average
N0=normals(X0); sgn=np.sign(np.mean(np.sum(N0*(X0-X0.mean(0)),1)))
def seen(X):
    N=normals(X)*sgn; m=np.zeros(len(X),bool)
    for K,R,t,C,w,h in cams:
        Y=X@R.T+t; p=Y@K.T; uv=p[:,:2]/p[:,2:]
        ins=(Y[:,2]>0)&(uv[:,0]>=0)&(uv[:,0]<=w-1)&(uv[:,1]>=0)&(uv[:,1]<=h-1)
        fac=np.sum(N*(C-X),1)>0
        m|=ins&fac
    return m
diag=np.linalg.norm(X0.max(0)-X0.min(0))
def arap(Xs,mask,init,its=20,one=None):
    # mask: pinned; one: dict i->ray unit vector (constrain the 2 DOF across the ray)
    x=init.copy(); x[mask]=Xs[mask]
    u=np.where(~mask)[0]; pos={v:k for k,v in enumerate(u)}
    m=len(u)
    Lu=np.kron(L[np.ix_(u,u)],np.eye(3))
    Wq=np.zeros((3*m,3*m)); wq=np.zeros(3*m)
    W=1e4
    for i,r in (one or {}).items():
        if i in pos:
            k=pos[i]; Q=np.eye(3)-np.outer(r,r)
            Wq[3*k:3*k+3,3*k:3*k+3]+=W*Q; wq[3*k:3*k+3]+=W*Q@Xs[i]
    A=Lu+Wq
    for _ in range(its):
        Rs=[]
        for i in range(n):
            P=np.array([X0[i]-X0[j] for j in nb[i]]); Q=np.array([x[i]-x[j] for j in nb[i]])
            U,S,Vt=np.linalg.svd(P.T@Q); R=(U@Vt).T
            if np.linalg.det(R)<0: U[:,-1]*=-1; R=(U@Vt).T
            Rs.append(R)
        b=np.zeros((n,3))
        for a_,c in E:
            d=0.5*(Rs[a_]+Rs[c])@(X0[a_]-X0[c]); b[a_]+=d; b[c]-=d
        rhs=(b[u]-L[np.ix_(u,mask)]@x[mask]).reshape(-1)+wq
        x[u]=np.linalg.solve(A,rhs).reshape(-1,3)
    return x
def seencount(X):
    N=normals(X)*sgn; m=np.zeros(len(X),int)
    for K,R,t,C,w,h in cams:
        Y=X@R.T+t; p=Y@K.T; uv=p[:,:2]/p[:,2:]
        ins=(Y[:,2]>0)&(uv[:,0]>=0)&(uv[:,0]<=w-1)&(uv[:,1]>=0)&(uv[:,1]<=h-1)
        cosv=np.sum(N*(C-X),1)/np.linalg.norm(C-X,axis=1)
        m+=ins&(cosv>COS)
    return m
errs=[];errs_prev=[];nseen=[]
prev=X0.copy()
for f in range(s['frames']['first']+1, s['frames']['last']+1):
    T,_=obj(H+'/truth/%04d.obj'%f)
    cnt=seencount(T); m=cnt>=2; nseen.append(m.sum())
    one={}
    Nn=normals(T)*sgn
    for i in np.where(cnt==1)[0]:
        for K,R,t,C,w,h in cams:
            Y=R@T[i]+t; p=K@Y; uv=p[:2]/p[2]
            cv=np.dot(Nn[i],C-T[i])/np.linalg.norm(C-T[i])
            if Y[2]>0 and 0<=uv[0]<=w-1 and 0<=uv[1]<=h-1 and cv>COS:
                r=T[i]-C; one[i]=r/np.linalg.norm(r)
    x=arap(T,m,prev,one=one)
    e=np.sqrt(np.mean(np.sum((x-T)**2,1)))/diag*100
    errs.append(e); prev=x
    print(f, m.sum(), '%.3f'%e, flush=True)
print('floor (seen by two cameras exact, one camera across its ray, the rest as-rigidly-as-possible): mean %.3f %% final %.3f %%; seen by two per frame %d-%d of %d'%(np.mean(errs),errs[-1],min(nseen),max(nseen),n))
