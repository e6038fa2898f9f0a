# Writes fixtures/mrcal/camera-{0,1,2}.cameramodel with mrcal 2.2 itself (cameramodel.write, as
# mrcal-calibrate-cameras writes a rig: every camera placed relative to camera 0's frame), and
# prints where X projects in each, by mrcal itself on the models read back from the files
# (mrcal.project of mrcal.transform_point_rt), the numbers in crates/modelflow/tests/calib.rs.
# Run from the repository root with Debian's python3-mrcal: /usr/bin/python3 tools/make_mrcal_fixture.py
import mrcal, numpy as np

models = [
    ('LENSMODEL_OPENCV8', [1402.5, 1401.1, 958.3, 541.2,
                           -0.12, 0.061, 0.0004, -0.0011, 0.013, 0.002, -0.001, 0.0005],
     [0, 0, 0, 0, 0, 0], [1920, 1080]),
    ('LENSMODEL_OPENCV5', [905.2, 904.4, 641.3, 358.7, -0.28, 0.09, 0.001, -0.0007, -0.012],
     [0.012, -0.21, 0.004, -0.35, 0.01, 0.05], [1280, 720]),
    ('LENSMODEL_PINHOLE', [700.0, 700.0, 319.5, 239.5],
     [-0.02, 0.18, -0.01, 0.31, -0.02, 0.1], [640, 480]),
]
for i, (lens, intr, rt, size) in enumerate(models):
    m = mrcal.cameramodel(intrinsics=(lens, np.array(intr, float)),
                          imagersize=np.array(size), extrinsics_rt_fromref=np.array(rt, float))
    m.write(f'fixtures/mrcal/camera-{i}.cameramodel')

X = np.array([0.12, -0.07, 1.9])
for i in range(len(models)):
    m = mrcal.cameramodel(f'fixtures/mrcal/camera-{i}.cameramodel')
    q = mrcal.project(mrcal.transform_point_rt(m.extrinsics_rt_fromref(), X), *m.intrinsics())
    print(f'camera-{i}', q.tolist())
