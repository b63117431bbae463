#!/usr/bin/env bash
# Installs the Debian packages terralod needs, only those that are missing.
#
# Usage: bash scripts/install-deps.sh [PACKAGE...]   (PACKAGE: more that a caller needs, e.g. fuzz.sh's clang)
set -euo pipefail
packages=(
  build-essential cmake ninja-build pkg-config zlib1g-dev libdeflate-dev
  libopenmesh-dev libgdal-dev libproj-dev proj-data libmeshoptimizer-dev libopenimageio-dev libsqlite3-dev
  libglm-dev libglfw3-dev libosmesa6-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  xvfb fonts-dejavu-core libfreetype-dev libharfbuzz-dev libfribidi-dev libfontconfig-dev
  fonts-noto-core fonts-wqy-zenhei clang-format
  chromium proj-bin gdal-bin
  openmpi-bin libopenmpi-dev
  "$@"
)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
# chromium: the headless browser of the CesiumJS client check (tools/cesium); proj-bin: PROJ's cs2cs,
# which gives that test the EGM96 geoid undulation (with proj-data's egm96_15.gtx); gdal-bin: gdaldem,
# the reference test_topographic_texture's hillshade is compared with (skipped without it). Open MPI: the
# distributed 'mpirun -np N terralod build' and its tests.
# Node.js runs the glTF validator and the CesiumJS check of the tests (tools/gltf, tools/cesium): any
# node >= 18.18 on the PATH will do (Debian 12's nodejs is 18.20), so the Debian packages are only
# installed when the commands are absent.
command -v node >/dev/null || missing+=(nodejs)
command -v npm >/dev/null || missing+=(npm)
if ((${#missing[@]})); then
  echo "install-deps: installing ${missing[*]}"
  SUDO=""
  [[ $(id -u) -ne 0 ]] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# The official glTF validator (gltf-transform validate) at the versions pinned in
# tools/gltf/package-lock.json; install scripts are skipped (validate needs none of them).
gltf_tools="$(cd "$(dirname "$0")/.." && pwd)/tools/gltf"
if [[ ! -d "$gltf_tools/node_modules" ]]; then
  echo "install-deps: npm ci in tools/gltf (glTF validator)"
  npm ci --prefix "$gltf_tools" --ignore-scripts --no-audit --no-fund >/dev/null
fi

# CesiumJS and puppeteer-core (which drives the Debian chromium; it downloads no browser) at the
# versions pinned in tools/cesium/package-lock.json, for tests/apps/test_cesium_client.cpp.
cesium_tools="$(cd "$(dirname "$0")/.." && pwd)/tools/cesium"
if [[ ! -d "$cesium_tools/node_modules" ]]; then
  echo "install-deps: npm ci in tools/cesium (CesiumJS client check)"
  npm ci --prefix "$cesium_tools" --ignore-scripts --no-audit --no-fund >/dev/null
fi
