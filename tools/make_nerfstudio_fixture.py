# Writes fixtures/nerfstudio from fixtures/colmap/text, the way nerfstudio's `ns-process-data`
# turns a COLMAP model into a transforms.json (nerfstudio/process_data/colmap_utils.py,
# colmap_to_json, several cameras: per-frame intrinsics; written here from its documented
# conventions, not by nerfstudio itself):
#   - c2w = inverse(world-to-camera); its camera axes turned from OpenCV's to OpenGL's (columns
#     1 and 2 negated); then the world turned z-up: rows (0, 2, 1), the new third row negated;
#     the same turn recorded as "applied_transform" (3x4);
#   - intrinsics copied as COLMAP gives them (pixel centres at half-integers): SIMPLE_PINHOLE and
#     PINHOLE -> PINHOLE, SIMPLE_RADIAL and RADIAL -> OPENCV (k1, k2, p1 = p2 = 0), OPENCV ->
#     OPENCV, OPENCV_FISHEYE -> OPENCV_FISHEYE (k1..k4); FULL_OPENCV has no nerfstudio model.
# Also a transforms_train.json in the original NeRF synthetic layout (Blender renders: one
# camera_angle_x, no image size, file paths without extension).
#
# For each file it prints where a world point projects, computed here by nerfstudio's and
# Blender's camera models (OpenGL camera-to-world, pixel centres at half-integers), and checks
# the nerfstudio ones against pycolmap's projections of the same point in COLMAP's world (the
# numbers in crates/modelflow/tests/calib.rs). Run from the repository root: python3
# tools/make_nerfstudio_fixture.py (numpy only).
import json, math, os
import numpy as np

src = 'fixtures/colmap/text'
out = 'fixtures/nerfstudio'


def data_lines(p):
    return [l.strip() for l in open(p) if l.strip() and not l.startswith('#')]


cams = {}
for l in data_lines(f'{src}/cameras.txt'):
    f = l.split()
    cams[int(f[0])] = (f[1], int(f[2]), int(f[3]), [float(v) for v in f[4:]])
images = []
for l in data_lines(f'{src}/images.txt'):
    f = l.split()
    if len(f) == 10:
        images.append(([float(v) for v in f[1:5]], [float(v) for v in f[5:8]], int(f[8]), f[9]))


def qrot(w, x, y, z):
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def intrinsics(model, w, h, p):
    o = {'w': w, 'h': h}
    if model == 'SIMPLE_PINHOLE':
        o.update(fl_x=p[0], fl_y=p[0], cx=p[1], cy=p[2], camera_model='PINHOLE')
    elif model == 'PINHOLE':
        o.update(fl_x=p[0], fl_y=p[1], cx=p[2], cy=p[3], camera_model='PINHOLE')
    elif model == 'SIMPLE_RADIAL':
        o.update(fl_x=p[0], fl_y=p[0], cx=p[1], cy=p[2], k1=p[3], k2=0.0, p1=0.0, p2=0.0, camera_model='OPENCV')
    elif model == 'RADIAL':
        o.update(fl_x=p[0], fl_y=p[0], cx=p[1], cy=p[2], k1=p[3], k2=p[4], p1=0.0, p2=0.0, camera_model='OPENCV')
    elif model == 'OPENCV':
        o.update(fl_x=p[0], fl_y=p[1], cx=p[2], cy=p[3], k1=p[4], k2=p[5], p1=p[6], p2=p[7], camera_model='OPENCV')
    elif model == 'OPENCV_FISHEYE':
        o.update(fl_x=p[0], fl_y=p[1], cx=p[2], cy=p[3], k1=p[4], k2=p[5], k3=p[6], k4=p[7], camera_model='OPENCV_FISHEYE')
    else:
        return None
    return o


applied = np.eye(4)[:3, :][[0, 2, 1], :]
applied[2, :] *= -1
frames = []
for q, t, cid, name in images:
    intr = intrinsics(*cams[cid])
    if intr is None:
        continue
    w2c = np.eye(4)
    w2c[:3, :3] = qrot(*q)
    w2c[:3, 3] = t
    c2w = np.linalg.inv(w2c)
    c2w[0:3, 1:3] *= -1
    c2w = c2w[[0, 2, 1, 3], :]
    c2w[2, :] *= -1
    frame = {'file_path': f'images/{name}', 'transform_matrix': c2w.tolist()}
    frame.update(intr)
    frames.append(frame)
os.makedirs(out, exist_ok=True)
with open(f'{out}/transforms.json', 'w') as fh:
    json.dump({'frames': frames, 'applied_transform': applied.tolist()}, fh, indent=4)


def project(frame, X, top={}):
    """Pixel (half-integer centres) of world point X by nerfstudio's camera model."""
    g = lambda k, d=0.0: frame.get(k, top.get(k, d))
    c2w = np.array(frame['transform_matrix'])[:3, :]
    p = c2w[:, :3].T @ (X - c2w[:, 3])  # OpenGL camera: x right, y up, looking down -z
    x, y = p[0] / -p[2], -p[1] / -p[2]  # image plane, y down
    model = g('camera_model', 'OPENCV')
    if model == 'OPENCV_FISHEYE':
        r = math.hypot(x, y)
        th = math.atan(r)
        thd = th * (1 + g('k1') * th**2 + g('k2') * th**4 + g('k3') * th**6 + g('k4') * th**8)
        s = thd / r if r > 0 else 1.0
        xd, yd = x * s, y * s
    else:
        r2 = x * x + y * y
        d = 1 + r2 * (g('k1') + r2 * (g('k2') + r2 * (g('k3') + r2 * g('k4'))))
        p1, p2 = g('p1'), g('p2')
        xd = x * d + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
        yd = y * d + 2 * p2 * x * y + p1 * (r2 + 2 * y * y)
    if 'fl_x' in frame or 'fl_x' in top:
        fx, fy, cx, cy = g('fl_x'), g('fl_y'), g('cx'), g('cy')
    else:  # NeRF synthetic: square pixels, the principal point at the image's centre
        W, H = top['_size']
        fx = fy = 0.5 * W / math.tan(0.5 * top['camera_angle_x'])
        cx, cy = W / 2, H / 2
    return [float(fx * xd + cx), float(fy * yd + cy)]


X = np.array([0.1, -0.05, 0.2])
Xn = applied[:, :3] @ X + applied[:, 3]
pycolmap = {  # crates/modelflow/tests/calib.rs, COLMAP
    'cam0': [364.3010088087352, 216.87258257291856], 'cam1': [379.4877235164787, 218.4618870312428],
    'cam2': [391.35008582751567, 221.33222442418347], 'cam3': [403.15044601368515, 223.3581242170272],
    'cam4': [414.76991976173724, 224.52679056298908], 'cam6': [400.36695040450985, 231.9783489886222],
}
print('transforms.json: X =', X.tolist(), 'in COLMAP\'s world is', Xn.tolist(), 'in the file\'s')
for f in frames:
    name = f['file_path'].split('/')[1]
    uv = project(f, Xn)
    assert max(abs(a - b) for a, b in zip(uv, pycolmap[name])) < 1e-9, (name, uv, pycolmap[name])
    print(f'  {name} {f["camera_model"]:<15} {uv!r}')

# The original NeRF synthetic layout: Blender's camera (OpenGL axes) looking at the origin.
def look_at(eye):
    eye = np.array(eye, float)
    back = eye / np.linalg.norm(eye)
    right = np.cross([0.0, 0.0, 1.0], back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, up, back, eye
    return m


nerf = {
    'camera_angle_x': 0.6911112070083618,
    'frames': [
        {'file_path': './train/r_0', 'rotation': 0.012566370614359171, 'transform_matrix': look_at([0.0, -4.0, 1.5]).tolist()},
        {'file_path': './train/r_1', 'rotation': 0.012566370614359171, 'transform_matrix': look_at([3.0, 2.5, 1.0]).tolist()},
    ],
}
with open(f'{out}/transforms_train.json', 'w') as fh:
    json.dump(nerf, fh, indent=4)
Y = np.array([0.3, -0.2, 0.4])
print('transforms_train.json (800x800): Y =', Y.tolist())
for f in nerf['frames']:
    print(f'  {f["file_path"]} {project(f, Y, dict(nerf, _size=(800, 800)))!r}')
