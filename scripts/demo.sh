#!/usr/bin/env bash
# Installs what is missing, builds terralod, and runs the main job: the flight demo, headless
# (OSMesa, no display needed), on the built-in terrain unless --input DEM is given. Frames,
# statistics and the summary land in fly_out/ (see terralod-fly --help for every option).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$(nproc)" --target terralod terralod-fly
./build/apps/terralod-fly --headless --frames 240 --out fly_out "$@"
