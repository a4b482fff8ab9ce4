#!/usr/bin/env bash
# Fresh Debian 12 machine to a passing test suite: install, build, run every test; then the
# unit tests again under AddressSanitizer and UndefinedBehaviorSanitizer (the integration tests,
# which run the command-line programs over whole scenes, run in the Release build only: under
# the sanitizers they took a large share of CI's time budget), and the threaded ones (the
# editor's runner, the display, background builds) under ThreadSanitizer.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/build.sh build
ctest --test-dir build --output-on-failure -j2 --timeout 300
# The sanitizer stage builds only what `ctest -L unit` runs (target unit_tests: the unit test
# executables), not the command lines, the editor or the CLI, process and display tests.
cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=Release -DPENUMBRA_SANITIZE=ON >/dev/null
cmake --build build-asan -j2 --target unit_tests
ctest --test-dir build-asan --output-on-failure -j2 --timeout 600 -L unit
cmake -S . -B build-tsan -G Ninja -DCMAKE_BUILD_TYPE=Release -DPENUMBRA_TSAN=ON >/dev/null
cmake --build build-tsan -j2 --target tsan_tests
# Address-space randomization off where allowed: ThreadSanitizer's fixed memory layout does not
# fit the wider randomization of recent kernels.
norandom=()
if setarch "$(uname -m)" -R true 2>/dev/null; then norandom=(setarch "$(uname -m)" -R); fi
"${norandom[@]}" ctest --test-dir build-tsan --output-on-failure -j2 --timeout 900
