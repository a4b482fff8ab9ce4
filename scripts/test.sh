#!/usr/bin/env bash
# Fresh Debian 12 machine to a passing test suite: install, build, run every test; then the
# unit and integration tests again under AddressSanitizer and UndefinedBehaviorSanitizer.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/build.sh build
ctest --test-dir build --output-on-failure -j2 --timeout 300
bash scripts/build.sh build-asan -DPENUMBRA_SANITIZE=ON
ctest --test-dir build-asan --output-on-failure -j2 --timeout 600 -LE golden
