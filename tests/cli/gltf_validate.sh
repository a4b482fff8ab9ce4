#!/usr/bin/env bash
# Issue 24's validator check: exports the bundled scenes, and a scene with a mesh, a two-sided
# object and an emitter of coloured light, as glTF and GLB (elements, and the high-fidelity
# mesh of issue 23), and runs the Khronos validator
# (tools/gltf-validator, installed by scripts/setup.sh) over every export: no error, no warning.
#
# Usage: gltf_validate.sh PENUMBRA SOURCE_DIR
set -euo pipefail
penumbra=$1
root=$2
validate="$root/tools/gltf-validator/validate.js"
if [ ! -d "$root/tools/gltf-validator/node_modules/gltf-validator" ]; then
  echo "gltf_validate: the validator is not installed (run scripts/setup.sh)" >&2
  exit 1
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

cat > "$tmp/mixed.json" <<SCENE
{
  "format": "penumbra-scene/1",
  "settings": {"patch_size": 0.5, "element_size": 0.25},
  "materials": {
    "floor": {"reflectance": [0.5, 0.45, 0.4]},
    "sheet": {"reflectance": [0.3, 0.6, 0.3], "two_sided": true},
    "hide": {"reflectance": [0.6, 0.55, 0.5]},
    "amber": {"reflectance": [0.5, 0.5, 0.5], "emission": [30, 12, 2]}
  },
  "objects": [
    {"id": "floor", "shape": {"type": "quad", "size": [3, 3]}, "material": "floor"},
    {"id": "sheet", "shape": {"type": "quad", "size": [1, 1]}, "material": "sheet",
     "transform": {"translate": [0.5, 0.6, 0], "rotate_deg": [90, 0, 0]}},
    {"id": "cow", "shape": {"type": "mesh", "file": "$root/scenes/meshes/cgal/cow.off"},
     "material": "hide", "transform": {"translate": [-0.6, 0.49, 0]}},
    {"id": "lamp", "shape": {"type": "quad", "size": [0.5, 0.5]}, "material": "amber",
     "transform": {"translate": [0, 2, 0], "rotate_deg": [180, 0, 0]}}
  ]
}
SCENE

"$penumbra" export "$root/scenes/cornell-box.json" "$tmp/cornell-box.gltf" --converge 1e-2
"$penumbra" export "$root/scenes/cornell-box.json" "$tmp/cornell-box.glb" --converge 1e-2
"$penumbra" export "$root/scenes/cube-room.json" "$tmp/cube-room.glb" --converge 1e-2
"$penumbra" export "$root/scenes/robot-room.json" "$tmp/robot-room.glb" --converge 1e-2
"$penumbra" export "$tmp/mixed.json" "$tmp/mixed.gltf" --converge 1e-2
"$penumbra" export "$tmp/mixed.json" "$tmp/mixed.glb" --converge 1e-2
# The high-fidelity mesh's triangles (issue 23).
"$penumbra" export "$root/scenes/cornell-box.json" "$tmp/cornell-box-hifi.glb" --converge 1e-2 --hifi
"$penumbra" export "$tmp/mixed.json" "$tmp/mixed-hifi.gltf" --converge 1e-2 --hifi
node "$validate" "$tmp"/*.gltf "$tmp"/*.glb
