# planar 3-link arm, lab protocol: pushes in 4 directions at 2 magnitudes with a loading bar (moment),
# each load preceded by an unloaded row, sequence repeated 3 times, joint coupling between joints 2 and 3
import numpy as np, csv, sys, os
rng=np.random.default_rng(int(os.environ.get('SEED','3')))
L=np.array([0.5,0.4,0.25]); K=np.diag([2e-6,3e-6,5e-6]); K[1,2]=K[2,1]=float(os.environ.get('COUP','1.5e-6'))
sigma=5e-6
def jac(q):
    a=np.cumsum(q); x=np.cumsum(L*np.cos(a)); y=np.cumsum(L*np.sin(a)); p=np.array([x[-1],y[-1]])
    J=np.zeros((3,3))
    for i in range(3):
        o=np.array([0,0]) if i==0 else np.array([x[i-1],y[i-1]])
        r=p-o; J[0,i]=-r[1]; J[1,i]=r[0]; J[2,i]=1
    return J
confs=np.column_stack([rng.uniform(-170,170,12),rng.uniform(-140,140,12),rng.uniform(-140,140,12)])
rows=[]; t=0
for rep in range(3):
  for ci,qd in enumerate(confs):
    J=jac(np.radians(qd))
    for ang in [0,90,180,270]:
      for mag in [100,250]:
        F=mag*np.array([np.cos(np.radians(ang)),np.sin(np.radians(ang))]); Mz=0.15*mag  # bar offset: moment grows with load
        W=np.array([F[0],F[1],Mz])
        t+=20; rows.append([t,f"cfg{ci}",21.0+rng.normal(0,.1),*qd,0,0,0,0,0])
        dq=K@(J.T@W); d=J[:2]@dq+rng.normal(0,sigma,2)
        t+=20; rows.append([t,f"cfg{ci}",21.0+rng.normal(0,.1),*qd,F[0],F[1],Mz,d[0],d[1]])
rows[101][9]+=3e-4; rows[333][10]-=2e-4   # blunders (loaded rows: odd indices)
with open(sys.argv[1],'w',newline='') as f:
    w=csv.writer(f); w.writerow(['time_s','pose_id','temp_C','q3_deg','q1_deg','q2_deg','mz_Nm','fy_N','fx_N','dy_m','dx_m'])
    for r in rows:
        w.writerow([r[0],r[1],f"{r[2]:.2f}",f"{r[5]:.3f}",f"{r[3]:.3f}",f"{r[4]:.3f}",f"{r[8]:.2f}",f"{r[7]:.2f}",f"{r[6]:.2f}",f"{r[10]:.6e}",f"{r[9]:.6e}"])
print(len(rows))
