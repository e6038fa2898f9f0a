# Writes fixtures/opencv (stereo.yml, stereo.json, rig.yml) with OpenCV 5.0.0 and prints where
# X = (0.1, -0.05, 2.2) projects in each camera; run in fixtures/opencv.
# pip install opencv-python-headless numpy
import cv2, numpy as np
K1=np.array([[800.0,0,319.5],[0,790.0,241.25],[0,0,1]]); D1=np.array([[-0.3,0.1,0.001,-0.0005,-0.02]])
K2=np.array([[805.0,0,322.0],[0,795.0,238.5],[0,0,1]]); D2=np.array([[0.1,-0.05,0.0,0.0,0.01]])
rvec=np.array([[0.02],[-0.3],[0.01]]); R,_=cv2.Rodrigues(rvec); T=np.array([[0.5],[0.01],[0.05]])
for ext in ['yml','json']:
    fs=cv2.FileStorage('stereo.'+ext, cv2.FILE_STORAGE_WRITE)
    fs.write('image_width',640); fs.write('image_height',480)
    fs.write('K1',K1); fs.write('D1',D1); fs.write('K2',K2); fs.write('D2',D2); fs.write('R',R); fs.write('T',T); fs.release()
# multi-camera: one map per camera, rvec form, and a fisheye
fs=cv2.FileStorage('rig.yml', cv2.FILE_STORAGE_WRITE)
for i,(K,D,rv,t,model) in enumerate([(K1,D1,np.zeros((3,1)),np.zeros((3,1)),'opencv'),(K2,D2,rvec,T,'opencv'),(K1,np.array([[0.05,-0.01,0.002,-0.0005]]),-rvec,-T,'fisheye')]):
    fs.startWriteStruct(f'cam{i}', cv2.FileNode_MAP)
    fs.write('image_width',640); fs.write('image_height',480)
    fs.write('camera_matrix',K); fs.write('distortion_coefficients',D); fs.write('distortion_model',model)
    fs.write('rvec',rv); fs.write('tvec',t)
    fs.endWriteStruct()
fs.release()
# reference projections of a point X (world = cam1 frame for stereo)
X=np.array([[0.1,-0.05,2.2]])
print('stereo cam0', cv2.projectPoints(X,np.zeros(3),np.zeros(3),K1,D1)[0].ravel().tolist())
print('stereo cam1', cv2.projectPoints(X,rvec,T,K2,D2)[0].ravel().tolist())
print('rig cam2 fisheye', cv2.fisheye.projectPoints(X.reshape(1,1,3),-rvec,-T,K1,np.array([0.05,-0.01,0.002,-0.0005]))[0].ravel().tolist())
