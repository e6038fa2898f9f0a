# Writes fixtures/alembic/: cameras as Blender's own Alembic exporter writes them, and where
# Blender itself puts known points in their images (what `modelflow import alembic` must agree
# with, tests in crates/modelflow/src/input/calib/alembic.rs); and fixtures/usd/blender.usda, the
# same cameras as Blender's USD exporter writes them, with blender-expected.json (the same
# pixels, the points in Blender's own Z-up world, which its USD export keeps; tests in
# crates/modelflow/src/input/calib/usd.rs). A 1280x720 render and four cameras:
#   front:  a 16:9 film back (36 x 20.25 mm, the image's aspect), lens 35 mm, shifted (0.05, -0.03),
#           under an empty `rig` that is moved, turned and scaled by 2 (a camera's parent is often
#           scaled: Blender views through its axes, not their length);
#   side:   Blender's default film back (36 x 24 mm, aspect 1.5 against the image's 1.78), lens 50,
#           sensor fit AUTO: Blender fits the film's width to the image's (the importer's rule
#           when the aspects differ);
#   tall:   a 16:9 film back, lens 24 mm, shifted (-0.02, 0.04), under an empty turned about two
#           axes;
#   moving: keyed at frames 1, 3 and 5 (position and rotation), lens 28 mm: a pose per frame.
# Alembic is Y-up: Blender's exporter turns its Z-up world, a point (x, y, z) in Blender is
# (x, z, -y) in the file; expected.json gives the points in the file's world.
#   target/bpyenv/bin/python tools/make_alembic_fixture.py      (from the repository root; bpy 5.0)
import bpy
import json
import math
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Vector

bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
scene.render.resolution_x, scene.render.resolution_y = 1280, 720
scene.render.resolution_percentage = 100
scene.render.fps = 24
scene.frame_start, scene.frame_end = 1, 5


def camera(name, lens, sensor, shift=(0.0, 0.0), parent=None):
    data = bpy.data.cameras.new(name)
    data.lens = lens
    data.sensor_width, data.sensor_height = sensor
    data.sensor_fit = "AUTO"
    data.shift_x, data.shift_y = shift
    data.clip_start, data.clip_end = 0.05, 100.0
    obj = bpy.data.objects.new(name, data)
    scene.collection.objects.link(obj)
    if parent is not None:
        obj.parent = parent
    return obj


def empty(name, location, rotation, scale):
    obj = bpy.data.objects.new(name, None)
    scene.collection.objects.link(obj)
    obj.location, obj.rotation_euler, obj.scale = location, rotation, scale
    return obj


def aim(obj, eye, target=(0.0, 0.0, 0.3)):
    """Places obj (unparented) at eye looking at target, +Z up."""
    d = Vector(target) - Vector(eye)
    obj.location = eye
    obj.rotation_euler = d.to_track_quat("-Z", "Y").to_euler()


rig = empty("rig", (0.5, -1.0, 0.2), (0.1, 0.0, 0.3), (2.0, 2.0, 2.0))
front = camera("front", 35.0, (36.0, 20.25), (0.05, -0.03), rig)
# In the rig's frame (scaled by 2): 2.4 world units back along -Y, looking at the origin.
front.location = (-0.3, -1.8, 0.45)
front.rotation_euler = (math.radians(80), 0.0, math.radians(-8))
side = camera("side", 50.0, (36.0, 24.0))
aim(side, (4.5, 1.0, 1.2))
tilt = empty("tilt", (0.0, 0.0, 0.0), (0.0, math.radians(15), math.radians(120)), (1.0, 1.0, 1.0))
tall = camera("tall", 24.0, (36.0, 20.25), (-0.02, 0.04), tilt)
tall.location = (0.0, -4.0, 1.0)
tall.rotation_euler = (math.radians(78), 0.0, 0.0)
moving = camera("moving", 28.0, (36.0, 20.25))
for frame, eye in [(1, (-3.0, -3.0, 1.5)), (3, (-2.0, -3.6, 1.0)), (5, (-0.8, -3.9, 2.0))]:
    aim(moving, eye)
    moving.keyframe_insert("location", frame=frame)
    moving.keyframe_insert("rotation_euler", frame=frame)

points = [Vector(p) for p in [(0.0, 0.0, 0.0), (0.3, -0.2, 0.5), (-0.4, 0.1, 0.2),
                              (0.2, 0.4, -0.1), (-0.25, -0.3, 0.7), (0.45, 0.05, 0.35)]]
width, height = scene.render.resolution_x, scene.render.resolution_y
expected = {"width": width, "height": height, "fps": 24,
            "points": [[p.x, p.z, -p.y] for p in points], "views": []}
for frame in range(1, 6):
    scene.frame_set(frame)
    for cam in (front, side, tall, moving):
        pixels = []
        for p in points:
            n = world_to_camera_view(scene, cam, p)
            assert n.z > 0
            # Blender's view coordinates run from the frame's bottom-left corner (0, 0) to its
            # top-right corner (1, 1); our pixel centres are at integers, y down.
            pixels.append([n.x * width - 0.5, (1.0 - n.y) * height - 0.5])
        expected["views"].append({"camera": cam.name, "frame": frame, "pixels": pixels})

bpy.ops.wm.alembic_export(filepath="fixtures/alembic/cameras.abc", start=1, end=5,
                          selected=False, flatten=False)
with open("fixtures/alembic/expected.json", "w") as f:
    json.dump(expected, f, indent=1)
    f.write("\n")
print("wrote fixtures/alembic/cameras.abc and expected.json")

bpy.ops.wm.usd_export(filepath="fixtures/usd/blender.usda", export_animation=True,
                      selected_objects_only=False, export_cameras=True)
expected["points"] = [[p.x, p.y, p.z] for p in points]
with open("fixtures/usd/blender-expected.json", "w") as f:
    json.dump(expected, f, indent=1)
    f.write("\n")
print("wrote fixtures/usd/blender.usda and blender-expected.json")
