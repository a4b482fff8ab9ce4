#!/usr/bin/env bash
# Fuzzes the parsers users' files reach (fuzz/parser_fuzz.cpp): builds the libFuzzer targets
# with Clang, AddressSanitizer and UndefinedBehaviorSanitizer into build-fuzz/, seeds each from
# scenes/ and small files written here, and runs each for a bounded number of executions or
# seconds. Prints one line per target (executions, seconds, findings) and exits 1 when any
# target found something: its inputs are in build-fuzz/findings/TARGET/ (crash-*, leak-*,
# timeout-*, oom-*), each to become a regression test.
#
#   scripts/fuzz.sh [--runs N | --seconds S] [--jobs J] [TARGET[=RUNS] ...]
#
# TARGET=RUNS gives that target its own number of runs (to bring each to a total).
# Defaults: 10,000,000 runs per target, two targets at a time, every target (scene log obj off
# ply gltf glb import_gltf import_glb import_obj holodeck).
set -euo pipefail
cd "$(dirname "$0")/.."

runs=10000000
seconds=0
jobs=2
targets=()
while [ $# -gt 0 ]; do
  case "$1" in
    --runs) runs=$2; shift 2 ;;
    --seconds) seconds=$2; runs=0; shift 2 ;;
    --jobs) jobs=$2; shift 2 ;;
    *) targets+=("$1"); shift ;;
  esac
done
for t in "${targets[@]}"; do
  if [[ "$t" == *=* ]]; then
    if ! [[ "${t#*=}" =~ ^[0-9]+$ ]]; then
      echo "fuzz.sh: $t: the runs after '=' must be a whole number" >&2
      exit 2
    fi
    if [ "$seconds" -gt 0 ]; then
      echo "fuzz.sh: $t: TARGET=RUNS counts runs; it does not go with --seconds" >&2
      exit 2
    fi
  fi
done
[ ${#targets[@]} -gt 0 ] || targets=(scene log obj off ply gltf glb import_gltf import_glb import_obj holodeck)

# The build's dependencies, and Clang (libFuzzer ships with Debian's clang package).
bash scripts/setup.sh
if ! command -v clang++ >/dev/null; then
  SUDO=$([ "$(id -u)" -eq 0 ] || echo sudo)
  $SUDO apt-get install -y -qq --no-install-recommends clang >/dev/null
fi

dir=build-fuzz
CC=clang CXX=clang++ cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DPENUMBRA_FUZZ=ON -DPENUMBRA_BUILD_TESTS=OFF >/dev/null
names=("${targets[@]%%=*}")
cmake --build "$dir" -j2 --target "${names[@]/#/fuzz_}"

# Seed corpora: the bundled scenes and logs, and a few small files of each mesh format.
seeds=$dir/seeds
rm -rf "$seeds"
mkdir -p "$seeds"/{scene,log,obj,off,ply,gltf,glb,import_gltf,import_glb,import_obj,holodeck}
cp scenes/*.json "$seeds/scene/"
cp scenes/logs/*.jsonl "$seeds/log/"
cp scenes/gltf/*.gltf "$seeds/import_gltf/"
cat >"$seeds/obj/quad.obj" <<'END_OBJ'
# a quad and a triangle, with normals, texture coordinates and negative indices
mtllib none.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
vt 0 0
vn 0 0 1
usemtl white
f 1/1/1 2/1/1 3/1/1 4/1/1
f -4//1 -3//1 -1//1
END_OBJ
cp "$seeds/obj/quad.obj" "$seeds/import_obj/"
cat >"$seeds/off/tetra.off" <<'END_OFF'
OFF
4 4 6
0 0 0
1 0 0
0 1 0
0 0 1
3 0 2 1
3 0 1 3
3 0 3 2
3 1 2 3
END_OFF
cat >"$seeds/ply/tetra.ply" <<'END_PLY'
ply
format ascii 1.0
element vertex 4
property float x
property float y
property float z
property uchar red
property uchar green
property uchar blue
element face 4
property list uchar int vertex_indices
end_header
0 0 0 255 0 0
1 0 0 0 255 0
0 1 0 0 0 255
0 0 1 255 255 255
3 0 2 1
3 0 1 3
3 0 3 2
3 1 2 3
END_PLY
# Binary PLY and glTF/GLB seeds (a triangle with an embedded buffer, a material, a camera and a
# light), written by Python's standard library.
python3 - "$seeds" <<'PY'
import base64, json, struct, sys
seeds = sys.argv[1]
with open(f"{seeds}/ply/tetra-binary.ply", "wb") as f:
    f.write(b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\n"
            b"property float y\nproperty float z\nelement face 4\n"
            b"property list uchar int vertex_indices\nend_header\n")
    for p in [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]:
        f.write(struct.pack("<3f", *p))
    for t in [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]:
        f.write(struct.pack("<B3i", 3, *t))
positions = struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0)
indices = struct.pack("<3H", 0, 1, 2) + b"\0\0"
blob = positions + indices
doc = {
    "asset": {"version": "2.0"},
    "scene": 0,
    "scenes": [{"nodes": [0, 1, 2]}],
    "nodes": [{"mesh": 0, "translation": [0, 1, 0]}, {"camera": 0, "translation": [0, 0, 3]},
              {"extensions": {"KHR_lights_punctual": {"light": 0}}, "translation": [0, 2, 0]}],
    "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}],
    "extensionsUsed": ["KHR_lights_punctual"],
    "extensions": {"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 10}]}},
    "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.2, 0.2, 1]},
                   "emissiveFactor": [0, 0, 0], "doubleSided": True}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}],
    "accessors": [
        {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
         "min": [0, 0, 0], "max": [1, 1, 0]},
        {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}],
    "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                    {"buffer": 0, "byteOffset": 36, "byteLength": 6}],
}
embedded = dict(doc, buffers=[{"byteLength": len(blob), "uri": "data:application/octet-stream;base64,"
                               + base64.b64encode(blob).decode()}])
for d in ("gltf", "import_gltf"):
    with open(f"{seeds}/{d}/triangle.gltf", "w") as f:
        json.dump(embedded, f)
binary = dict(doc, buffers=[{"byteLength": len(blob)}])
text = json.dumps(binary).encode()
text += b" " * (-len(text) % 4)
glb = struct.pack("<III", 0x46546C67, 2, 12 + 8 + len(text) + 8 + len(blob))
glb += struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(blob), 0x004E4942) + blob
for d in ("glb", "import_glb"):
    with open(f"{seeds}/{d}/triangle.glb", "wb") as f:
        f.write(glb)

# Holodeck files (docs/holodeck.md): one section, a committed beam, and a copy with an
# uncommitted beam record and a torn one after it.
import zlib
def rec(magic, body):
    return magic + struct.pack("<I", zlib.crc32(body)) + body
head = b"PNBRHOLO" + struct.pack("<II", 1, 1)
head += struct.pack("<6d3IB3x", 0, 0, 0, 4, 3, 2, 6, 5, 4, 0)
head += struct.pack("<II", zlib.crc32(head), 0)
start = len(head) + 80
beam = rec(b"BEAM", struct.pack("<IIq", 0, 2, 5) + bytes(range(20)))
directory = rec(b"DIRS", struct.pack("<QQ", 1, 1) + struct.pack("<IIqQ", 0, 2, 5, start))
end = start + len(beam) + len(directory)
slot = struct.pack("<4Q", 1, start + len(beam), len(directory), end)
slots = bytes(40) + slot + struct.pack("<II", zlib.crc32(slot), 0)
committed = head + slots + beam + directory
with open(f"{seeds}/holodeck/committed.hdk", "wb") as f:
    f.write(committed)
appended = rec(b"BEAM", struct.pack("<IIq", 0, 1, 9) + bytes(10))
with open(f"{seeds}/holodeck/torn.hdk", "wb") as f:
    f.write(committed + appended + appended[:17])
PY

# ASan without allocation stacks: recording a stack for every allocation is most of an
# allocation-heavy target's time (the importers'), and a finding's input run again with the
# default options shows them. A user's own ASAN_OPTIONS come after and win.
export ASAN_OPTIONS="malloc_context_size=0${ASAN_OPTIONS:+:$ASAN_OPTIONS}"

# The runs, `jobs` targets at a time; each target's corpus grows in build-fuzz/corpus/TARGET.
run_one() {
  local t=${1%%=*} runs=$runs
  [ "$1" != "$t" ] && runs=${1#*=}
  local corpus=$dir/corpus/$t findings=$dir/findings/$t log=$dir/logs/$t.txt
  mkdir -p "$corpus" "$findings" "$dir/logs"
  local limit=(-runs="$runs")
  [ "$seconds" -gt 0 ] && limit=(-max_total_time="$seconds")
  local start=$SECONDS status=0
  "$dir/fuzz_$t" "${limit[@]}" -max_len=16384 -rss_limit_mb=2048 -timeout=20 \
    -artifact_prefix="$findings/" -print_final_stats=1 "$corpus" "$seeds/$t" >"$log" 2>&1 || status=$?
  local execs
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo 0)
  local found
  found=$(find "$findings" -type f | wc -l)
  printf 'fuzz %-12s %12s executions in %5d s, %d findings (exit %d)\n' "$t" "$execs" \
    $((SECONDS - start)) "$found" "$status"
}
export -f run_one
export dir seeds runs seconds
printf '%s\n' "${targets[@]}" | xargs -P "$jobs" -I{} bash -c 'run_one {}'

found=$(find "$dir/findings" -type f 2>/dev/null | wc -l)
if [ "$found" -gt 0 ]; then
  echo "fuzz: $found findings in $dir/findings" >&2
  exit 1
fi
