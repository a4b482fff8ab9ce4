"""Builds a furnished living room in Blender as a designer leaves it (boxes that interpenetrate,
a tessellated monkey head, thin legs and poles, panel lamps under the ceiling) and exports it
with Blender's own glTF exporter (issue 46's test scene: scenes/gltf/furnished-room.glb).

    blender -b --factory-startup -noaudio --python-exit-code 1 \
        --python scripts/blender/make_furnished_room.py -- GLTF_DIR

Writes GLTF_DIR/furnished-room.glb. Units are metres. Blender is Z-up; the exporter turns it
to glTF's Y-up: Blender (x, y, z) -> file (x, z, -y). Every material but Plaster keeps
Blender's default (Backface Culling off), so the exporter marks it doubleSided; Plaster has
Backface Culling ticked, as a designer ticks it to see into the room from outside in the
viewport, so the walls and ceiling are one-sided. Modifiers are applied, scales are not (nodes
carry them).

The scene (Blender coordinates, centre and full size of each box; 20 mesh objects):

- Walls: a 1 m cube scaled (5, 4, 2.7) at (0, 0, 1.35), bottom face deleted, normals flipped
  inward (four walls and the ceiling, seen from inside). Material Plaster (0.8, 0.78, 0.74),
  Backface Culling on.
- Floor: a plane 5 x 4 at the origin, normal +Z. Material Oak (0.45, 0.3, 0.17).
- LampLeft, LampRight: planes 1.2 x 0.6 at (-1.2, 0, 2.68) and (1.2, 0, 2.68), turned 180 deg
  about X to face down (2 cm under the ceiling). Material PanelLight: black base colour,
  Emission (1.0, 0.92, 0.8), strength 12.
- The sofa against the back wall (+y), four boxes of material Fabric (0.25, 0.32, 0.45), each
  reaching into its neighbours as boxes modelled one by one do:
  SofaSeat (-0.9, 1.45, 0.22) size (2.0, 0.9, 0.44); SofaBack (-0.9, 1.82, 0.5) size
  (2.0, 0.24, 0.9) (through the seat's back 0.1 m); SofaArmLeft (-1.9, 1.45, 0.32) and
  SofaArmRight (0.1, 1.45, 0.32), size (0.22, 0.96, 0.64) (through both ends of seat and back).
- The table: TableTop (0.4, 0.1, 0.74) size (1.2, 0.7, 0.04), material Walnut
  (0.3, 0.18, 0.1); TableLeg1-4 size (0.04, 0.04, 0.74) at z 0.37 at x = 0.4 +- 0.54,
  y = 0.1 +- 0.29 (up into the top by 0.02), material Steel (0.2, 0.2, 0.22).
- Suzanne: Blender's monkey (size 0.4), one level of Catmull-Clark subdivision applied, flat
  shaded, at (0.4, 0.1, 0.92) turned -30 deg about Z (its chin sinks into the table top).
  Material Terracotta (0.7, 0.3, 0.18).
- The floor lamp in the right back corner: LampPole, a cylinder of 12 sides, radius 0.015,
  height 1.6, at (2.0, 1.4, 0.8), material Steel; LampShade, an open cone (no caps) of 24
  sides, radius 0.26 at the bottom and 0.16 at the top, height 0.3, at (2.0, 1.4, 1.5) (the
  pole runs through it), material Linen (0.85, 0.8, 0.68).
- The shelf on the left wall (-x): ShelfBoard (-2.37, -0.6, 1.4) size (0.3, 1.2, 0.03)
  (into the wall by 0.02), material Painted (0.85, 0.85, 0.85); on it ShelfBoxRed
  (-2.36, -0.98, 1.5) size (0.22, 0.26, 0.2), ShelfBoxBlue (-2.38, -0.6, 1.53) size
  (0.2, 0.2, 0.26) and ShelfBoxYellow (-2.36, -0.22, 1.48) size (0.24, 0.3, 0.16), their
  bottoms 1 cm into the board. Materials Red (0.6, 0.1, 0.08), Blue (0.1, 0.2, 0.55),
  Yellow (0.75, 0.6, 0.1).
- Camera: at (2.2, -1.85, 1.65) looking at (0.0, 0.8, 0.75), 20 mm lens on the 36 mm sensor,
  render 512 x 512.
"""
import math
import os
import sys

import bmesh
import bpy
from mathutils import Euler, Vector


def arguments():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    if len(argv) != 1:
        raise SystemExit("usage: blender -b --python make_furnished_room.py -- GLTF_DIR")
    return os.path.abspath(argv[0])


def empty_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.unit_settings.system = "METRIC"
    scene.unit_settings.scale_length = 1.0
    scene.render.resolution_x = 512
    scene.render.resolution_y = 512
    return scene


def material(name, colour, emission=None, strength=0.0, backface_culling=False):
    """A Principled BSDF material: base colour, and emission colour x strength if given."""
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    m.use_backface_culling = backface_culling
    bsdf = m.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*colour, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.8
    if emission is not None:
        bsdf.inputs["Emission"].default_value = (*emission, 1.0)
        bsdf.inputs["Emission Strength"].default_value = strength
    return m


def name_object(obj, name, mat):
    obj.name = name
    obj.data.name = name
    obj.data.materials.append(mat)
    return obj


def add_box(name, centre, size, mat):
    """A 1 m cube scaled to `size` (scale left on the node) at `centre`."""
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=centre)
    obj = name_object(bpy.context.active_object, name, mat)
    obj.scale = size
    return obj


def add_plane(name, size, location, mat):
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=location)
    obj = name_object(bpy.context.active_object, name, mat)
    obj.scale = (size[0], size[1], 1.0)
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


def build_room(mats):
    walls = add_box("Walls", (0.0, 0.0, 1.35), (5.0, 4.0, 2.7), mats["Plaster"])

    def open_and_turn_inward(bm):
        bottom = [f for f in bm.faces if f.normal.z < -0.5]
        bmesh.ops.delete(bm, geom=bottom, context="FACES")
        bmesh.ops.reverse_faces(bm, faces=bm.faces[:])
    edit_faces(walls, open_and_turn_inward)

    add_plane("Floor", (5.0, 4.0), (0.0, 0.0, 0.0), mats["Oak"])
    for name, x in (("LampLeft", -1.2), ("LampRight", 1.2)):
        lamp = add_plane(name, (1.2, 0.6), (x, 0.0, 2.68), mats["PanelLight"])
        lamp.rotation_euler = Euler((math.radians(180.0), 0.0, 0.0), "XYZ")


def build_sofa(mats):
    fabric = mats["Fabric"]
    add_box("SofaSeat", (-0.9, 1.45, 0.22), (2.0, 0.9, 0.44), fabric)
    add_box("SofaBack", (-0.9, 1.82, 0.5), (2.0, 0.24, 0.9), fabric)
    add_box("SofaArmLeft", (-1.9, 1.45, 0.32), (0.22, 0.96, 0.64), fabric)
    add_box("SofaArmRight", (0.1, 1.45, 0.32), (0.22, 0.96, 0.64), fabric)


def build_table(mats):
    add_box("TableTop", (0.4, 0.1, 0.74), (1.2, 0.7, 0.04), mats["Walnut"])
    k = 1
    for dx in (-0.54, 0.54):
        for dy in (-0.29, 0.29):
            add_box("TableLeg%d" % k, (0.4 + dx, 0.1 + dy, 0.37), (0.04, 0.04, 0.74),
                    mats["Steel"])
            k += 1
    bpy.ops.mesh.primitive_monkey_add(size=0.4, location=(0.4, 0.1, 0.92))
    monkey = name_object(bpy.context.active_object, "Suzanne", mats["Terracotta"])
    monkey.rotation_euler = Euler((0.0, 0.0, math.radians(-30.0)), "XYZ")
    subdivision = monkey.modifiers.new("Subdivision", "SUBSURF")
    subdivision.levels = 1
    subdivision.render_levels = 1
    bpy.ops.object.modifier_apply(modifier=subdivision.name)
    bpy.ops.object.shade_flat()


def build_floor_lamp(mats):
    bpy.ops.mesh.primitive_cylinder_add(vertices=12, radius=0.015, depth=1.6,
                                        location=(2.0, 1.4, 0.8))
    name_object(bpy.context.active_object, "LampPole", mats["Steel"])
    bpy.ops.mesh.primitive_cone_add(vertices=24, radius1=0.26, radius2=0.16, depth=0.3,
                                    end_fill_type="NOTHING", location=(2.0, 1.4, 1.5))
    name_object(bpy.context.active_object, "LampShade", mats["Linen"])


def build_shelf(mats):
    add_box("ShelfBoard", (-2.37, -0.6, 1.4), (0.3, 1.2, 0.03), mats["Painted"])
    add_box("ShelfBoxRed", (-2.36, -0.98, 1.5), (0.22, 0.26, 0.2), mats["Red"])
    add_box("ShelfBoxBlue", (-2.38, -0.6, 1.53), (0.2, 0.2, 0.26), mats["Blue"])
    add_box("ShelfBoxYellow", (-2.36, -0.22, 1.48), (0.24, 0.3, 0.16), mats["Yellow"])


def add_camera(scene):
    cam_data = bpy.data.cameras.new("Camera")
    cam_data.lens = 20.0
    cam_data.sensor_width = 36.0
    cam_data.sensor_fit = "AUTO"
    camera = bpy.data.objects.new("Camera", cam_data)
    camera.location = (2.2, -1.85, 1.65)
    direction = Vector((0.0, 0.8, 0.75)) - camera.location
    camera.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(camera)
    scene.camera = camera


def build(scene):
    mats = {
        "Plaster": material("Plaster", (0.8, 0.78, 0.74), backface_culling=True),
        "Oak": material("Oak", (0.45, 0.3, 0.17)),
        "PanelLight": material("PanelLight", (0.0, 0.0, 0.0), (1.0, 0.92, 0.8), 12.0),
        "Fabric": material("Fabric", (0.25, 0.32, 0.45)),
        "Walnut": material("Walnut", (0.3, 0.18, 0.1)),
        "Steel": material("Steel", (0.2, 0.2, 0.22)),
        "Terracotta": material("Terracotta", (0.7, 0.3, 0.18)),
        "Linen": material("Linen", (0.85, 0.8, 0.68)),
        "Painted": material("Painted", (0.85, 0.85, 0.85)),
        "Red": material("Red", (0.6, 0.1, 0.08)),
        "Blue": material("Blue", (0.1, 0.2, 0.55)),
        "Yellow": material("Yellow", (0.75, 0.6, 0.1)),
    }
    build_room(mats)
    build_sofa(mats)
    build_table(mats)
    build_floor_lamp(mats)
    build_shelf(mats)
    add_camera(scene)


def export(gltf_dir):
    os.makedirs(gltf_dir, exist_ok=True)
    bpy.ops.export_scene.gltf(filepath=os.path.join(gltf_dir, "furnished-room.glb"),
                              export_format="GLB", export_yup=True, export_apply=True,
                              export_lights=True, export_cameras=True, export_extras=True,
                              use_selection=False)


def main():
    gltf_dir = arguments()
    scene = empty_scene()
    build(scene)
    bpy.context.view_layer.update()
    export(gltf_dir)
    meshes = [o for o in scene.objects if o.type == "MESH"]
    faces = sum(len(o.data.polygons) for o in meshes)
    print("make_furnished_room: wrote %s: %d mesh objects, %d faces"
          % (os.path.join(gltf_dir, "furnished-room.glb"), len(meshes), faces))


main()
