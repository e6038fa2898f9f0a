# Writes fixtures/metashape/cameras.xml, a camera file in Agisoft Metashape's XML layout (two
# sensors, two aligned cameras, one not aligned, a chunk transform with scale), and prints where
# the world point X projects in each camera by Metashape's own published camera model (its user
# manual, appendix "Camera models", frame cameras), implemented here independently of modelflow:
# pixel coordinates with the top-left pixel's centre at (0.5, 0.5), as Metashape counts them.
# pip install numpy; run from the repository root.
import numpy as np

def rot(v):  # Rodrigues' formula
    v = np.asarray(v, float); a = np.linalg.norm(v); k = v / a
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K

sensors = [
    dict(w=1920, h=1080, f=1710.5, cx=12.3, cy=-8.7, b1=0.8, b2=-0.3, k1=-0.12, k2=0.05, k3=-0.01, p1=0.0007, p2=-0.0004),
    dict(w=1280, h=720, f=1005.0, cx=-3.1, cy=4.2, b1=0.0, b2=0.0, k1=0.08, k2=-0.02, k3=0.0, p1=0.0, p2=0.0),
]
# Camera-to-chunk transforms: cameras looking at the chunk's origin from about 3 units away.
cams = [("cam0", 0, rot([0.1, -0.4, 0.05]), np.array([1.2, -0.1, -2.8])),
        ("cam1", 1, rot([-0.05, 0.35, -0.02]), np.array([-1.0, 0.2, -2.9]))]
Rc, Tc, s = rot([0.3, 0.2, -0.1]), np.array([10.0, -4.0, 2.5]), 1.7
X_world = s * Rc @ np.array([0.1, -0.2, 0.3]) + Tc

def project(sen, Rcam, tcam, Xw):
    Xchunk = Rc.T @ (Xw - Tc) / s
    X = Rcam.T @ (Xchunk - tcam)
    x, y = X[0] / X[2], X[1] / X[2]
    r2 = x * x + y * y
    rad = 1 + sen['k1'] * r2 + sen['k2'] * r2**2 + sen['k3'] * r2**3
    xp = x * rad + (sen['p1'] * (r2 + 2 * x * x) + 2 * sen['p2'] * x * y)
    yp = y * rad + (sen['p2'] * (r2 + 2 * y * y) + 2 * sen['p1'] * x * y)
    u = sen['w'] * 0.5 + sen['cx'] + xp * sen['f'] + xp * sen['b1'] + yp * sen['b2']
    v = sen['h'] * 0.5 + sen['cy'] + yp * sen['f']
    return u, v

f = lambda a: ' '.join(repr(float(v)) for v in np.ravel(a))
out = ['<?xml version="1.0" encoding="UTF-8"?>', '<document version="2.0.0">', '  <chunk label="Chunk 1" enabled="true">', '    <sensors next_id="2">']
for i, sen in enumerate(sensors):
    out += [f'    <sensor id="{i}" label="sensor {i}" type="frame">', f'      <resolution width="{sen["w"]}" height="{sen["h"]}"/>',
            '      <calibration type="frame" class="adjusted">', f'        <resolution width="{sen["w"]}" height="{sen["h"]}"/>']
    out += [f'        <{k}>{sen[k]!r}</{k}>' for k in ['f', 'cx', 'cy', 'b1', 'b2', 'k1', 'k2', 'k3', 'p1', 'p2'] if sen[k] != 0.0 or k == 'f']
    out += ['      </calibration>', '    </sensor>']
out += ['    </sensors>', '    <cameras next_id="3" next_group_id="0">']
for i, (name, sid, R, t) in enumerate(cams):
    M = np.eye(4); M[:3, :3] = R; M[:3, 3] = t
    out += [f'      <camera id="{i}" sensor_id="{sid}" label="{name}">', f'        <transform>{f(M)}</transform>', '      </camera>']
out += ['      <camera id="2" sensor_id="0" label="not aligned"/>', '    </cameras>', '    <transform>',
        f'      <rotation locked="true">{f(Rc)}</rotation>', f'      <translation locked="true">{f(Tc)}</translation>',
        f'      <scale locked="true">{s!r}</scale>', '    </transform>', '  </chunk>', '</document>']
open('fixtures/metashape/cameras.xml', 'w').write('\n'.join(out) + '\n')
print('X_world', X_world.tolist())
for name, sid, R, t in cams:
    print(name, project(sensors[sid], R, t, X_world))
