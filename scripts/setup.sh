#!/usr/bin/env bash
# Installs Penumbra's Debian 12 build dependencies (idempotent; apt-get as root, or through
# sudo) and extracts the real meshes the sample scenes use from Debian's libcgal-demo data.
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(
  build-essential cmake ninja-build pkg-config python3
  libglfw3-dev libglm-dev libembree-dev libopenmesh-dev libcgal-dev libcgal-demo libimgui-dev
  libosmesa6-dev libegl-dev libegl1-mesa-dev libgl-dev libgles-dev libtbb-dev
  nlohmann-json3-dev libcli11-dev libstb-dev libtinyobjloader-dev libtinygltf-dev
  libgtest-dev libbenchmark-dev libeigen3-dev libtinyexr-dev python3-glad xvfb libspdlog-dev
  zlib1g-dev
  # Open MPI: `mpirun -np N penumbra holodeck fill` shares a batch fill among processes.
  libopenmpi-dev openmpi-bin
  # xvfb-run needs xauth (only a Recommends of xvfb); llvmpipe comes with libgl1-mesa-dri.
  xauth libgl1-mesa-dri
)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
# Node.js and npm run the Khronos glTF validator in the export tests; Debian's unless the
# machine already has a Node.js with its npm (NodeSource's nodejs bundles npm and conflicts
# with Debian's npm package).
if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
  missing+=(nodejs npm)
fi
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}" >&2
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# Real meshes for robot-room and large (not committed; see scenes/meshes/README.md).
MESHES=(cow elephant dino bull camel elk mushroom armadillo bunny00 ChineseDragon-10kv)
dest=scenes/meshes/cgal
need=0
for m in "${MESHES[@]}"; do [ -f "$dest/$m.off" ] || need=1; done
if [ $need -eq 1 ]; then
  mkdir -p "$dest"
  tmp=$(mktemp -d)
  tar xzf /usr/share/doc/libcgal-dev/data.tar.gz -C "$tmp" \
    $(printf 'data/meshes/%s.off ' "${MESHES[@]}")
  for m in "${MESHES[@]}"; do cp "$tmp/data/meshes/$m.off" "$dest/"; done
  rm -rf "$tmp"
fi

# The glTF validator, pinned by tools/gltf-validator/package-lock.json.
validator=tools/gltf-validator
if [ ! -f "$validator/node_modules/gltf-validator/package.json" ] ||
   [ "$validator/package-lock.json" -nt "$validator/node_modules/.package-lock.json" ]; then
  echo "setup: installing the glTF validator ($validator)" >&2
  npm ci --prefix "$validator" --no-audit --no-fund --loglevel=error >/dev/null
fi
