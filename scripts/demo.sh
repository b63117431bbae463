#!/usr/bin/env bash
# Installs what is missing, builds terralod, and runs the main job on a built-in terrain.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$(nproc)" --target terralod
./build/apps/terralod demo "$@"
