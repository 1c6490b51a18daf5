#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Sets up (Debian packages), builds and runs every test. Usage: scripts/test.sh
# Extra: SCANMESH_SANITIZE=1 also runs the whole suite under ASan+UBSan;
#        SCANMESH_FUZZ_SECONDS=N also builds the libFuzzer targets and runs each for N seconds.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
jobs=$(nproc)
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j "$jobs"
ctest --test-dir build --output-on-failure -j "$jobs"
