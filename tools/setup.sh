#!/usr/bin/env bash
# Installs the Debian packages linksight needs (only those missing; apt-get update only
# when something is missing), then configures and builds into build/ (or $LINKSIGHT_BUILD_DIR).
# Extra arguments go to the CMake configure step. Downloads nothing but Debian packages.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build_dir=${LINKSIGHT_BUILD_DIR:-$root/build}

packages=(
  cmake g++ make            # toolchain
  libeigen3-dev             # tracker maths
  libgtest-dev              # tests
  libbenchmark-dev          # bench/
  libcli11-dev              # CLI flags
  nlohmann-json3-dev        # intrinsics.json, summary.json
  libstb-dev                # PNG decoding (stb_image)
  ocl-icd-opencl-dev opencl-headers  # OpenCL back end: ICD loader and headers
  pocl-opencl-icd           # an OpenCL CPU device, so every OpenCL test runs anywhere
  libbullet-dev             # sim/: the chain's physics
  libyaml-cpp-dev           # scene files
  libassimp-dev             # sim/: mesh files (load_mesh)
  libembree-dev             # sim/: ray casting for the simulated depth camera
  python3-matplotlib        # linksight run: figures (tools/plot_run.py)
  slurm-wlm munge           # the slurm ctest: a real single-node Slurm (slurmctld, slurmd, sbatch) and munge
  zlib1g-dev                # assimp's CMake package links libz.so, which --no-install-recommends leaves out
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
if ((${#missing[@]})); then
  echo "setup: installing missing Debian packages: ${missing[*]}"
  sudo=""
  if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null || { echo "setup: need root or sudo to install ${missing[*]}" >&2; exit 1; }
    sudo="sudo"
  fi
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

cmake -S "$root" -B "$build_dir" "$@" >/dev/null
cmake --build "$build_dir" -j "$(nproc)"
