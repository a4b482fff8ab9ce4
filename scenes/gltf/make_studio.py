#!/usr/bin/env python3
"""Writes studio.gltf: a small room laid out as Blender's glTF exporter lays a scene out.

A collection node holds the room, a table, two chairs that share one mesh and one material
(instancing), an emissive ceiling panel (KHR_materials_emissive_strength), a point light
(KHR_lights_punctual, on a node of its own) and a perspective camera turned by a quaternion.
Nodes use translation/rotation/scale except the table, which uses a matrix. Run it from any
folder; it writes next to itself.
"""
import math
import os

from gltf_doc import GltfDoc

g = GltfDoc("penumbra scenes/gltf/make_studio.py", "Scene",
            ["KHR_lights_punctual", "KHR_materials_emissive_strength"])
doc = g.doc
doc["extensions"] = {"KHR_lights_punctual": {"lights": []}}
mesh, node = g.mesh, g.node


def material(name, colour, emissive=None, strength=None):
    return g.material(name, colour, 0.8, emissive, strength)


def box(sx, sy, sz, inward=False):
    """An axis-aligned box centred at the origin; faces outward (or inward, for a room)."""
    x, y, z = sx / 2, sy / 2, sz / 2
    faces = [
        [(-x, -y, -z), (x, -y, -z), (x, -y, z), (-x, -y, z)],  # bottom, facing -y
        [(-x, y, -z), (-x, y, z), (x, y, z), (x, y, -z)],      # top, +y
        [(-x, -y, -z), (-x, y, -z), (x, y, -z), (x, -y, -z)],  # back, -z
        [(-x, -y, z), (x, -y, z), (x, y, z), (-x, y, z)],      # front, +z
        [(-x, -y, -z), (-x, -y, z), (-x, y, z), (-x, y, -z)],  # left, -x
        [(x, -y, -z), (x, y, -z), (x, y, z), (x, -y, z)],      # right, +x
    ]
    return [list(reversed(f)) for f in faces] if inward else faces


def quaternion_y(deg):
    h = math.radians(deg) / 2
    return [0.0, math.sin(h), 0.0, math.cos(h)]


plaster = material("Plaster", [0.75, 0.73, 0.70])
wood = material("Wood", [0.55, 0.35, 0.20])
fabric = material("Fabric", [0.20, 0.30, 0.55])
panel_light = material("PanelLight", [0.0, 0.0, 0.0], [1.0, 0.95, 0.85], 6.0)

collection = node(name="Collection", children=[])
doc["scenes"][0]["nodes"].append(collection)
children = doc["nodes"][collection]["children"]
# The room: 5 x 2.8 x 4 m, floor at y = 0.
children.append(node(name="Room", mesh=mesh("Room", box(5.0, 2.8, 4.0, inward=True), plaster),
                     translation=[0.0, 1.4, 0.0]))
# The table: a top and a pedestal, placed by a matrix (column-major), turned 30 degrees.
c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
table = mesh("Table", box(1.4, 0.06, 0.8) +
             [[(p[0], p[1] - 0.38, p[2]) for p in f] for f in box(0.2, 0.7, 0.2)], wood)
children.append(node(name="Table", mesh=table,
                     matrix=[c, 0, -s, 0, 0, 1, 0, 0, s, 0, c, 0, 0.3, 0.75, -0.4, 1]))
# Two chairs sharing one mesh and one material, each turned with a quaternion.
chair = mesh("Chair", box(0.45, 0.45, 0.45) +
             [[(p[0], p[1] + 0.45, p[2] - 0.2) for p in f] for f in box(0.45, 0.5, 0.05)], fabric)
children.append(node(name="Chair", mesh=chair, translation=[-0.6, 0.225, 0.3],
                     rotation=quaternion_y(200)))
children.append(node(name="Chair.001", mesh=chair, translation=[1.1, 0.225, -0.9],
                     rotation=quaternion_y(-40)))
# A 0.8 x 0.8 m emissive panel 2 mm below the ceiling, facing down.
children.append(node(name="Panel", mesh=mesh("Panel", [[(-0.4, 0, -0.4), (0.4, 0, -0.4),
                                                        (0.4, 0, 0.4), (-0.4, 0, 0.4)]],
                                             panel_light),
                     translation=[0.0, 2.798, 0.0]))
# A point light over the table: a 50 W Blender light, which Blender's exporter writes as
# 50 / 4π W/sr × 683 lm/W candela.
doc["extensions"]["KHR_lights_punctual"]["lights"].append(
    {"name": "Bulb", "type": "point", "color": [1.0, 0.85, 0.7],
     "intensity": round(50.0 / (4 * math.pi) * 683, 3)})
children.append(node(name="Bulb", translation=[1.6, 1.9, 1.2],
                     extensions={"KHR_lights_punctual": {"light": 0}}))
# The camera in a corner looking at the table: turned 35 degrees about +y, then down.
doc["cameras"].append({"name": "Camera", "type": "perspective",
                       "perspective": {"yfov": 0.9, "znear": 0.05, "aspectRatio": 1.5}})
yaw, pitch = math.radians(35) / 2, math.radians(-18) / 2
qy = [0.0, math.sin(yaw), 0.0, math.cos(yaw)]
qx = [math.sin(pitch), 0.0, 0.0, math.cos(pitch)]
q = [qy[3] * qx[0] + qy[0] * qx[3] + qy[1] * qx[2] - qy[2] * qx[1],
     qy[3] * qx[1] - qy[0] * qx[2] + qy[1] * qx[3] + qy[2] * qx[0],
     qy[3] * qx[2] + qy[0] * qx[1] - qy[1] * qx[0] + qy[2] * qx[3],
     qy[3] * qx[3] - qy[0] * qx[0] - qy[1] * qx[1] - qy[2] * qx[2]]
children.append(node(name="Camera", camera=0, translation=[2.1, 1.7, 1.8], rotation=q))

g.write(os.path.join(os.path.dirname(os.path.abspath(__file__)), "studio.gltf"))
