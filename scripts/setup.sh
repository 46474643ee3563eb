#!/usr/bin/env bash
# Install tetfsi's build dependencies from Debian 12 packages, only those missing.
# Idempotent: a second run installs nothing and takes well under a second. Also extracts the
# Stanford bunny from CGAL's data (libcgal-demo) into data/meshes/bunny00.off.
# Usage: setup.sh [--blender]
#   --blender  also Debian's blender (3.4; blender and blender-data take 190 MB installed), for
#              `make test-blender` and scripts/blender_check.py: only when asked, nothing else
#              needs it.
set -euo pipefail

with_blender=0
for arg in "$@"; do
  case $arg in
    --blender) with_blender=1 ;;
    *) echo "setup: unknown option '$arg' (usage: setup.sh [--blender])" >&2; exit 2 ;;
  esac
done

packages=(
  build-essential cmake ninja-build ccache pkg-config clang-format
  libeigen3-dev libcgal-dev libgmp-dev libmpfr-dev libboost-dev
  libsuitesparse-dev libopenblas0-pthread libopenblas-dev
  libvtk9-dev python3-vtk9 zlib1g-dev liblz4-dev
  doctest-dev libtbb-dev nlohmann-json3-dev libcli11-dev libspdlog-dev libfmt-dev
  libpetsc-real-dev libhypre-dev openmpi-bin   # mpirun: MPI ranks (tetfsi run under mpirun -np N)
  xvfb python3-numpy python3-matplotlib   # tetfsi render (VTK needs X: Xvfb), tetfsi plot
  libcgal-demo                            # CGAL's data: the Stanford bunny of data/scenes/bunny.json
  libopenvdb-dev libopenvdb-tools         # OpenVDB: the .vdb export, the particle level set;
                                          # vdb_print reads the export back in the tests
)
if ((with_blender)); then
  packages+=(blender)                     # Blender headless: make test-blender
fi

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

# The Stanford bunny (data/scenes/bunny.json) comes from CGAL's data in libcgal-demo; only
# that one file is extracted, into data/meshes/ (ignored by git: not ours to commit).
bunny="$(cd "$(dirname "$0")/.." && pwd)/data/meshes/bunny00.off"
if [[ ! -s "$bunny" ]]; then
  tar -xzOf /usr/share/doc/libcgal-dev/data.tar.gz data/meshes/bunny00.off >"$bunny.tmp"
  mv "$bunny.tmp" "$bunny"
  echo "setup: extracted $bunny from libcgal-demo's CGAL data"
fi
