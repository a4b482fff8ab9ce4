"""Imports a glTF/GLB file into an empty Blender scene with Blender's own importer and prints
what Blender made of it as one JSON line (issue 24: Penumbra's exports open in Blender).

    blender -b --factory-startup -noaudio --python-exit-code 1 \
        --python scripts/blender/check_import.py -- FILE.gltf|.glb [--ids a,b,c] [--lamps a,b] [--color]

The JSON line starts with "check_import: " and holds:
- "objects": per mesh object its name, vertex count, "color" (a colour attribute from
  COLOR_0, Blender names it "Col"), "radiance" (a `_RADIANCE` attribute kept), its
  materials and its custom properties (node extras, e.g. penumbra_id);
- "materials": per material its emission colour and strength (Principled BSDF, else the
  Emission node Blender builds for an unlit material) and "principled" (false: unlit);
- "cameras", "lights": their names.
With --ids the objects' penumbra_id set must be exactly those ids; with --lamps each named
object must have an emissive Principled BSDF material (emission colour x strength above 0; not
an unlit material's emission shader); with --color every
mesh object must have a colour attribute (Penumbra's exports carry COLOR_0). Exits 1 when the
import raised or was cancelled, or when a check fails (the failures are in "failures").
"""
import json
import sys

import bpy
import numpy

# Blender 3.4.1's glTF importer uses numpy.bool, an alias NumPy 1.24 (Debian 12's) removed; the
# import fails with an AttributeError without it. Restore the alias for the importer.
if "bool" not in vars(numpy):
    numpy.bool = bool


def arguments():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    if not argv:
        raise SystemExit("usage: ... check_import.py -- FILE [--ids a,b] [--lamps a,b] [--color]")
    path, ids, lamps, colour = argv[0], None, None, False
    rest = argv[1:]
    while rest:
        key = rest.pop(0)
        if key == "--color":
            colour = True
        elif key in ("--ids", "--lamps") and rest:
            names = [n for n in rest.pop(0).split(",") if n]
            if key == "--ids":
                ids = names
            else:
                lamps = names
        else:
            raise SystemExit("check_import: unknown argument " + key)
    return path, ids, lamps, colour


def emission_of(material):
    """(colour, strength, has a Principled BSDF) of a node material, as Blender shows it."""
    colour, strength, principled = [0.0, 0.0, 0.0], 0.0, False
    if not material.use_nodes or material.node_tree is None:
        return colour, strength, principled
    for node in material.node_tree.nodes:
        if node.type == "BSDF_PRINCIPLED":
            principled = True
            colour = list(node.inputs["Emission"].default_value)[:3]
            strength = node.inputs["Emission Strength"].default_value
        elif node.type == "EMISSION" and strength == 0.0:
            colour = list(node.inputs["Color"].default_value)[:3]
            strength = node.inputs["Strength"].default_value
    return colour, strength, principled


def custom_properties(idblock):
    out = {}
    for key in idblock.keys():
        value = idblock[key]
        try:
            json.dumps(value)
        except TypeError:
            value = value.to_dict() if hasattr(value, "to_dict") else str(value)
        out[key] = value
    return out


def describe():
    objects, cameras, lights = [], [], []
    for obj in bpy.context.scene.objects:
        if obj.type == "CAMERA":
            cameras.append(obj.name)
        elif obj.type == "LIGHT":
            lights.append(obj.name)
        elif obj.type == "MESH":
            mesh = obj.data
            objects.append({
                "name": obj.name,
                "vertices": len(mesh.vertices),
                "color": [a.name for a in mesh.color_attributes],
                "radiance": "_RADIANCE" in mesh.attributes,
                "attributes": sorted(a.name for a in mesh.attributes),
                "materials": [m.name for m in mesh.materials if m is not None],
                "properties": custom_properties(obj),
            })
    materials = []
    for m in bpy.data.materials:
        colour, strength, principled = emission_of(m)
        materials.append({"name": m.name, "emission": colour, "strength": strength,
                          "principled": principled})
    return {"objects": objects, "materials": materials, "cameras": cameras, "lights": lights}


def check(result, ids, lamps, colour):
    failures = []
    by_id = {o["properties"].get("penumbra_id", o["name"]): o for o in result["objects"]}
    if ids is not None and sorted(by_id) != sorted(ids):
        failures.append("objects %s, expected %s" % (sorted(by_id), sorted(ids)))
    # A lamp's material is a Principled BSDF with emission; Blender makes Penumbra's unlit
    # materials (KHR_materials_unlit) an emission shader of the vertex colour, no Principled.
    emissive = {m["name"] for m in result["materials"]
                if m["principled"] and m["strength"] * max(m["emission"]) > 0}
    for lamp in lamps or []:
        o = by_id.get(lamp)
        if o is None:
            failures.append("lamp %s: no such object" % lamp)
        elif not any(name in emissive for name in o["materials"]):
            failures.append("lamp %s: no emissive material among %s" % (lamp, o["materials"]))
    for o in result["objects"] if colour else []:
        if not o["color"]:
            failures.append("object %s: no colour attribute (COLOR_0)" % o["name"])
    return failures


def main():
    path, ids, lamps, colour = arguments()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    try:
        status = bpy.ops.import_scene.gltf(filepath=path)
    except Exception as error:  # the importer reports its errors as exceptions
        print("check_import: " + json.dumps({"file": path, "error": str(error)}))
        sys.exit(1)
    result = describe()
    result["file"] = path
    result["status"] = sorted(status)
    result["failures"] = check(result, ids, lamps, colour)
    if "FINISHED" not in status:
        result["failures"].append("import status " + ", ".join(sorted(status)))
    print("check_import: " + json.dumps(result))
    sys.exit(1 if result["failures"] else 0)


main()
