# Writes fixtures/anipose/calibration.toml with aniposelib 0.4.3 itself (CameraGroup.dump: two
# cameras of OpenCV's standard model and one fisheye, the layout Pose2Sim and FreeMoCap also
# read), and prints where X projects in each camera, by the cameras' own `project`
# (cv2.projectPoints / cv2.fisheye.projectPoints), and in each camera of
# fixtures/caliscope-board-sample/camera_array.toml (caliscope's own file, copied from its
# repository; projected as caliscope projects: cv2.projectPoints(X, Rodrigues(R), t, K, dist)).
# The numbers are in crates/modelflow/tests/calib.rs. Run from the repository root:
#   python3 -m venv /tmp/anienv && /tmp/anienv/bin/pip install aniposelib==0.4.3
#   /tmp/anienv/bin/python tools/make_toml_fixtures.py
import cv2, numpy as np, toml
from aniposelib.cameras import Camera, FisheyeCamera, CameraGroup

K = lambda f, cx, cy: np.array([[f, 0, cx], [0, f * 1.002, cy], [0, 0, 1.0]])
cams = [
    Camera(name='left', size=(1280, 720), matrix=K(900.0, 641.3, 358.7),
           dist=np.array([-0.28, 0.09, 0.001, -0.0007, -0.012]),
           rvec=np.array([0.0, 0.0, 0.0]), tvec=np.array([0.0, 0.0, 0.0])),
    Camera(name='right', size=(1280, 720), matrix=K(910.0, 636.0, 362.5),
           dist=np.array([0.05, -0.02, 0.0, 0.0, 0.0]),
           rvec=np.array([0.03, -0.42, 0.015]), tvec=np.array([-0.35, 0.01, 0.08])),
    FisheyeCamera(name='wide', size=(1920, 1080), matrix=K(700.0, 958.5, 541.5),
                  dist=np.array([0.04, -0.012, 0.003, -0.0004]),
                  rvec=np.array([-0.05, 0.38, -0.02]), tvec=np.array([0.31, -0.02, 0.1])),
]
group = CameraGroup(cams, metadata={'adjusted': False, 'error': 0.42})
group.dump('fixtures/anipose/calibration.toml')

X = np.array([[0.12, -0.07, 1.9]])
back = CameraGroup.load('fixtures/anipose/calibration.toml')
for c in back.cameras:
    print('anipose', c.get_name(), c.project(X).ravel().tolist())

cal = toml.load('fixtures/caliscope-board-sample/camera_array.toml')
Y = np.array([[0.05, 0.1, 0.02]])
for key, c in cal['cameras'].items():
    rvec, _ = cv2.Rodrigues(np.array(c['rotation']))
    uv, _ = cv2.projectPoints(Y, rvec, np.array(c['translation']), np.array(c['matrix']),
                              np.array(c['distortions']))
    print('caliscope', key, uv.ravel().tolist())
