#!/usr/bin/env bash
# Installs the Debian packages diffipc needs. Idempotent: installs only what is missing.
set -euo pipefail

PACKAGES=(
  build-essential cmake ccache pkg-config git
  libgmp-dev libeigen3-dev libsuitesparse-dev libopenblas0-pthread libopenblas-pthread-dev
  libhdf5-dev libtbb-dev
  nlohmann-json3-dev libcli11-dev libspdlog-dev libfmt-dev libmuparser-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  pybind11-dev python3-dev python3-numpy python3-pytest python3-h5py python3-scipy python3-meshio
  libopenmpi-dev openmpi-bin python3-mpi4py
  coinor-libipopt-dev libnlopt-cxx-dev python3-matplotlib libgmsh-dev python3-gmsh
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install_deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

echo "install_deps: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -q
$SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
