# Writes fixtures/alicevision/cameras.sfm and legacy.sfm, SfM files in AliceVision's (Meshroom's)
# JSON layout as its sfmDataIO/jsonIO.cpp writes them (every value a string, matrices flattened
# column by column as Eigen stores them), with landmarks whose observations are where
# AliceVision's own camera model puts them, implemented here independently of modelflow from
# AliceVision's sources (camera/IntrinsicScaleOffset, Pinhole, DistortionRadial, DistortionBrown,
# DistortionFisheye; geometry/Pose3; sfmData::SfMData::getPose):
#   x_cam = R·(X − C)                       (Pose3: R world-to-camera, C the centre)
#   rig:   R = R_sub·R_rig, C = C_rig + R_rigᵀ·C_sub   (sub-pose ∘ rig pose, "isPoseIndependant": "false")
#   p = x_cam[:2] / x_cam[2], distorted in those normalised coordinates
#   u = fx·p_d + (w/2 + offset), pixel centres at integers (AliceVision samples images at them)
#   fy = focalLength[mm] / sensorWidth[mm] · width, fx = fy / pixelRatio   (file version ≥ 1.2.11:
#   camera/IntrinsicScaleOffset.cpp's setFocalLength, and AliceVision's compatibility files of one
#   camera, whose focalLength is fx's up to 1.2.8 and fy's from 1.2.11)
#   version < 1.2.1: the principal point is absolute; < 1.2.0: one pxFocalLength.
# pip install numpy; run from the repository root.
import json
import numpy as np

def rot(v):  # Rodrigues' formula
    v = np.asarray(v, float); a = np.linalg.norm(v)
    if a == 0.0:
        return np.eye(3)
    k = v / a
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K

def look_at(c, target=(0.0, 0.0, 0.0), roll=0.0):
    """World-to-camera rotation of a camera at c looking at target, y down (OpenCV axes)."""
    c = np.asarray(c, float); z = np.asarray(target, float) - c; z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, -1.0, 0.0]); x /= np.linalg.norm(x); y = np.cross(z, x)
    return rot([0, 0, roll]) @ np.array([x, y, z])

def distort(kind, k, p):
    x, y = p; r2 = x * x + y * y
    if kind == 'none':
        return p
    if kind == 'radialk1':
        return p * (1 + k[0] * r2)
    if kind == 'radialk3':
        return p * (1 + k[0] * r2 + k[1] * r2**2 + k[2] * r2**3)
    if kind == 'radialk3pt':
        return p * (1 + k[0] * r2 + k[1] * r2**2 + k[2] * r2**3) / (1 + k[0] + k[1] + k[2])
    if kind == 'brown':
        k1, k2, k3, t1, t2 = k
        d = k1 * r2 + k2 * r2**2 + k3 * r2**3
        return np.array([x + x * d + t2 * (r2 + 2 * x * x) + 2 * t1 * x * y,
                         y + y * d + t1 * (r2 + 2 * y * y) + 2 * t2 * x * y])
    if kind == 'fisheye':
        r = np.sqrt(r2); th = np.arctan(r)
        td = th + k[0] * th**3 + k[1] * th**5 + k[2] * th**7 + k[3] * th**9
        return p * td / r
    raise ValueError(kind)

def project(intr, R, C, X):
    xc = R @ (X - C)
    pd = distort(intr['kind'], intr['k'], xc[:2] / xc[2])
    fy = intr['fmm'] / intr['sw'] * intr['w']; fx = fy / intr['ratio']
    return [fx * pd[0] + intr['w'] / 2 + intr['off'][0], fy * pd[1] + intr['h'] / 2 + intr['off'][1]]

s = lambda v: repr(float(v)) if isinstance(v, (float, np.floating)) else str(v)
vec = lambda a: [s(float(v)) for v in np.ravel(np.asarray(a, float), order='F')]  # Eigen: column-major

intrinsics = {
    1: dict(w=1920, h=1080, sw=36.0, fmm=35.0, ratio=1.0, off=(12.5, -7.25), kind='none', k=[]),
    2: dict(w=1280, h=720, sw=23.5, fmm=18.0, ratio=1.0, off=(-4.0, 3.5), kind='radialk3', k=[-0.21, 0.09, -0.02]),
    3: dict(w=1920, h=1080, sw=36.0, fmm=28.0, ratio=1.02, off=(6.0, 9.0), kind='brown', k=[-0.11, 0.04, -0.006, 0.0008, -0.0005]),
    4: dict(w=1600, h=1200, sw=6.17, fmm=2.9, ratio=1.0, off=(-10.0, 5.0), kind='fisheye', k=[0.05, -0.01, 0.002, -0.0003]),
    5: dict(w=1280, h=720, sw=23.5, fmm=20.0, ratio=1.0, off=(2.0, -1.0), kind='radialk1', k=[-0.15]),
    6: dict(w=1280, h=720, sw=23.5, fmm=20.0, ratio=1.0, off=(0.0, 0.0), kind='radialk3pt', k=[-0.12, 0.03, 0.0]),
}
centres = {11: [3.0, -0.5, -2.0], 12: [-3.0, -0.4, -2.2], 13: [0.3, -2.8, -2.4], 14: [0.0, 0.5, -3.0]}
poses = {p: (look_at(c, roll=0.1 * i), np.array(c, float)) for i, (p, c) in enumerate(centres.items())}
# The rig: its pose (world to rig) and two sub-poses (rig to camera).
rig_pose = (rot([0.05, -0.2, 0.03]), np.array([0.5, -0.3, -3.5]))
sub = [(np.eye(3), np.array([-0.3, 0.0, 0.0])), (rot([0.0, 0.15, 0.0]), np.array([0.3, 0.0, 0.0]))]
views = [  # (viewId, camera folder, intrinsic, pose or rig sub-pose)
    (101, 'cam0', 1, 11), (102, 'cam1', 2, 12), (103, 'cam2', 3, 13), (104, 'cam3', 4, 14),
    (105, 'cam4', 5, ('rig', 0)), (106, 'cam5', 6, ('rig', 1)), (107, 'cam6', 1, 17),  # 17: not reconstructed
]

def view_pose(p):
    if isinstance(p, tuple):
        (Rs, Cs), (Rr, Cr) = sub[p[1]], rig_pose
        return Rs @ Rr, Cr + Rr.T @ Cs
    return poses.get(p)

landmarks = [np.array(x) for x in [(0.1, -0.05, 0.2), (-0.3, 0.25, -0.1), (0.25, 0.3, 0.15)]]

def intrinsic_entry(i, d):
    e = {"intrinsicId": s(i), "width": s(d['w']), "height": s(d['h']), "sensorWidth": s(d['sw']),
         "sensorHeight": s(d['sw'] * d['h'] / d['w']), "serialNumber": "", "type": "pinhole",
         "initializationMode": "estimated", "initialFocalLength": s(d['fmm']), "focalLength": s(d['fmm']),
         "pixelRatio": s(d['ratio']), "pixelRatioLocked": "true", "offsetLocked": "false", "scaleLocked": "false",
         "principalPoint": vec(d['off']), "distortionLocked": "false", "distortionInitializationMode": "none",
         "distortionParams": [s(v) for v in d['k']] if d['k'] else "", "undistortionOffset": ["0", "0"],
         "undistortionParams": "", "distortionType": d['kind'], "undistortionType": "none", "locked": "false"}
    return e

doc = {"version": ["1", "2", "14"], "featuresFolders": ["../FeatureExtraction"], "matchesFolders": ["../FeatureMatching"], "views": [], "intrinsics": [], "poses": [], "rigs": [], "structure": []}
for vid, cam, iid, p in views:
    v = {"viewId": s(vid), "poseId": s(p if not isinstance(p, tuple) else 15), "frameId": "0", "intrinsicId": s(iid)}
    if isinstance(p, tuple):
        v.update({"rigId": "0", "subPoseId": s(p[1]), "isPoseIndependant": "false"})
    v.update({"path": f"/shoot/images/{cam}/0000.png", "width": s(intrinsics[iid]['w']), "height": s(intrinsics[iid]['h']),
              "metadata": {"AliceVision:SensorWidth": s(intrinsics[iid]['sw'])}})
    doc["views"].append(v)
doc["intrinsics"] = [intrinsic_entry(i, d) for i, d in intrinsics.items()]
for pid, (R, C) in list(poses.items()) + [(15, rig_pose)]:
    doc["poses"].append({"poseId": s(pid), "pose": {"transform": {"rotation": vec(R), "center": vec(C)}, "locked": "0"}})
doc["rigs"].append({"rigId": "0", "subPoses": [{"status": "constant", "pose": {"rotation": vec(R), "center": vec(C)}} for R, C in sub]})
for li, X in enumerate(landmarks):
    obs = []
    for vid, cam, iid, p in views:
        vp = view_pose(p)
        if vp is None:
            continue
        obs.append({"observationId": s(vid), "featureId": s(li), "x": [s(v) for v in project(intrinsics[iid], vp[0], vp[1], X)], "scale": "1"})
    doc["structure"].append({"landmarkId": s(li), "descType": "dspsift", "color": ["128", "128", "128"], "X": [s(v) for v in X], "observations": obs})
open('fixtures/alicevision/cameras.sfm', 'w').write(json.dumps(doc, indent=4) + '\n')

# The layout of file version 1.0.0 (Meshroom 2019–2020): one pxFocalLength, the principal point
# from the image's top-left corner, the distortion in the type's name.
legacy = {"version": ["1", "0", "0"], "views": [], "intrinsics": [], "poses": [], "structure": []}
old = {7: dict(w=1280, h=720, f=1050.0, pp=(650.25, 355.5), kind='radialk3', type='radial3', k=[-0.18, 0.05, 0.0]),
       8: dict(w=1280, h=720, f=990.0, pp=(630.0, 362.0), kind='radialk1', type='radial1', k=[-0.09])}
for vid, (iid, pid) in {201: (7, 11), 202: (8, 12)}.items():
    legacy["views"].append({"viewId": s(vid), "poseId": s(pid), "intrinsicId": s(iid), "path": f"/shoot/images/cam{vid - 201}/0000.png", "width": "1280", "height": "720", "metadata": ""})
for iid, d in old.items():
    legacy["intrinsics"].append({"intrinsicId": s(iid), "width": s(d['w']), "height": s(d['h']), "serialNumber": "", "type": d['type'],
                                 "initializationMode": "estimated", "pxInitialFocalLength": s(d['f']), "pxFocalLength": s(d['f']),
                                 "principalPoint": vec(d['pp']), "distortionParams": [s(v) for v in d['k']], "locked": "0"})
for pid in (11, 12):
    R, C = poses[pid]
    legacy["poses"].append({"poseId": s(pid), "pose": {"transform": {"rotation": vec(R), "center": vec(C)}, "locked": "0"}})
for li, X in enumerate(landmarks):
    obs = []
    for vid, (iid, pid) in {201: (7, 11), 202: (8, 12)}.items():
        d = old[iid]
        intr = dict(w=d['w'], h=d['h'], sw=1.0, fmm=d['f'] / d['w'], ratio=1.0, off=(d['pp'][0] - d['w'] / 2, d['pp'][1] - d['h'] / 2), kind=d['kind'], k=d['k'])
        obs.append({"observationId": s(vid), "featureId": s(li), "x": [s(v) for v in project(intr, *poses[pid], X)]})
    legacy["structure"].append({"landmarkId": s(li), "descType": "sift", "color": ["0", "0", "0"], "X": [s(v) for v in X], "observations": obs})
open('fixtures/alicevision/legacy.sfm', 'w').write(json.dumps(legacy, indent=4) + '\n')
print('wrote fixtures/alicevision/cameras.sfm and legacy.sfm')
