# Writes fixtures/kalibr/camchain.yaml in the layout of Kalibr's kalibr_calibrate_cameras (its
# ConfigReader writes the camera chain with PyYAML's yaml.dump, leaf lists in flow style, as here; Kalibr itself, a ROS
# package, was not run): three cameras, pinhole-radtan, pinhole-equi and pinhole-radtan, each
# T_cn_cnm1 taking the previous camera's coordinates to its own. Prints where X projects in each
# camera, the chain composed here in numpy (cam0's frame the world) and projected by OpenCV
# (cv2.projectPoints, cv2.fisheye.projectPoints), the numbers in crates/modelflow/tests/calib.rs.
# Run from the repository root, with numpy, opencv-python and pyyaml:
#   python3 tools/make_kalibr_fixture.py
import cv2, numpy as np, yaml


def rigid(rvec, t):
    T = np.eye(4)
    T[:3, :3] = cv2.Rodrigues(np.array(rvec, float))[0]
    T[:3, 3] = t
    return T


cams = [
    dict(model='radtan', k=[458.654, 457.296, 367.215, 248.375],
         d=[-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05], size=[752, 480], T=None),
    dict(model='equidistant', k=[461.851, 462.247, 325.276, 247.102],
         d=[0.0268, -0.0121, 0.0031, -0.0009], size=[640, 480],
         T=rigid([0.012, -0.06, 0.004], [-0.11, 0.002, 0.015])),
    dict(model='radtan', k=[1402.5, 1400.1, 958.3, 541.2],
         d=[0.061, -0.093, 0.0004, -0.0011], size=[1920, 1080],
         T=rigid([-0.02, -0.05, 0.01], [-0.12, -0.005, 0.03])),
]
chain = {}
for n, c in enumerate(cams):
    e = {'camera_model': 'pinhole', 'intrinsics': c['k'], 'distortion_model': c['model'],
         'distortion_coeffs': c['d'], 'resolution': c['size'], 'rostopic': f'/cam{n}/image_raw',
         'cam_overlaps': [m for m in range(len(cams)) if m != n]}
    if c['T'] is not None:
        e['T_cn_cnm1'] = c['T'].tolist()
    chain[f'cam{n}'] = e
with open('fixtures/kalibr/camchain.yaml', 'w') as f:
    yaml.dump(chain, f, default_flow_style=None)

X = np.array([[0.15, -0.08, 2.3]])
T_w = np.eye(4)
for n, c in enumerate(cams):
    if c['T'] is not None:
        T_w = c['T'] @ T_w
    rvec = cv2.Rodrigues(T_w[:3, :3])[0]
    t = T_w[:3, 3]
    fu, fv, pu, pv = c['k']
    K = np.array([[fu, 0, pu], [0, fv, pv], [0, 0, 1.0]])
    if c['model'] == 'equidistant':
        uv = cv2.fisheye.projectPoints(X.reshape(1, 1, 3), rvec, t, K, np.array(c['d']))[0]
    else:
        uv = cv2.projectPoints(X, rvec, t, K, np.array(c['d']))[0]
    print(f'cam{n}', uv.ravel().tolist())
