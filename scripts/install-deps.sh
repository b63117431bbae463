#!/usr/bin/env bash
# Installs the Debian packages terralod needs, only those that are missing.
set -euo pipefail
packages=(
  build-essential cmake pkg-config zlib1g-dev
  libopenmesh-dev libgdal-dev libopenimageio-dev libsqlite3-dev
  libglm-dev libglfw3-dev libosmesa6-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  xvfb fonts-dejavu-core clang-format
)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "install-deps: installing ${missing[*]}"
  SUDO=""
  [[ $(id -u) -ne 0 ]] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
