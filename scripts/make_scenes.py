#!/usr/bin/env python3
"""Writes Penumbra's sample scenes (scenes/*.json, format penumbra-scene/1, see DESIGN.md).

    python3 scripts/make_scenes.py            # writes every scene
    python3 scripts/make_scenes.py cube-room  # writes only the named ones

Deterministic: no randomness, fixed float formatting, so re-running it reproduces the
committed files byte for byte. Standard library only.

Conventions used throughout:
- Surfaces are one-sided. Rooms are built from inward-facing quads (a quad's front is +Y
  before rotation): floor as is, ceiling rotate_deg [180,0,0], the wall at -z [90,0,0], at
  +z [-90,0,0], at +x [0,0,90], at -x [0,0,-90] (as tests/test_scenes.h addClosedRoom).
  Furniture is boxes (outward normals), seen from outside.
- Lamps are quads just below the ceiling, rotated [180,0,0] so they face down.
- Meshes come from Debian's libcgal-demo data set, extracted into scenes/meshes/cgal/ by
  scripts/setup.sh (see scenes/meshes/README.md). MESHES below records each file's
  object-space bounding box (measured from the .off files) so a mesh can be scaled, turned
  upright and set on the floor without loading it here.

Patch and element counts each scene was sized for, and what
`penumbra solve SCENE --max-shots 0 --report R.json` measured, are in the docstrings of
the builders below; re-measure after changing a scene or the discretization rules.
"""

import json
import math
import os
import sys

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
SCENES = os.path.join(ROOT, "scenes")

# ---------------------------------------------------------------------------------------------
# Meshes: file -> (bbox min, bbox max, up axis in the file). Up "y" needs no rotation, "z" is
# turned upright with rotate_deg [-90, 0, 0] (z -> y, y -> -z).

MESHES = {
    "cow": ((-0.5, -0.306, -0.163), (0.5, 0.306, 0.163), "y"),            # 5,804 faces, length x
    "elephant": ((-0.36, -0.5, -0.301), (0.36, 0.5, 0.301), "y"),         # 5,558 faces, rearing
    "bull": ((-0.5, -0.341, -0.401), (0.5, 0.341, 0.401), "y"),           # 12,396 faces, length x
    "dino": ((-1.002, -1.159, -2.045), (0.992, 2.545, 2.018), "z"),       # 7,828 faces, stands on -z
    "camel": ((-0.153, -0.489, -0.5), (0.153, 0.489, 0.5), "y"),          # 19,536 faces, length z
    "elk": ((-51.446, -80.733, -101.538), (99.227, 78.894, 54.849), "y"),  # 3,290 faces, abstract
    "armadillo": ((-63.5, -54.202, -57.704), (63.518, 97.108, 57.719), "y"),  # 52,000 faces
    "ChineseDragon-10kv": ((-34.433, -52.697, -1036.631), (27.165, 60.191, -927.312), "y"),  # 19,994
    "bunny00": ((-0.499, -0.493, -0.386), (0.499, 0.494, 0.386), "y"),    # 75,408 faces
}


def num(x):
    """Short, stable decimal text for a coordinate."""
    x = round(float(x), 4)
    if x == 0:
        return "0"
    if x == int(x):
        return str(int(x))
    return repr(x)


def vec(v):
    return "[" + ", ".join(num(c) for c in v) + "]"


# ---------------------------------------------------------------------------------------------
# Objects


def transform(translate=None, rotate=None, scale=None):
    t = {}
    if translate is not None:
        t["translate"] = list(translate)
    if rotate is not None and any(r != 0 for r in rotate):
        t["rotate_deg"] = list(rotate)
    if scale is not None:
        t["scale"] = list(scale)
    return t


def obj(oid, shape, material, translate=None, rotate=None, scale=None):
    o = {"id": oid, "shape": shape, "material": material}
    t = transform(translate, rotate, scale)
    if t:
        o["transform"] = t
    return o


def quad(oid, sx, sz, material, translate, rotate=None):
    return obj(oid, {"type": "quad", "size": [sx, sz]}, material, translate, rotate)


def box(oid, size, material, centre, rotate_y=0.0):
    return obj(oid, {"type": "box", "size": list(size)}, material, centre, [0, rotate_y, 0])


def box_on(oid, size, material, x, y0, z, rotate_y=0.0):
    """A box whose bottom face is at height y0."""
    return box(oid, size, material, (x, y0 + size[1] / 2, z), rotate_y)


def cylinder(oid, radius, height, material, centre, segments=None, rotate=None):
    s = {"type": "cylinder", "radius": radius, "height": height}
    if segments:
        s["segments"] = segments
    return obj(oid, s, material, centre, rotate)


def sphere(oid, radius, material, centre, segments=None):
    s = {"type": "sphere", "radius": radius}
    if segments:
        s["segments"] = segments
    return obj(oid, s, material, centre)


def mesh(oid, name, material, size, x, z, floor_y=0.0, rotate_y=0.0, along="height"):
    """A CGAL mesh scaled uniformly so its height (or its longest horizontal extent when
    along="length") is `size`, turned upright, centred on (x, z), bottom on floor_y."""
    lo, hi, up = MESHES[name]
    ext = [hi[k] - lo[k] for k in range(3)]
    if up == "y":
        height, horiz = ext[1], max(ext[0], ext[2])
        cx, cz, bottom = (lo[0] + hi[0]) / 2, (lo[2] + hi[2]) / 2, lo[1]
        rot = [0, rotate_y, 0]
    else:  # z up: rotate X -90 maps (x, y, z) -> (x, z, -y)
        height, horiz = ext[2], max(ext[0], ext[1])
        cx, cz, bottom = (lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, lo[2]
        rot = [-90, rotate_y, 0]
    s = size / (height if along == "height" else horiz)
    # Centre offset after scaling and the Y rotation (rotation about Y happens after X).
    a = math.radians(rotate_y)
    ox, oz = s * cx, s * cz
    rx = ox * math.cos(a) + oz * math.sin(a)
    rz = -ox * math.sin(a) + oz * math.cos(a)
    t = [round(x - rx, 4), round(floor_y - s * bottom, 4), round(z - rz, 4)]
    return obj(oid, {"type": "mesh", "file": "meshes/cgal/" + name + ".off"}, material, t, rot,
               [round(s, 6)] * 3)


def room(prefix, w, d, h, materials, centre=(0.0, 0.0), open_front=False):
    """Inward-facing quads for a room x in centre.x ± w/2, z in centre.z ± d/2, y in [0, h].
    materials: dict with keys floor, ceiling, back, front, left, right."""
    cx, cz = centre
    out = [
        quad(prefix + "floor", w, d, materials["floor"], (cx, 0, cz)),
        quad(prefix + "ceiling", w, d, materials["ceiling"], (cx, h, cz), [180, 0, 0]),
        quad(prefix + "back", w, h, materials["back"], (cx, h / 2, cz - d / 2), [90, 0, 0]),
    ]
    if not open_front:
        out.append(quad(prefix + "front", w, h, materials["front"], (cx, h / 2, cz + d / 2),
                        [-90, 0, 0]))
    out += [
        quad(prefix + "left", h, d, materials["left"], (cx - w / 2, h / 2, cz), [0, 0, -90]),
        quad(prefix + "right", h, d, materials["right"], (cx + w / 2, h / 2, cz), [0, 0, 90]),
    ]
    return out


def lamp(oid, sx, sz, material, x, z, ceiling_h, gap=0.01, patch_size=None):
    """A downward-facing quad lamp just below the ceiling; `patch_size` makes it one shooter."""
    obj = quad(oid, sx, sz, material, (x, ceiling_h - gap, z), [180, 0, 0])
    if patch_size:
        obj["patch_size"] = patch_size
    return obj


def camera(position, look_at, fov=45.0, up=(0, 1, 0)):
    return {"position": list(position), "look_at": list(look_at), "up": list(up), "fov_deg": fov}


def scene(settings, materials, objects, cameras):
    return {"format": "penumbra-scene/1", "settings": settings, "materials": materials,
            "objects": objects, "cameras": cameras}


# ---------------------------------------------------------------------------------------------
# JSON text: one material / object / camera per line, numbers via num().


def dump_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return num(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(dump_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(json.dumps(k) + ": " + dump_value(x) for k, x in v.items()) + "}"
    raise TypeError(type(v))


def dump_scene(s):
    lines = ["{", '  "format": ' + json.dumps(s["format"]) + ",",
             '  "settings": ' + dump_value(s["settings"]) + ",", '  "materials": {']
    items = list(s["materials"].items())
    for i, (k, m) in enumerate(items):
        lines.append("    " + json.dumps(k) + ": " + dump_value(m) + ("," if i + 1 < len(items) else ""))
    lines.append("  },")
    lines.append('  "objects": [')
    for i, o in enumerate(s["objects"]):
        lines.append("    " + dump_value(o) + ("," if i + 1 < len(s["objects"]) else ""))
    lines.append("  ],")
    lines.append('  "cameras": {')
    cams = list(s["cameras"].items())
    for i, (k, c) in enumerate(cams):
        lines.append("    " + json.dumps(k) + ": " + dump_value(c) + ("," if i + 1 < len(cams) else ""))
    lines.append("  }")
    lines.append("}")
    text = "\n".join(lines) + "\n"
    json.loads(text)  # must parse
    ids = [o["id"] for o in s["objects"]]
    assert len(ids) == len(set(ids)), "duplicate object id"
    return text


# ---------------------------------------------------------------------------------------------
# Materials

WHITE = {"reflectance": [0.73, 0.73, 0.73]}
RED = {"reflectance": [0.63, 0.065, 0.05]}
GREEN = {"reflectance": [0.14, 0.45, 0.091]}


def lamp_material(emission):
    return {"reflectance": [0.78, 0.78, 0.78], "emission": list(emission)}


# ---------------------------------------------------------------------------------------------
# Scenes


def cornell_box():
    """Cornell-style box, 1.5 m, open front (+z). patch 0.25, element 0.0625 (4×4 elements
    per full patch). Measured: 248 patches, 3,952 elements."""
    S = 1.5
    mats = {"white": WHITE, "red": RED, "green": GREEN, "light": lamp_material([50, 40, 28])}
    objs = room("", S, S, S, {"floor": "white", "ceiling": "white", "back": "white",
                              "front": "white", "left": "red", "right": "green"},
                open_front=True)
    objs += [
        lamp("light", 0.4, 0.3, "light", 0, 0, S, gap=0.005),
        box_on("short-box", (0.42, 0.42, 0.42), "white", 0.3, 0, 0.25, rotate_y=-17),
        box_on("tall-box", (0.42, 0.85, 0.42), "white", -0.28, 0, -0.25, rotate_y=20),
    ]
    cams = {"default": camera((0, S / 2, 3.4), (0, S / 2, 0), fov=36)}
    return scene({"patch_size": 0.25, "element_size": 0.0625}, mats, objs, cams)


def table(prefix, x, z, top=(1.4, 0.05, 0.9), height=0.75, leg=0.06, material="wood",
          leg_material=None):
    """Table: a top box whose upper face is at `height`, four square legs inset 0.06 m."""
    tx, ty, tz = top
    out = [box_on(prefix + "top", top, material, x, height - ty, z)]
    lx, lz = tx / 2 - leg / 2 - 0.06, tz / 2 - leg / 2 - 0.06
    for i, (sx, sz) in enumerate([(-1, -1), (1, -1), (1, 1), (-1, 1)]):
        out.append(box_on(prefix + "leg-%d" % (i + 1), (leg, height - ty, leg),
                          leg_material or material, x + sx * lx, 0, z + sz * lz))
    return out


def cube_room():
    """George et al. 1990 "Cube" scale (≈450 patches, ≈1,750 elements): a closed
    4.5 × 4.5 × 2.8 m room, a table, one lamp. Measured: 450 patches, 1,688 elements.
    The later edit log puts a cube on the table: its top (1.6 × 1.0 m, upper face at
    y = 0.75, centred on (0, -0.2)) is clear."""
    W, D, H = 4.5, 4.5, 2.8
    mats = {
        "wall": {"reflectance": [0.72, 0.7, 0.65]},
        "floor": {"reflectance": [0.45, 0.4, 0.35]},
        "ceiling": {"reflectance": [0.8, 0.8, 0.8]},
        "wood": {"reflectance": [0.55, 0.35, 0.2]},
        "lamp": lamp_material([28, 25, 20]),
    }
    objs = room("", W, D, H, {"floor": "floor", "ceiling": "ceiling", "back": "wall",
                              "front": "wall", "left": "wall", "right": "wall"})
    objs.append(lamp("lamp", 0.7, 0.7, "lamp", 0, 0, H))
    objs += table("table-", 0, -0.2, top=(1.6, 0.05, 1.0), height=0.75)
    cams = {"default": camera((1.5, 1.6, 2.1), (-0.2, 1.15, -0.6), fov=70)}
    return scene({"patch_size": 0.5, "element_size": 0.25}, mats, objs, cams)


def chair(prefix, x, z, facing_deg, material):
    """An office chair from boxes: seat, backrest, column, base. facing_deg: direction the
    sitter faces, as a rotation about Y of -z (0: faces -z, toward the back wall)."""
    a = math.radians(facing_deg)
    # Local +z (behind the sitter) rotated by facing_deg about Y.
    bx, bz = math.sin(a), math.cos(a)
    return [
        box_on(prefix + "base", (0.55, 0.05, 0.55), material, x, 0.02, z, facing_deg + 45),
        box_on(prefix + "column", (0.06, 0.38, 0.06), material, x, 0.07, z, facing_deg),
        box_on(prefix + "seat", (0.48, 0.07, 0.46), material, x, 0.45, z, facing_deg),
        box_on(prefix + "back", (0.46, 0.5, 0.06), material, x + 0.22 * bx, 0.55, z + 0.22 * bz,
               facing_deg),
    ]


def cubicles():
    """Cohen et al. 1988's two office cubicles, at their scale (≈500 patches, ≈7,000
    elements): a 6.4 × 4.6 × 2.7 m office, two cubicles along the back wall with 1.5 m
    partitions, a desk with a side return, a monitor, a file cabinet and a chair in each, and
    four ceiling lamps. Measured: 482 patches, 6,898 elements."""
    W, D, H = 6.4, 4.6, 2.7
    mats = {
        "wall": {"reflectance": [0.75, 0.74, 0.7]},
        "carpet": {"reflectance": [0.25, 0.27, 0.32]},
        "ceiling": {"reflectance": [0.82, 0.82, 0.82]},
        "partition": {"reflectance": [0.45, 0.5, 0.6]},
        "desk": {"reflectance": [0.6, 0.48, 0.33]},
        "chair": {"reflectance": [0.15, 0.15, 0.17]},
        "metal": {"reflectance": [0.55, 0.56, 0.58]},
        "screen": {"reflectance": [0.08, 0.08, 0.09]},
        "lamp": lamp_material([22, 21, 18]),
    }
    objs = room("", W, D, H, {"floor": "carpet", "ceiling": "ceiling", "back": "wall",
                              "front": "wall", "left": "wall", "right": "wall"})
    back = -D / 2
    depth = 2.3      # cubicle depth from the back wall
    t = 0.06         # partition thickness
    ph = 1.5         # partition height
    cw = 2.6         # cubicle width
    xs = [-cw / 2 - 0.05, cw / 2 + 0.05]  # cubicle centres
    zc = back + depth / 2
    # Partitions: outer sides, shared middle, front returns with a 0.9 m opening.
    objs += [
        box_on("partition-left", (t, ph, depth), "partition", xs[0] - cw / 2, 0, zc),
        box_on("partition-middle", (t, ph, depth), "partition", 0, 0, zc),
        box_on("partition-right", (t, ph, depth), "partition", xs[1] + cw / 2, 0, zc),
    ]
    for i, x in enumerate(xs):
        n = str(i + 1)
        ret = cw - 0.9  # front return partition length, opening at the room's centre line
        rx = x - cw / 2 + ret / 2 if i == 0 else x + cw / 2 - ret / 2
        objs.append(box_on("partition-front-" + n, (ret, ph, t), "partition", rx, 0,
                           back + depth))
        # Desk against the back wall: top on two side panels; a return along the outer side.
        dx0 = x - 0.1 if i == 0 else x + 0.1
        objs += [
            box_on("desk-" + n + "-top", (1.8, 0.04, 0.75), "desk", dx0, 0.7, back + 0.4),
            box_on("desk-" + n + "-panel-a", (0.04, 0.7, 0.7), "desk", dx0 - 0.86, 0, back + 0.4),
            box_on("desk-" + n + "-panel-b", (0.04, 0.7, 0.7), "desk", dx0 + 0.86, 0, back + 0.4),
        ]
        side = -1 if i == 0 else 1
        objs.append(box_on("desk-" + n + "-return", (0.6, 0.04, 1.1), "desk",
                           x + side * (cw / 2 - 0.35), 0.7, back + 0.75 + 0.55))
        objs.append(box_on("cabinet-" + n, (0.45, 0.65, 0.55), "metal",
                           x + side * (cw / 2 - 0.3), 0, back + 0.75 + 0.85))
        objs.append(box_on("monitor-" + n, (0.55, 0.36, 0.05), "screen", dx0, 0.86, back + 0.3))
        objs.append(box_on("monitor-" + n + "-stand", (0.2, 0.12, 0.15), "metal", dx0, 0.74,
                           back + 0.3))
        objs += chair("chair-" + n + "-", dx0 + side * -0.15, back + 1.15, side * -20, "chair")
    for i, (lx, lz) in enumerate([(-1.6, -0.9), (1.6, -0.9), (-1.6, 1.2), (1.6, 1.2)]):
        objs.append(lamp("lamp-%d" % (i + 1), 1.2, 0.3, "lamp", lx, lz, H))
    cams = {"default": camera((0.4, 2.5, 2.2), (0, 0.45, -1.3), fov=68)}
    return scene({"patch_size": 0.8, "element_size": 0.19}, mats, objs, cams)


def robot(material_body="robot-metal", material_trim="robot-trim", x=0.0, z=0.0, turn=0.0):
    """A robot in the spirit of George et al. 1990 Figure 7, from primitives. Objects:
    robot-body (torso box), robot-head (sphere), robot-base (cylinder), robot-arm-left,
    robot-arm-right (cylinders), robot-eye (sphere)."""
    a = math.radians(turn)

    def at(dx, dz):
        return x + dx * math.cos(a) + dz * math.sin(a), z - dx * math.sin(a) + dz * math.cos(a)

    out = []
    bx, bz = at(0, 0)
    out.append(cylinder("robot-base", 0.3, 0.5, material_trim, (bx, 0.25, bz), segments=48))
    out.append(box("robot-body", (0.6, 0.75, 0.4), material_body, (bx, 0.5 + 0.375, bz), turn))
    out.append(sphere("robot-head", 0.2, material_body, (bx, 1.25 + 0.2, bz), segments=48))
    for side, name in [(-1, "left"), (1, "right")]:
        ax, az = at(side * 0.39, 0)
        out.append(cylinder("robot-arm-" + name, 0.07, 0.7, material_trim, (ax, 0.95, az),
                            segments=32))
    ex, ez = at(0, 0.17)
    out.append(sphere("robot-eye", 0.05, "robot-eye", (ex, 1.5, ez), segments=24))
    return out


def robot_room_objects(with_robot):
    """Room for the robot: 5.2 × 4.4 × 2.4 m, three lamps, four CGAL animals (cow, bull,
    elephant, dino) standing on the floor along the walls, the robot in the middle."""
    W, D, H = 5.2, 4.4, 2.4
    objs = room("", W, D, H, {"floor": "floor", "ceiling": "ceiling", "back": "wall",
                              "front": "wall", "left": "wall-accent", "right": "wall"})
    objs += [
        # Each lamp is one shooter (its elements stay 0.1 m): a light's redistribution after
        # an edit is then one deterministic shot, as in George et al.
        lamp("lamp-1", 0.8, 0.6, "lamp", -1.2, -0.6, H, patch_size=1.0),
        lamp("lamp-2", 0.8, 0.6, "lamp", 1.2, -0.6, H, patch_size=1.0),
        lamp("lamp-3", 0.8, 0.6, "lamp", 0, 1.3, H, patch_size=1.0),
    ]
    objs += [
        mesh("cow", "cow", "hide", 1.6, -1.55, -1.5, rotate_y=20, along="length"),
        mesh("bull", "bull", "bull", 1.5, 1.6, -1.4, rotate_y=-25, along="length"),
        mesh("elephant", "elephant", "elephant", 1.4, -1.95, -0.2, rotate_y=70),
        mesh("dino", "dino", "dino", 1.7, 1.75, -0.2, rotate_y=-110),
    ]
    if with_robot:
        objs += robot(x=0.0, z=-0.3, turn=0)
    return objs


def robot_room_materials():
    return {
        "wall": {"reflectance": [0.7, 0.7, 0.68]},
        "wall-accent": {"reflectance": [0.35, 0.45, 0.65]},
        "floor": {"reflectance": [0.5, 0.42, 0.33]},
        "ceiling": {"reflectance": [0.8, 0.8, 0.8]},
        "hide": {"reflectance": [0.6, 0.55, 0.5]},
        "bull": {"reflectance": [0.35, 0.22, 0.15]},
        "elephant": {"reflectance": [0.5, 0.5, 0.52]},
        "dino": {"reflectance": [0.3, 0.55, 0.3]},
        "robot-metal": {"reflectance": [0.65, 0.66, 0.7]},
        "robot-trim": {"reflectance": [0.7, 0.35, 0.1]},
        "robot-eye": {"reflectance": [0.1, 0.3, 0.8]},
        "lamp": lamp_material([20, 18, 14]),
    }


ROBOT_ROOM_SETTINGS = {"patch_size": 0.1, "element_size": 0.1}
ROBOT_ROOM_CAMERA = camera((0, 1.7, 2.15), (0, 0.65, -0.5), fov=80)


def robot_room():
    """George et al. 1990 Figure 7 scale (≈12,700 patches, ≈46,000 elements). Patches are
    0.1 m and primitives have one element per patch; the meshes' triangles are the fine
    elements (≈33k) grouped into ≈3k patches; the robot's spheres and cylinders are gridded
    finer by their segment counts. Measured: 12,926 patches, 46,082 elements (without
    the robot: 12,320 and 42,873)."""
    return scene(ROBOT_ROOM_SETTINGS, robot_room_materials(), robot_room_objects(True),
                 {"default": ROBOT_ROOM_CAMERA})


def robot_room_empty():
    """robot-room.json without the robot-* objects (the edit log adds the robot)."""
    # The robot's materials stay: the edit log's "add" lines refer to them by name.
    return scene(ROBOT_ROOM_SETTINGS, robot_room_materials(), robot_room_objects(False),
                 {"default": ROBOT_ROOM_CAMERA})


def large():
    """Scaling scene (≥ 200,000 elements): a 30 × 20 × 6 m hall, a grid of pillars, rows of
    crates, a few CGAL meshes on plinths, eight ceiling lamps. patch 0.5, element 0.1.
    Measured: 12,088 patches, 270,154 elements; loads in about a second."""
    W, D, H = 30.0, 20.0, 6.0
    mats = {
        "wall": {"reflectance": [0.7, 0.68, 0.64]},
        "floor": {"reflectance": [0.4, 0.4, 0.42]},
        "ceiling": {"reflectance": [0.75, 0.75, 0.75]},
        "pillar": {"reflectance": [0.6, 0.58, 0.55]},
        "crate": {"reflectance": [0.55, 0.4, 0.25]},
        "plinth": {"reflectance": [0.8, 0.8, 0.8]},
        "statue": {"reflectance": [0.62, 0.6, 0.58]},
        "lamp": lamp_material([30, 28, 24]),
    }
    objs = room("", W, D, H, {"floor": "floor", "ceiling": "ceiling", "back": "wall",
                              "front": "wall", "left": "wall", "right": "wall"})
    for i, lx in enumerate([-11.25, -3.75, 3.75, 11.25]):
        for j, lz in enumerate([-5.0, 5.0]):
            objs.append(lamp("lamp-%d-%d" % (i + 1, j + 1), 2.0, 1.0, "lamp", lx, lz, H))
    for i, px in enumerate([-10.0, -5.0, 0.0, 5.0, 10.0]):
        for j, pz in enumerate([-6.0, 6.0]):
            objs.append(box_on("pillar-%d-%d" % (i + 1, j + 1), (0.6, H, 0.6), "pillar", px, 0, pz))
    k = 0
    for row, cz in enumerate([-8.0, 8.0]):
        for c in range(8):
            k += 1
            cx = -12.25 + 3.5 * c
            s = 0.8 + 0.1 * ((c + row) % 3)
            objs.append(box_on("crate-%d" % k, (s, s, s), "crate", cx, 0, cz, rotate_y=(15 * c) % 45))
    statues = [("bull", 1.8, "length", -7.5), ("camel", 2.2, "height", -2.5),
               ("ChineseDragon-10kv", 1.8, "height", 2.5), ("elephant", 1.8, "height", 7.5)]
    for i, (name, size, along, x) in enumerate(statues):
        sid = name.split("-")[0].lower()
        z = 1.5 if i % 2 == 0 else -1.5
        objs.append(box_on("plinth-" + sid, (2.0, 0.4, 2.0), "plinth", x, 0, z))
        objs.append(mesh("statue-" + sid, name, "statue", size, x, z, floor_y=0.4, along=along,
                         rotate_y=30))
    cams = {"default": camera((14.0, 3.6, 3.0), (0, 0.8, -1.0), fov=65)}
    return scene({"patch_size": 0.5, "element_size": 0.1}, mats, objs, cams)


def armadillo_field():
    """Display benchmark scene (Bala et al. 2003 Table 1 "Dragon" scale): 20 armadillos
    (52,000 triangles each, 1.04M in all) on a 5 × 4 grid on a floor, four slats casting a
    shadow pattern, one area lamp. Coarse patches (the solver is not the point here):
    patch 1.0 m, element 0.5 m; the meshes' triangles are the elements."""
    W, D, H = 9.0, 8.0, 3.5
    mats = {
        "floor": {"reflectance": [0.55, 0.5, 0.45]},
        "statue": {"reflectance": [0.6, 0.6, 0.62]},
        "slat": {"reflectance": [0.4, 0.3, 0.25]},
        "lamp": lamp_material([150, 140, 120]),
    }
    objs = [quad("floor", W, D, "floor", (0, 0, 0))]
    objs.append(lamp("lamp", 1.2, 1.2, "lamp", 0.0, 0.0, H, gap=0.0, patch_size=2.0))
    for k, z in enumerate([-0.9, -0.3, 0.3, 0.9]):
        objs.append(box("slat-%d" % (k + 1), (3.0, 0.05, 0.12), "slat", (0.0, 2.6, z)))
    for i in range(5):
        for j in range(4):
            x = -3.0 + 1.5 * i
            z = -2.25 + 1.5 * j
            objs.append(mesh("armadillo-%d-%d" % (i + 1, j + 1), "armadillo", "statue", 1.0, x, z,
                             rotate_y=180 + 15 * ((i + j) % 3)))
    cams = {"default": camera((0.0, 4.2, 7.0), (0, 0.5, 0.0), fov=55)}
    return scene({"patch_size": 1.0, "element_size": 0.5}, mats, objs, cams)


BUILDERS = {
    "cornell-box": cornell_box,
    "cube-room": cube_room,
    "cubicles": cubicles,
    "robot-room": robot_room,
    "robot-room-empty": robot_room_empty,
    "large": large,
    "armadillo-field": armadillo_field,
}


def main(argv):
    names = argv[1:] or list(BUILDERS)
    for n in names:
        if n not in BUILDERS:
            sys.exit("make_scenes: unknown scene '%s' (known: %s)" % (n, ", ".join(BUILDERS)))
        path = os.path.join(SCENES, n + ".json")
        with open(path, "w") as f:
            f.write(dump_scene(BUILDERS[n]()))
        print(os.path.relpath(path, ROOT))


if __name__ == "__main__":
    main(sys.argv)
