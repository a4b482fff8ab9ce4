#!/usr/bin/env bash
# Fresh Debian 12 machine to the main job: install, build, then the headless demo. It replays
# the bundled edit sessions (each edit's lighting redistributed, not recomputed, and checked
# against a from-scratch reference), and writes images, lit-scene exports and reports under
# out/. On a machine with a display it then opens the editor on robot-room.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/build.sh build
mkdir -p out
bin=build/penumbra

echo "demo: replaying scenes/logs/cube-room-session.jsonl (30 edits) with references" >&2
"$bin" replay scenes/cube-room.json scenes/logs/cube-room-session.jsonl --budget-shots 5 \
  --reference --save-scene out/cube-room-edited.json --export out/cube-room-edited.glb \
  --report out/cube-room-session.json
"$bin" render out/cube-room-edited.json --width 640 --height 480 --out out/cube-room-edited.png

echo "demo: adding the robot to robot-room" >&2
"$bin" replay scenes/robot-room-empty.json scenes/logs/robot-room-add-robot.jsonl \
  --converge 0.01 --export out/robot-room.ply --report out/robot-room-add-robot.json
"$bin" render scenes/robot-room.json --converge 0.01 --width 640 --height 480 \
  --out out/robot-room.png --report out/robot-room-render.json

echo "demo: robot-room through the edge-and-point display (20 frames along an orbit)" >&2
"$bin" render scenes/robot-room.json --converge 0.01 --mode epi --frames 20 --overlay edges \
  --width 512 --height 384 --out out/robot-room-epi.png --report out/robot-room-epi.json

echo "demo: cornell-box" >&2
"$bin" render scenes/cornell-box.json --width 640 --height 480 --out out/cornell-box.png \
  --report out/cornell-box-render.json
"$bin" export scenes/cornell-box.json out/cornell-box.gltf
echo "demo: wrote $(ls out | wc -l) files under out/" >&2

if [ -n "${DISPLAY:-}" ] && [ -x build/penumbra-editor ]; then
  echo "demo: a display is present: opening the editor (edits are logged to out/editor.jsonl)" >&2
  build/penumbra-editor scenes/robot-room.json --log out/editor.jsonl
fi
