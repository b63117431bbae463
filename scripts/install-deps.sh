#!/usr/bin/env bash
# Installs the Debian packages terralod needs, only those that are missing.
set -euo pipefail
packages=(
  build-essential cmake pkg-config zlib1g-dev
  libopenmesh-dev libgdal-dev libproj-dev proj-data libopenimageio-dev libsqlite3-dev
  libglm-dev libglfw3-dev libosmesa6-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  xvfb fonts-dejavu-core clang-format
)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
# Node.js runs the glTF validator of the tests (tools/gltf): any node >= 18 on the PATH will do
# (Debian 12's nodejs is 18), so the Debian packages are only installed when the commands are absent.
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
