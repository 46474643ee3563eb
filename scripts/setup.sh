#!/usr/bin/env bash
# Install tetfsi's build dependencies from Debian 12 packages, only those missing.
# Idempotent: a second run installs nothing and takes well under a second.
set -euo pipefail

packages=(
  build-essential cmake ninja-build ccache pkg-config clang-format
  libeigen3-dev libcgal-dev libgmp-dev libmpfr-dev libboost-dev
  libsuitesparse-dev libopenblas0-pthread libopenblas-dev
  libvtk9-dev python3-vtk9 zlib1g-dev liblz4-dev
  doctest-dev libtbb-dev nlohmann-json3-dev libcli11-dev libspdlog-dev libfmt-dev
  libpetsc-real-dev libhypre-dev
  xvfb python3-numpy python3-matplotlib   # tetfsi render (VTK needs X: Xvfb), tetfsi plot
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if ((${#missing[@]})); then
  echo "setup: installing ${#missing[@]} Debian packages: ${missing[*]}"
  sudo_cmd=()
  if [[ $(id -u) -ne 0 ]]; then
    command -v sudo >/dev/null || { echo "setup: need root or sudo to apt-get install" >&2; exit 1; }
    sudo_cmd=(sudo)
  fi
  export DEBIAN_FRONTEND=noninteractive
  "${sudo_cmd[@]}" apt-get update -qq
  "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
  echo "setup: done"
fi
