"""A minimal glTF 2.0 writer for the example scenes (make_studio.py, make_cornell.py): one
embedded buffer, meshes of quads with one material each, metallic-roughness materials with
optional emission (KHR_materials_emissive_strength)."""
import base64
import json
import struct


class GltfDoc:
    def __init__(self, generator, scene_name, extensions):
        self.buffer = bytearray()
        self.doc = {
            "asset": {"version": "2.0", "generator": generator},
            "extensionsUsed": extensions,
            "scene": 0,
            "scenes": [{"name": scene_name, "nodes": []}],
            "nodes": [], "meshes": [], "materials": [], "accessors": [], "bufferViews": [],
            "cameras": [],
        }

    def view(self, data, target):
        while len(self.buffer) % 4:
            self.buffer.append(0)
        offset = len(self.buffer)
        self.buffer.extend(data)
        self.doc["bufferViews"].append({"buffer": 0, "byteOffset": offset,
                                        "byteLength": len(data), "target": target})
        return len(self.doc["bufferViews"]) - 1

    def mesh(self, name, quads, material):
        """quads: lists of four corners, counter-clockwise seen from the side they face."""
        positions, indices = [], []
        for q in quads:
            base = len(positions)
            positions.extend(q)
            indices.extend([base, base + 1, base + 2, base, base + 2, base + 3])
        lo = [min(p[i] for p in positions) for i in range(3)]
        hi = [max(p[i] for p in positions) for i in range(3)]
        accessors = self.doc["accessors"]
        pv = self.view(b"".join(struct.pack("<3f", *p) for p in positions), 34962)
        accessors.append({"bufferView": pv, "componentType": 5126, "count": len(positions),
                          "type": "VEC3", "min": lo, "max": hi})
        iv = self.view(b"".join(struct.pack("<H", i) for i in indices), 34963)
        accessors.append({"bufferView": iv, "componentType": 5123, "count": len(indices),
                          "type": "SCALAR"})
        self.doc["meshes"].append({"name": name, "primitives": [{
            "attributes": {"POSITION": len(accessors) - 2},
            "indices": len(accessors) - 1, "material": material}]})
        return len(self.doc["meshes"]) - 1

    def material(self, name, colour, roughness, emissive=None, strength=None):
        m = {"name": name, "pbrMetallicRoughness": {"baseColorFactor": colour + [1.0],
                                                    "metallicFactor": 0.0,
                                                    "roughnessFactor": roughness}}
        if emissive:
            m["emissiveFactor"] = emissive
        if strength:
            m["extensions"] = {"KHR_materials_emissive_strength": {"emissiveStrength": strength}}
        self.doc["materials"].append(m)
        return len(self.doc["materials"]) - 1

    def node(self, **fields):
        self.doc["nodes"].append(fields)
        return len(self.doc["nodes"]) - 1

    def write(self, path):
        self.doc["buffers"] = [{"byteLength": len(self.buffer),
                                "uri": "data:application/octet-stream;base64," +
                                       base64.b64encode(bytes(self.buffer)).decode()}]
        with open(path, "w") as f:
            json.dump(self.doc, f, indent=1)
            f.write("\n")
        print(path)
