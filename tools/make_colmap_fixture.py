# Writes fixtures/colmap (text and bin) with pycolmap 4.2.1 and prints, per camera model, where the
# point X = (0.1, -0.05, 0.2) projects (COLMAP pixel convention); run in fixtures/colmap.
# pip install pycolmap numpy
import pycolmap, numpy as np, os
r=pycolmap.Reconstruction()
models=[('SIMPLE_PINHOLE',[700,320,240]),('PINHOLE',[700,690,321,239]),('SIMPLE_RADIAL',[700,320,240,-0.1]),
('RADIAL',[700,320,240,-0.1,0.02]),('OPENCV',[700,690,321,239,-0.2,0.05,0.001,-0.0005]),
('FULL_OPENCV',[700,690,321,239,-0.2,0.05,0.001,-0.0005,0.01,0.02,-0.01,0.005]),('OPENCV_FISHEYE',[500,505,320,240,0.05,-0.01,0.002,-0.0005])]
X=np.array([0.1,-0.05,0.2])
for i,(m,p) in enumerate(models):
    cam=pycolmap.Camera(model=m,width=640,height=480,params=p,camera_id=i+1)
    r.add_camera_with_trivial_rig(cam)
    ang=0.1*(i+1)
    R=pycolmap.Rotation3d(np.array([0.1*np.sin(ang),0.2,0.05*i]))
    T=pycolmap.Rigid3d(R,np.array([0.05*i,-0.02,2.0+0.1*i]))
    img=pycolmap.Image(name=f'cam{i}/0000.png',camera_id=i+1,image_id=i+1)
    r.add_image_with_trivial_frame(img,T)
    im=r.image(i+1)
    xc=im.cam_from_world()*X
    uv=cam.img_from_cam(xc)
    print(m, repr(list(uv)))
os.makedirs('text',exist_ok=True); os.makedirs('bin',exist_ok=True)
r.write_text('text'); r.write_binary('bin')
