#!/usr/bin/env bash
# Fresh Debian 12 machine to the main job: install, build, then the headless demo. It solves
# the bundled scenes and writes images, lit-scene exports and reports under out/. With a
# display, the editor opens once it exists (ui/ is still to come).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/build.sh build
mkdir -p out
bin=build/penumbra
for scene in cornell-box cube-room cubicles; do
  echo "demo: $scene" >&2
  "$bin" render "scenes/$scene.json" --converge 1e-3 --width 640 --height 480 \
    --out "out/$scene.png" --report "out/$scene-render.json"
  "$bin" export "scenes/$scene.json" "out/$scene.glb" --converge 1e-3 \
    --report "out/$scene-solve.json"
done
"$bin" solve scenes/robot-room.json --converge 1e-2 --export out/robot-room.ply \
  --report out/robot-room-solve.json
"$bin" render scenes/robot-room.json --converge 1e-2 --width 640 --height 480 \
  --out out/robot-room.png
echo "demo: wrote $(ls out | wc -l) files under out/" >&2
