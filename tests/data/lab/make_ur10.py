# another lab's log: UR10, loading bar 0.2 m off the tool point (force + moment), 3 hanging masses,
# sequence repeated twice, unloaded rows before each load, temperature+timestamp, reordered columns
import numpy as np, pinocchio as pin, csv, sys
import os; rng=np.random.default_rng(int(os.environ.get("SEED","7")))
m=pin.buildModelFromUrdf('/tmp/newuser/config/robots/ur10.urdf'); d=m.createData()
fid=m.getFrameId('tool0'); bid=m.getFrameId('base_link')
tool=np.array([0,0,0.05])
names=[m.names[i] for i in range(1,m.njoints)]
k_true=np.array([2.2e-6,1.9e-6,4.3e-6,1.1e-5,0.9e-5,1.2e-5])
sigma=8e-6
def defl(q,F,M):
    pin.forwardKinematics(m,d,q); pin.updateFramePlacements(m,d)
    oMb=d.oMf[bid]; oMf=d.oMf[fid]
    J=pin.computeFrameJacobian(m,d,q,fid,pin.LOCAL_WORLD_ALIGNED)
    p=oMf.act(tool); o=oMf.translation
    # shift to tool point: v_p = v_o + w x (p-o) = v_o - (p-o) x w
    r=p-o; Jv=J[:3]-np.cross(r,J[3:].T).T; Jw=J[3:]
    # base frame = base_link; express in base_link
    R=oMb.rotation
    Jv=R.T@Jv; Jw=R.T@Jw
    tau=Jv.T@F+Jw.T@M
    dq=k_true*tau
    return Jv@dq, Jw@dq
confs=rng.uniform(-150,150,(8,6)); confs[:,1]=rng.uniform(-160,-20,8); confs[:,2]=rng.uniform(-150,150,8)
rows=[]
t=1700000000.0
bar=np.array([0.2,0,0])   # loading bar: weight hangs 0.2 m along base x from the tool point
for rep in range(2):
  for ci,qd in enumerate(confs):
    q=np.radians(qd)
    for F in [np.array([0,0,-49.05]),np.array([0,0,-98.1]),np.array([0,0,-196.2]),np.array([100.,0,0]),np.array([0,100.,0])]:
        M=np.cross(bar,F)
        t+=30; temp=21.3+0.02*ci+rng.normal(0,0.05)
        rows.append(dict(pose_id=f"P{ci+1:02d}",t=t,temp=temp,q=qd,F=[0,0,0],M=[0,0,0],d=[0,0,0]))
        t+=30
        dv,dw=defl(q,F,M)
        dv=dv+rng.normal(0,sigma,3)
        rows.append(dict(pose_id=f"P{ci+1:02d}",t=t,temp=temp,q=qd,F=F,M=M,d=dv))
# blunders
rows[13]['d']=np.array(rows[13]['d'])+np.array([4e-4,0,0])
rows[40]['d']=np.array(rows[40]['d'])+np.array([0,-6e-4,3e-4])
hdr=['timestamp','pose_id','temperature_C']+['dz_m','dx_m','dy_m']+['fz_N','fx_N','fy_N','mx_Nm','my_Nm','mz_Nm']+[f'q_{n}_deg' for n in names]
mm = len(sys.argv)>2 and sys.argv[2]=='mm'
with open(sys.argv[1],'w',newline='') as f:
    w=csv.writer(f); w.writerow(hdr)
    for r in rows:
        dd=np.array(r['d'],float)*(1000 if mm else 1)
        w.writerow([f"{r['t']:.1f}",r['pose_id'],f"{r['temp']:.2f}",f"{dd[2]:.6e}",f"{dd[0]:.6e}",f"{dd[1]:.6e}",f"{r['F'][2]:.2f}",f"{r['F'][0]:.2f}",f"{r['F'][1]:.2f}"]+[f"{x:.3f}" for x in r['M']]+[f"{x:.4f}" for x in r['q']])
print(len(rows),'rows; joint names',names)
