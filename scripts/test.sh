#!/usr/bin/env bash
# Fresh Debian 12 machine to a passing test suite: install, build, run every test.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/build.sh build
ctest --test-dir build --output-on-failure -j2 --timeout 300
