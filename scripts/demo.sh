#!/usr/bin/env bash
# Installs what is missing, builds terralod, and runs the main job: the flight demo, headless
# (OSMesa, no display needed). Without arguments it flies the built-in terrain at 2049 x 2049
# samples (61 km across, 64 blocks of 257: several times what the 512 MiB memory budget holds,
# so the runtime streams them), built once into build/demo/terrain.db with a hillshade layer
# and reused, with the heads-up display drawn into the frames. With arguments, they go to
# terralod-fly instead (e.g. --db FILE.db, --input DEM, --frames N). Frames, frames.csv and the
# summary land in fly_out/; the last line states the guarantee measured on this run.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
export CMAKE_GENERATOR="${CMAKE_GENERATOR:-Ninja}"  # as scripts/test.sh: both share build/
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$(nproc)" --target terralod terralod-fly
if (($# > 0)); then
  exec ./build/apps/terralod-fly --headless --frames 240 --out fly_out "$@"
fi
demo=build/demo
if [[ ! -f $demo/ready ]]; then  # each step is atomic or resumable: a rerun finishes the job
  mkdir -p "$demo"
  ./build/apps/terralod generate --size 2049 --out "$demo/terrain.tif"
  ./build/apps/terralod build --input "$demo/terrain.tif" --out "$demo/terrain.db"
  ./build/apps/terralod texture shade "$demo/terrain.db" --layer shade
  touch "$demo/ready"
fi
exec ./build/apps/terralod-fly --headless --db "$demo/terrain.db" --layer shade --hud --frames 240 --out fly_out
