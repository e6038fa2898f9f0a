# Writes fixtures/alembic/trs.abc and trs-expected.json: cameras whose transforms are Alembic's
# translate / rotate / scale operations (as Maya's AbcExport writes them; Blender's exporter
# writes one matrix), the file laid out here by hand in Alembic's Ogawa layout, then read by
# Blender's importer, that is by the Alembic library itself, which composes the operations; the
# expected pixels are where Blender then puts six points (what `modelflow import alembic` must
# agree with). Two cameras, 1280x720:
#   /rig (translate, rotateY) / trs_camShape under trs_cam: translate, rotate about an axis,
#       rotateX, rotateY, rotateZ, scale (uniform), then the film back with Maya's four film-back
#       operations, each doing nothing (Blender's importer, that is the Alembic library, reads
#       them; film-translate.abc is the same with the film translated);
#   /rig / world_cam: `.inherits` false (its transform is in the world, not the rig's): translate,
#       rotateY, rotateX, rotateZ.
#   target/bpyenv/bin/python tools/make_alembic_trs_fixture.py   (from the repository root; bpy 5.0)
import hashlib
import json
import math
import struct

import bpy
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Vector

DATA = 1 << 63


class Ogawa:
    def __init__(self):
        self.b = bytearray(b"Ogawa\xff\x00\x01" + b"\x00" * 8)

    def data(self, payload):
        if not payload:
            return DATA
        at = len(self.b)
        self.b += struct.pack("<Q", len(payload)) + payload
        return at | DATA

    def group(self, children):
        if not children:
            return 0
        at = len(self.b)
        self.b += struct.pack("<Q", len(children)) + b"".join(struct.pack("<Q", c) for c in children)
        return at

    def finish(self, root):
        self.b[8:16] = struct.pack("<Q", root)
        return bytes(self.b)


def sample(o, values):
    return o.data(hashlib.sha256(values).digest()[:16] + values)


def header(name, meta, kind, pod=0, extent=0, samples=0, sampling=0):
    """Alembic's property header, sizes in one byte (hint 0)."""
    info = kind | (pod << 4) | (extent << 12)
    if meta:
        info |= 0xFF << 20
    if kind:
        info |= 0x800 if samples <= 1 else 0
        info |= 0x100 if sampling else 0
    out = struct.pack("<I", info)
    if kind:
        out += bytes([samples]) + (bytes([sampling]) if sampling else b"")
    out += bytes([len(name)]) + name.encode()
    if meta:
        out += bytes([len(meta)]) + meta.encode()
    return out


def compound(o, props):
    return o.group([g for g, _ in props] + [o.data(b"".join(h for _, h in props))])


def scalar(o, name, pod, fmt, values, sampling=1):
    v = struct.pack("<" + fmt * len(values), *values)
    return (o.group([sample(o, v)]), header(name, "", 1, pod, len(values), 1, sampling))


def obj(o, props, children):
    h = b""
    for name, meta, _ in children:
        h += struct.pack("<I", len(name)) + name.encode() + b"\xff"
        h += struct.pack("<I", len(meta)) + meta.encode()
    h += b"\x00" * 32
    return o.group([props] + [c for _, _, c in children] + [o.data(h)])


XFORM = "schema=AbcGeom_Xform_v3;schemaObjTitle=AbcGeom_Xform_v3:.xform"
CAMERA = "schema=AbcGeom_Camera_v1;schemaObjTitle=AbcGeom_Camera_v1:.geom"


def xform(o, ops, vals, inherits=True):
    """An Xform's properties: ops as (type << 4) codes, their channels' values."""
    props = [
        scalar(o, ".inherits", 0, "B", [1 if inherits else 0]),
        scalar(o, ".ops", 1, "B", ops, sampling=0),
        scalar(o, ".vals", 11, "d", vals),
        scalar(o, "isNotConstantIdentity", 0, "B", [1], sampling=0),
    ]
    inner = compound(o, props)
    return compound(o, [(inner, header(".xform", "schema=AbcGeom_Xform_v3", 0))])


def strings(o, name, values):
    """A string array property of one sample: the strings, each ending in a NUL, and their
    count as the sample's dimensions."""
    payload = b"".join(v.encode() + b"\x00" for v in values)
    dims = o.data(struct.pack("<Q", len(values)))
    return (o.group([sample(o, payload), dims]), header(name, "", 2, 12, 1, 1, 1))


def camera(o, focal, hoff, voff, film_back=None):
    """A Camera's properties; `film_back`: (op names, channels), as Maya writes them."""
    core = [focal, 3.6, hoff, 2.025, voff, 1.0, 0, 0, 0, 0, 5.6, 5.0, 0, 1 / 48, 0.05, 100.0]
    props = [scalar(o, ".core", 11, "d", core)]
    if film_back:
        names, channels = film_back
        props += [strings(o, ".filmBackOps", names),
                  scalar(o, ".filmBackChannels", 11, "d", channels)]
    inner = compound(o, props)
    return compound(o, [(inner, header(".geom", "schema=AbcGeom_Camera_v1", 0))])


MAYA_OPS = ["tfilmFitOffs", "spreScale", "tfilmTranslate", "spostScale"]


def write(path, translate):
    """The two cameras; trs_cam's film back carries Maya's four film-back operations, its film
    translated by `translate`."""
    o = Ogawa()
    T, R, S, RX, RY, RZ = 0x10, 0x20, 0x00, 0x40, 0x50, 0x60
    shape = obj(o, camera(o, 35.0, 0.12, -0.09,
                          (MAYA_OPS, [0.0, 0.0, 1.0, 1.0, *translate, 1.0, 1.0])), [])
    trs = obj(o, xform(o, [T, R, RX, RY, RZ, S],
                       [0.4, 0.3, 5.5, 0.3, 1.0, 0.2, 8.0, -5.0, 4.0, 15.0, 1.5, 1.5, 1.5]),
              [("trs_camShape", CAMERA, shape)])
    shape2 = obj(o, camera(o, 28.0, -0.05, 0.07), [])
    world = obj(o, xform(o, [T, RY, RX, RZ], [-4.5, 1.2, 2.0, -66.0, -13.7, 8.0], inherits=False),
                [("world_camShape", CAMERA, shape2)])
    rig = obj(o, xform(o, [T, RY], [0.5, -0.3, 0.2, 30.0]),
              [("trs_cam", XFORM, trs), ("world_cam", XFORM, world)])
    top = obj(o, o.group([]), [("rig", XFORM, rig)])
    # Time samplings: the identity, then 24 fps from frame 1; no indexed metadata.
    times = struct.pack("<IdId", 1, 1.0, 1, 0.0) + struct.pack("<IdId", 1, 1 / 24, 1, 1 / 24)
    root = o.group([o.data(struct.pack("<i", 0)), o.data(struct.pack("<i", 10805)), top,
                    o.data(b""), o.data(times), o.data(b"")])
    with open(path, "wb") as f:
        f.write(o.finish(root))


write("fixtures/alembic/trs.abc", [0.0, 0.0])
# The same with the film translated (Maya's film translate): refused, the screen window moved.
write("fixtures/alembic/film-translate.abc", [0.05, -0.02])

bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
scene.render.resolution_x, scene.render.resolution_y = 1280, 720
bpy.ops.wm.alembic_import(filepath="fixtures/alembic/trs.abc")
scene.frame_set(1)
bpy.context.view_layer.update()
# Points in the file's world (Y up); Blender's importer turns it Z up: (x, y, z) -> (x, -z, y).
points = [(0.0, 0.0, 0.0), (0.3, 0.5, 0.2), (-0.4, 0.2, -0.1), (0.2, -0.1, 0.4),
          (-0.25, 0.7, 0.3), (0.45, 0.35, -0.05)]
expected = {"width": 1280, "height": 720, "points": points, "views": []}
for cam in sorted((c for c in scene.objects if c.type == "CAMERA"), key=lambda c: c.name):
    pixels = []
    for x, y, z in points:
        n = world_to_camera_view(scene, cam, Vector((x, -z, y)))
        assert n.z > 0, (cam.name, n)
        pixels.append([n.x * 1280 - 0.5, (1.0 - n.y) * 720 - 0.5])
    expected["views"].append({"camera": cam.name, "pixels": pixels})
    print(cam.name, cam.parent.name if cam.parent else None, pixels[0])
with open("fixtures/alembic/trs-expected.json", "w") as f:
    json.dump(expected, f, indent=1)
    f.write("\n")
print("wrote fixtures/alembic/trs.abc and trs-expected.json")
