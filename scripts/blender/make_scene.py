"""Builds a small lit room in Blender as a designer would and exports it with Blender's own
glTF and OBJ exporters (issue 28's test data: scenes/gltf/blender-room.*, scenes/obj/).

    blender -b --factory-startup -noaudio --python-exit-code 1 \
        --python scripts/blender/make_scene.py -- GLTF_DIR [OBJ_DIR]

Writes GLTF_DIR/blender-room.gltf (+ blender-room.bin), GLTF_DIR/blender-room.glb and
OBJ_DIR/blender-room.obj (+ .mtl); OBJ_DIR defaults to GLTF_DIR. Units are metres. Blender
is Z-up; both exporters turn it to glTF's/OBJ's Y-up: Blender (x, y, z) -> file (x, z, -y).

The scene (Blender coordinates; the tests in tests/edit/scene_import_test.cpp restate these
numbers and compute the expected file values from them independently):

- Walls: a 1 m cube scaled (4, 4, 3) at (0, 0, 1.5), bottom face deleted, normals flipped
  inward; scale left unapplied, so the node carries it. Material Plaster.
- Floor: a 4 m plane at the origin, normal +Z. Material Floor.
- BoxA, BoxB: 1 m cubes (scaled, unapplied) sharing the material Wood.
- Shelf: an empty at (0.9, -0.7, 0), turned 30 deg about Z, scaled 1.25, parent of
- Crate: a 1 m cube (vertices +-0.5) at local (0.2, 0.1, 0.4), Euler XYZ (15, 0, 40) deg,
  scale (0.6, 0.4, 0.5); its top face Wood, the rest Crate (two materials, two primitives).
- Panel: a 1 m plane scaled (1.0, 0.6, 1) at (0, 0, 2.98), turned 180 deg about X so it faces
  down; material PanelLight: black base colour, Emission (1.0, 0.9, 0.75), strength 8.
- Bulb: a 25 W point light, colour (1.0, 0.8, 0.6), at (-1.3, -1.2, 2.2).
- Camera: at (1.7, -1.7, 1.6) looking at (0, 0, 0.8), 24 mm lens on the 36 mm sensor,
  render 640 x 480 (yfov = 2 atan(0.75 / (4/3))).
"""
import math
import os
import sys

import bmesh
import bpy
from mathutils import Euler, Vector


def arguments():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    if not argv or len(argv) > 2:
        raise SystemExit("usage: blender -b --python make_scene.py -- GLTF_DIR [OBJ_DIR]")
    gltf_dir = os.path.abspath(argv[0])
    obj_dir = os.path.abspath(argv[1]) if len(argv) > 1 else gltf_dir
    return gltf_dir, obj_dir


def empty_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.unit_settings.system = "METRIC"
    scene.unit_settings.scale_length = 1.0
    scene.render.resolution_x = 640
    scene.render.resolution_y = 480
    return scene


def material(name, colour, emission=None, strength=0.0):
    """A Principled BSDF material: base colour, and emission colour x strength if given."""
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    bsdf = m.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*colour, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.8
    if emission is not None:
        bsdf.inputs["Emission"].default_value = (*emission, 1.0)
        bsdf.inputs["Emission Strength"].default_value = strength
    return m


def add_cube(name, location, scale, mat):
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=location)
    obj = bpy.context.active_object
    obj.name = name
    obj.data.name = name  # the OBJ exporter then writes "o NAME", not "NAME_Cube.001"
    obj.scale = scale
    obj.data.materials.append(mat)
    return obj


def add_plane(name, size, location, mat):
    bpy.ops.mesh.primitive_plane_add(size=size, location=location)
    obj = bpy.context.active_object
    obj.name = name
    obj.data.name = name
    obj.data.materials.append(mat)
    return obj


def edit_faces(obj, change):
    """Runs change(bm) on the object's mesh as an edit-mode operation would."""
    bm = bmesh.new()
    bm.from_mesh(obj.data)
    bm.faces.ensure_lookup_table()
    change(bm)
    bm.to_mesh(obj.data)
    bm.free()
    obj.data.update()


def build(scene):
    plaster = material("Plaster", (0.75, 0.75, 0.72))
    floor = material("Floor", (0.6, 0.55, 0.5))
    wood = material("Wood", (0.45, 0.3, 0.18))
    crate = material("Crate", (0.2, 0.35, 0.6))
    panel_light = material("PanelLight", (0.0, 0.0, 0.0), (1.0, 0.9, 0.75), 8.0)

    # The walls and ceiling: a box without its bottom, seen from inside.
    walls = add_cube("Walls", (0.0, 0.0, 1.5), (4.0, 4.0, 3.0), plaster)

    def open_and_turn_inward(bm):
        bottom = [f for f in bm.faces if f.normal.z < -0.5]
        bmesh.ops.delete(bm, geom=bottom, context="FACES")
        bmesh.ops.reverse_faces(bm, faces=bm.faces[:])
    edit_faces(walls, open_and_turn_inward)

    add_plane("Floor", 4.0, (0.0, 0.0, 0.0), floor)

    # Two boxes of one material: a low table and a stool beside it.
    add_cube("BoxA", (-0.8, 0.6, 0.35), (0.7, 0.5, 0.7), wood)
    add_cube("BoxB", (-0.2, 1.1, 0.25), (0.5, 0.5, 0.5), wood)

    # A crate on a turned, scaled shelf empty: the node hierarchy carries the transforms.
    bpy.ops.object.empty_add(type="PLAIN_AXES", location=(0.9, -0.7, 0.0))
    shelf = bpy.context.active_object
    shelf.name = "Shelf"
    shelf.rotation_euler = Euler((0.0, 0.0, math.radians(30.0)), "XYZ")
    shelf.scale = (1.25, 1.25, 1.25)
    box = add_cube("Crate", (0.0, 0.0, 0.0), (0.6, 0.4, 0.5), crate)
    box.data.materials.append(wood)

    def wood_top(bm):
        for f in bm.faces:
            f.material_index = 1 if f.normal.z > 0.5 else 0
    edit_faces(box, wood_top)
    box.parent = shelf  # parent inverse stays identity: world = shelf @ crate's own TRS
    box.location = (0.2, 0.1, 0.4)
    box.rotation_euler = Euler((math.radians(15.0), 0.0, math.radians(40.0)), "XYZ")

    # The ceiling panel faces down.
    panel = add_plane("Panel", 1.0, (0.0, 0.0, 2.98), panel_light)
    panel.scale = (1.0, 0.6, 1.0)
    panel.rotation_euler = Euler((math.radians(180.0), 0.0, 0.0), "XYZ")

    bulb_data = bpy.data.lights.new("Bulb", type="POINT")
    bulb_data.energy = 25.0  # W
    bulb_data.color = (1.0, 0.8, 0.6)
    bulb = bpy.data.objects.new("Bulb", bulb_data)
    bulb.location = (-1.3, -1.2, 2.2)
    scene.collection.objects.link(bulb)

    cam_data = bpy.data.cameras.new("Camera")
    cam_data.lens = 24.0
    cam_data.sensor_width = 36.0
    cam_data.sensor_fit = "AUTO"
    camera = bpy.data.objects.new("Camera", cam_data)
    camera.location = (1.7, -1.7, 1.6)
    direction = Vector((0.0, 0.0, 0.8)) - camera.location
    camera.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(camera)
    scene.camera = camera


def export(gltf_dir, obj_dir):
    os.makedirs(gltf_dir, exist_ok=True)
    os.makedirs(obj_dir, exist_ok=True)
    common = dict(export_yup=True, export_apply=False, export_lights=True, export_cameras=True,
                  export_extras=True, use_selection=False)
    bpy.ops.export_scene.gltf(filepath=os.path.join(gltf_dir, "blender-room.gltf"),
                              export_format="GLTF_SEPARATE", **common)
    bpy.ops.export_scene.gltf(filepath=os.path.join(gltf_dir, "blender-room.glb"),
                              export_format="GLB", **common)
    bpy.ops.export_scene.obj(filepath=os.path.join(obj_dir, "blender-room.obj"),
                             use_selection=False, use_materials=True, use_triangles=False,
                             use_normals=True, use_uvs=True, use_mesh_modifiers=True,
                             axis_forward="-Z", axis_up="Y", global_scale=1.0,
                             path_mode="AUTO")


def main():
    gltf_dir, obj_dir = arguments()
    scene = empty_scene()
    build(scene)
    bpy.context.view_layer.update()
    export(gltf_dir, obj_dir)
    crate = bpy.data.objects["Crate"]
    corner = crate.matrix_world @ Vector((0.5, 0.5, 0.5))
    print("make_scene: wrote %s and %s; Crate corner (0.5, 0.5, 0.5) in Blender world: "
          "(%.6f, %.6f, %.6f)" % (gltf_dir, obj_dir, *corner))


main()
