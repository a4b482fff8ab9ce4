#!/usr/bin/env bash
# Real-Blender check for issues 24 and 28 (manual, not in CI: Blender is large). See
# docs/import.md, "Checking with Blender".
#
# (a) Exports every bundled scene (scenes/*.json) as .gltf and .glb and imports each with
#     Blender's own glTF importer (scripts/blender/check_import.py): no import error, one mesh
#     object per scene object (by its penumbra_id), every lamp with an emissive material, every
#     object with its COLOR_0 colour attribute.
# (b) Builds the room of scripts/blender/make_scene.py in Blender, exports it with Blender's
#     glTF (.gltf + .bin, .glb) and OBJ (+ .mtl) exporters, and solves, probes (the floor under
#     the ceiling panel) and renders each export with Penumbra; says whether the files are the
#     ones committed in scenes/gltf and scenes/obj.
#
# Usage: scripts/blender_check.sh [BUILD_DIR]   (default build/; built with scripts/build.sh
#        when it has no penumbra). Installs Debian's blender (3.4.1) and python3-numpy when
#        missing (root or sudo). Exit 1 on any failure.
set -uo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
build=${1:-build}
penumbra="$build/penumbra"

SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO=sudo; fi
if ! command -v blender >/dev/null || ! python3 -c 'import numpy' 2>/dev/null &&
   ! dpkg -s python3-numpy >/dev/null 2>&1; then
  echo "blender_check: installing blender and python3-numpy (Debian packages)"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends \
    blender python3-numpy >/dev/null || { echo "blender_check: apt-get failed" >&2; exit 1; }
fi
if [ ! -x "$penumbra" ]; then
  echo "blender_check: building penumbra into $build"
  bash scripts/build.sh "$build" || exit 1
fi

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }
blender_run() {  # blender_run SCRIPT LOG -- ARGS...
  local script=$1 log=$2
  shift 3
  blender -b --factory-startup -noaudio --python-exit-code 1 \
    --python "$root/scripts/blender/$script" -- "$@" >"$log" 2>&1
}
echo "blender_check: $(blender --version 2>/dev/null | head -1), penumbra $penumbra"

# (a) Penumbra's exports in Blender's importer.
echo
echo "== (a) bundled scenes exported by Penumbra, imported by Blender"
for scene in scenes/*.json; do
  name=$(basename "$scene" .json)
  ids=$(jq -r '[.objects[].id] | join(",")' "$scene")
  lamps=$(jq -r '.materials as $m | [.objects[] | select(($m[.material].emission // [0]) | add > 0)
                 | .id] | join(",")' "$scene")
  for ext in gltf glb; do
    out="$tmp/$name.$ext"
    if ! timeout 900 "$penumbra" export "$scene" "$out" --converge 1e-2 \
         >"$tmp/export.log" 2>&1; then
      fail "$name.$ext: penumbra export: $(tail -1 "$tmp/export.log")"
      continue
    fi
    log="$tmp/$name.$ext.log"
    blender_run check_import.py "$log" -- "$out" --ids "$ids" --lamps "$lamps" --color
    status=$?
    json=$(grep '^check_import: ' "$log" | sed 's/^check_import: //')
    warnings=$(grep -ciE '^(warning|WARNING)|\| WARNING' "$log")
    if [ -z "$json" ]; then
      fail "$name.$ext: Blender printed no result (exit $status): $(tail -3 "$log")"
      continue
    fi
    echo "$json" | jq -r --arg f "$name.$ext" --arg kb "$(( $(stat -c %s "$out") / 1024 ))" \
      --arg w "$warnings" '"\($f) (\($kb) KB): \(.objects | length) objects, \(.materials | length) materials, \(.cameras | length) cameras; COLOR_0 on \([.objects[] | select(.color | length > 0)] | length), _RADIANCE kept on \([.objects[] | select(.radiance)] | length); unlit materials \([.materials[] | select(.principled | not)] | length), lamp materials \([.materials[] | select(.principled and .strength * (.emission | max) > 0) | "\(.name) (strength \(.strength * 100 | round / 100))"] | join(", ")); penumbra_id on \([.objects[] | select(.properties.penumbra_id)] | length); importer warning lines \($w)"'
    if [ "$status" != 0 ]; then
      fail "$name.$ext: $(echo "$json" | jq -c '.failures // .error')"
    fi
  done
done

# (b) A room made in Blender, exported by Blender, opened by Penumbra.
echo
echo "== (b) scripts/blender/make_scene.py: Blender's exports opened by Penumbra"
if ! blender_run make_scene.py "$tmp/make.log" -- "$tmp/gltf" "$tmp/obj"; then
  fail "make_scene.py: $(tail -5 "$tmp/make.log")"
else
  grep '^make_scene:' "$tmp/make.log"
  for f in gltf/blender-room.gltf gltf/blender-room.bin gltf/blender-room.glb \
           obj/blender-room.obj obj/blender-room.mtl; do
    if cmp -s "$tmp/$f" "scenes/$f"; then
      echo "scenes/$f: the same as Blender writes now"
    else
      echo "scenes/$f: differs from what Blender writes now (rerun make_scene.py to update)"
    fi
  done
  # The floor 1 mm above the floor, under the panel's centre, and in a corner.
  printf '0 0.001 0 0 1 0\n1.8 0.001 1.8 0 1 0\n' >"$tmp/points.txt"
  for f in gltf/blender-room.gltf gltf/blender-room.glb obj/blender-room.obj; do
    file="$tmp/$f"
    if ! "$penumbra" solve "$file" --report "$tmp/report.json" >"$tmp/solve.log" 2>&1; then
      fail "$f: penumbra solve: $(tail -1 "$tmp/solve.log")"
      continue
    fi
    jq -r --arg f "$f" '"\($f): solve: \(.shots) shots, unshot \(.unshot_fraction), \(.elements) elements, \(.patches) patches, emitted \(.emitted_energy_w) W (sum of R, G, B), \(.seconds | . * 100 | round / 100) s"' \
      "$tmp/report.json"
    if ! jq -e '.unshot_fraction < 1e-3' "$tmp/report.json" >/dev/null; then
      fail "$f: did not converge"
    fi
    sed 's/^/    /' "$tmp/solve.log" | grep -i warning
    if "$penumbra" probe "$file" --points "$tmp/points.txt" >"$tmp/probe.txt" 2>/dev/null; then
      echo "    irradiance H (W/m2) on the floor under the panel: $(sed -n 1p "$tmp/probe.txt"); in a corner: $(sed -n 2p "$tmp/probe.txt")"
      # At least the panel's direct light: E = π × 8 × (1, 0.9, 0.75) times the form factor
      # from the point to the 1 × 0.6 m panel 2.979 m above (Howell B-3, four corner pieces).
      if ! awk 'function corner(x, y, h,   X, Y, a, b) {
                  X = x / h; Y = y / h; a = sqrt(1 + X * X); b = sqrt(1 + Y * Y)
                  return (X / a * atan2(Y, a) + Y / b * atan2(X, b)) / (2 * 3.14159265358979) }
                NR == 1 { f = 4 * corner(0.5, 0.3, 2.979); e = 3.14159265358979 * 8
                  printf "    the panel alone gives it %.3f %.3f %.3f directly\n", e * f, e * 0.9 * f, e * 0.75 * f
                  exit !($1 > e * f && $2 > e * 0.9 * f && $3 > e * 0.75 * f) }' \
             "$tmp/probe.txt"; then
        fail "$f: the floor under the panel gets less than the panel's direct light"
      fi
    else
      fail "$f: penumbra probe failed"
    fi
    # OBJ holds no camera (nor the point light): rendered from the glTF files only.
    case $f in *.obj) continue ;; esac
    camera=(--camera Camera)
    png="$tmp/$(basename "$f").png"
    if "$penumbra" render "$file" "${camera[@]}" --width 160 --height 120 --out "$png" \
         >"$tmp/render.log" 2>&1; then
      echo "    render ${camera[*]:-(default view)}: 160x120, $(stat -c %s "$png") bytes"
    else
      fail "$f: penumbra render: $(tail -1 "$tmp/render.log")"
    fi
  done
fi

echo
if [ "$failures" != 0 ]; then
  echo "blender_check: $failures failure(s)"
  exit 1
fi
echo "blender_check: all passed"
