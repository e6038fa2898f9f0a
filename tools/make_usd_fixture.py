"""Writes fixtures/usd/cameras.usda with Pixar's USD library (the `usd-core` package), and
cameras-expected.json: where Pixar's own camera model (`UsdGeom.Camera.GetCamera`, the
transform operations composed and interpolated by USD, then `Gf.Camera`'s frustum) puts six
points in each camera at frames 1..5 (what `modelflow import usd` must agree with; tests in
crates/modelflow/src/input/calib/usd.rs). Five cameras of 1280x720 images, sized by render
settings that name them, and what a stage from Maya, Houdini or Omniverse holds around them:
  front:   under /rig (translate, rotateZXY, scale 2); its own translate, rotateX, rotateZ; a
           16:9 film back with aperture offsets;
  orbit:   the camera prim `orbitShape` (no transform of its own) under the Xform `orbit`
           (translate, a pivot: translate:pivot, orient, !invert!translate:pivot); the default
           35 mm aperture (aspect 1.37 against the image's 1.78, conformed by USD's default
           policy, expandAperture); its size from the render settings of its render product;
  matrixcam: a 4x4 xformOp:transform under a moved and scaled /world, which its
           !resetXformStack! drops; a square aperture conformed by the policy cropAperture;
  moving:  translate sampled at frames 1, 3, 5, orient at 1 and 5 (USD slerps in between),
           rotateY still;
  tumble:  a 4x4 transform sampled at frames 1 and 5: USD interpolates the matrices entry by
           entry, and Gf.Camera orthonormalises what that gives.
And what is not a camera on the stage: a class and an over holding cameras, a deactivated
camera, a prim with variants, a prim referencing another internally, custom data, a mesh with
primvars, comments and docs.

Conform rule (CameraUtilConformWindow, applied here independently of modelflow): when the
aperture's aspect differs from the image's, expandAperture widens the narrower side, crop
narrows the wider one; the offsets stay.

    target/pyenv/bin/python tools/make_usd_fixture.py     (from the repository root)
"""
import json

from pxr import Gf, Sdf, Usd, UsdGeom, UsdRender

W, H = 1280, 720
stage = Usd.Stage.CreateNew("fixtures/usd/cameras.usda")
stage.SetMetadata("comment", "cameras for modelflow's USD import test")
UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
UsdGeom.SetStageMetersPerUnit(stage, 1.0)
stage.SetTimeCodesPerSecond(24)
stage.SetFramesPerSecond(24)
stage.SetStartTimeCode(1)
stage.SetEndTimeCode(5)


def film(cam, focal, ha, va, ho=0.0, vo=0.0):
    cam.CreateFocalLengthAttr(focal)
    if ha is not None:
        cam.CreateHorizontalApertureAttr(ha)
        cam.CreateVerticalApertureAttr(va)
    if ho or vo:
        cam.CreateHorizontalApertureOffsetAttr(ho)
        cam.CreateVerticalApertureOffsetAttr(vo)
    cam.CreateProjectionAttr("perspective")
    cam.CreateClippingRangeAttr(Gf.Vec2f(0.05, 100))


def settings(path, camera, resolution, policy=None, products=None):
    s = UsdRender.Settings.Define(stage, path)
    if camera:
        s.CreateCameraRel().SetTargets([camera])
    if resolution:
        s.CreateResolutionAttr(Gf.Vec2i(*resolution))
    if policy:
        s.CreateAspectRatioConformPolicyAttr(policy)
    if products:
        s.CreateProductsRel().SetTargets(products)
    return s


rig = UsdGeom.Xform.Define(stage, "/rig")
rig.AddTranslateOp().Set(Gf.Vec3d(0.5, -1.0, 0.2))
rig.AddRotateZXYOp().Set(Gf.Vec3f(10, 20, 30))
rig.AddScaleOp().Set(Gf.Vec3f(2, 2, 2))
front = UsdGeom.Camera.Define(stage, "/rig/front")
front.AddTranslateOp().Set(Gf.Vec3d(-0.3, 1.8, 0.45))
front.AddRotateXOp().Set(-10.0)
front.AddRotateZOp().Set(-8.0)
film(front, 35.0, 36.0, 20.25, 1.8, -1.08)
settings("/Render/front", "/rig/front", (W, H))

orbit = UsdGeom.Xform.Define(stage, "/orbit")
orbit.AddTranslateOp().Set(Gf.Vec3d(3.0, 0.8, 3.5))
pivot = orbit.AddTranslateOp(opSuffix="pivot")
pivot.Set(Gf.Vec3d(0.2, -0.1, 0.3))
orbit.AddOrientOp().Set(Gf.Quatf(Gf.Rotation(Gf.Vec3d(0.2, 1, 0.1), 42).GetQuat()))
orbit.AddTranslateOp(opSuffix="pivot", isInverseOp=True)
film(UsdGeom.Camera.Define(stage, "/orbit/orbitShape"), 24.0, None, None)
product = UsdRender.Product.Define(stage, "/Render/orbitProduct")
product.CreateCameraRel().SetTargets(["/orbit/orbitShape"])
settings("/Render/orbitSettings", None, (W, H), products=["/Render/orbitProduct"])

world = UsdGeom.Xform.Define(stage, "/world")
world.AddTranslateOp().Set(Gf.Vec3d(10, 20, 30))
world.AddScaleOp().Set(Gf.Vec3f(3, 3, 3))
matrixcam = UsdGeom.Camera.Define(stage, "/world/cams/matrixcam")
UsdGeom.Xform.Define(stage, "/world/cams")
matrixcam.SetResetXformStack(True)
m = Gf.Matrix4d().SetRotate(Gf.Rotation(Gf.Vec3d(1, 0.3, -0.2), -25)) * Gf.Matrix4d().SetTranslate(
    Gf.Vec3d(-0.4, 1.5, 4.0))
matrixcam.AddTransformOp().Set(m)
film(matrixcam, 30.0, 24.0, 24.0, -0.6, 0.9)
settings("/Render/matrix", "/world/cams/matrixcam", (W, H), policy="cropAperture")

tumble = UsdGeom.Camera.Define(stage, "/tumble")
op = tumble.AddTransformOp()
for f, axis, angle, eye in [(1, (0.3, 1, 0.1), -35, (-2.5, 0.5, 3.0)), (5, (1, 0.4, -0.3), 30, (-1.5, 2.2, 3.4))]:
    op.Set(Gf.Matrix4d().SetRotate(Gf.Rotation(Gf.Vec3d(*axis), angle)) * Gf.Matrix4d().SetTranslate(
        Gf.Vec3d(*eye)), f)
film(tumble, 20.0, 36.0, 20.25)
settings("/Render/tumble", "/tumble", (W, H))

moving = UsdGeom.Camera.Define(stage, "/moving")
t = moving.AddTranslateOp()
for f, p in [(1, (-3.0, 1.5, 3.0)), (3, (-2.0, 1.0, 3.6)), (5, (-0.8, 2.0, 3.9))]:
    t.Set(Gf.Vec3d(*p), f)
o = moving.AddOrientOp()
o.Set(Gf.Quatf(Gf.Rotation(Gf.Vec3d(0, 1, 0), -40).GetQuat()), 1)
o.Set(Gf.Quatf((Gf.Rotation(Gf.Vec3d(0, 1, 0), -10) * Gf.Rotation(Gf.Vec3d(1, 0, 0), -20)).GetQuat()), 5)
moving.AddRotateYOp().Set(5.0)
film(moving, 28.0, 36.0, 20.25)
settings("/Render/moving", "/moving", (W, H))

# Not cameras on the stage.
stage.CreateClassPrim("/_template")
UsdGeom.Camera.Define(stage, "/_template/cam")
Sdf.CreatePrimInLayer(stage.GetRootLayer(), "/ghost/cam").typeName = "Camera"
off = UsdGeom.Camera.Define(stage, "/off")
off.GetPrim().SetActive(False)
props = UsdGeom.Xform.Define(stage, "/props")
props.GetPrim().SetCustomData({"source": "modelflow fixture", "version": 2})
props.GetPrim().SetDocumentation("props: a mesh, a variant set, a reference")
mesh = UsdGeom.Mesh.Define(stage, "/props/tri")
mesh.CreatePointsAttr([(0, 0, 0), (1, 0, 0), (0, 1, 0)])
mesh.CreateFaceVertexCountsAttr([3])
mesh.CreateFaceVertexIndicesAttr([0, 1, 2])
UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                         UsdGeom.Tokens.faceVarying).Set([(0, 0), (1, 0), (0, 1)])
vs = props.GetPrim().GetVariantSets().AddVariantSet("look")
for v in ("plain", "shiny"):
    vs.AddVariant(v)
vs.SetVariantSelection("shiny")
with vs.GetVariantEditContext():
    stage.DefinePrim("/props/shine", "Sphere")
vs.SetVariantSelection("plain")
copy = stage.DefinePrim("/props/copy", "Xform")
copy.GetReferences().AddInternalReference("/props/tri")
stage.GetRootLayer().Save()

points = [(0.0, 0.0, 0.0), (0.3, -0.2, 0.5), (-0.4, 0.1, 0.2), (0.2, 0.4, -0.1),
          (-0.25, -0.3, 0.7), (0.45, 0.05, 0.35)]
policies = {"front": None, "orbit": "expandAperture", "matrixcam": "cropAperture", "moving": None,
            "tumble": None}
paths = {"front": "/rig/front", "orbit": "/orbit/orbitShape", "matrixcam": "/world/cams/matrixcam",
         "moving": "/moving", "tumble": "/tumble"}
expected = {"width": W, "height": H, "points": [list(p) for p in points], "views": []}
stage = Usd.Stage.Open("fixtures/usd/cameras.usda")
for frame in range(1, 6):
    for name, path in paths.items():
        cam = UsdGeom.Camera(stage.GetPrimAtPath(path)).GetCamera(Usd.TimeCode(frame))
        ha, va = cam.horizontalAperture, cam.verticalAperture
        aspect = W / H
        if abs((ha / va) / aspect - 1) > 0.02:
            widen = ha / va < aspect if policies[name] == "expandAperture" else ha / va > aspect
            if widen:
                cam.horizontalAperture = va * aspect
            else:
                cam.verticalAperture = ha / aspect
        fr = cam.frustum
        view, proj = fr.ComputeViewMatrix(), fr.ComputeProjectionMatrix()
        pixels = []
        for p in points:
            q = view.Transform(Gf.Vec3d(*p))
            assert q[2] < 0, (name, frame)
            n = proj.Transform(q)
            pixels.append([(n[0] + 1) / 2 * W - 0.5, (1 - n[1]) / 2 * H - 0.5])
        expected["views"].append({"camera": name, "frame": frame, "pixels": pixels})
with open("fixtures/usd/cameras-expected.json", "w") as f:
    json.dump(expected, f, indent=1)
    f.write("\n")
print("wrote fixtures/usd/cameras.usda and cameras-expected.json")
