# Writes fixtures/gltf/: the Blender hard sample's first mesh (an irregular closed surface, 565
# vertices) as Blender's own glTF exporter writes it, after Blender has given it what an artist's
# mesh has: UV islands (Smart UV Project: seams everywhere), flat shading on part of it (split
# normals), and a place in the scene through a parent's transform (turned, scaled unevenly and
# mirrored, moved) and its own (turned). Blender's exporter then splits the vertices at every seam and hard
# edge and writes the transforms as glTF nodes. Beside it, `expected.obj`: the same mesh as
# Blender's OBJ exporter writes it in world coordinates, +Y up as glTF's (forward -Z, up Y), with
# its UVs: what modelflow must read the .glb as (tests/mesh_formats.rs).
#   target/bpyenv/bin/python tools/make_gltf_fixture.py      (from the repository root; bpy 5.0)
import bpy
import math

bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.wm.obj_import(filepath="fixtures/blender-hard-sample-frame0/mesh/initial.obj",
                      forward_axis="NEGATIVE_Z", up_axis="Y")
obj = bpy.context.selected_objects[0]
obj.name = "surface"
bpy.context.view_layer.objects.active = obj
bpy.ops.object.mode_set(mode="EDIT")
bpy.ops.mesh.select_all(action="SELECT")
bpy.ops.uv.smart_project(angle_limit=math.radians(50), island_margin=0.02)
bpy.ops.object.mode_set(mode="OBJECT")
# Flat shading on the faces of one side (hard edges at its border), smooth elsewhere.
for p in obj.data.polygons:
    p.use_smooth = p.center.x < 0.02
parent = bpy.data.objects.new("rig", None)
bpy.context.scene.collection.objects.link(parent)
parent.location = (0.3, -1.2, 0.5)
parent.rotation_euler = (0.2, -0.5, 0.9)
parent.scale = (1.5, 0.8, -1.1)
obj.parent = parent
obj.rotation_euler = (0.0, 0.0, 0.4)
bpy.context.view_layer.update()
bpy.ops.export_scene.gltf(filepath="fixtures/gltf/surface.glb", export_format="GLB",
                          export_yup=True, export_apply=False, export_materials="NONE",
                          export_animations=False)
bpy.ops.object.select_all(action="DESELECT")
obj.select_set(True)
bpy.ops.wm.obj_export(filepath="fixtures/gltf/expected.obj", export_selected_objects=True,
                      forward_axis="NEGATIVE_Z", up_axis="Y", export_uv=True,
                      export_normals=False, export_materials=False, apply_modifiers=False)
print("wrote fixtures/gltf/surface.glb and expected.obj:", len(obj.data.vertices), "vertices,",
      len(obj.data.polygons), "faces")
