#!/usr/bin/env bash
# Installs the Debian packages linksight needs (only those missing; apt-get update only
# when something is missing), then configures and builds into build/ (or $LINKSIGHT_BUILD_DIR).
# Extra arguments go to the CMake configure step. Downloads nothing but Debian packages.
# LINKSIGHT_SETUP=cli (tools/demo.sh): only what the `linksight` CLI needs, and only that
# target is built; the default (tools/test.sh) installs and builds everything.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build_dir=${LINKSIGHT_BUILD_DIR:-$root/build}

packages=(
  cmake g++ make            # toolchain
  libeigen3-dev             # tracker maths
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
  python3-plotly            # linksight run: the 3-D view, view.html (tools/plot_view.py)
  zlib1g-dev                # assimp's CMake package links libz.so, which --no-install-recommends leaves out
)
what=${LINKSIGHT_SETUP:-all}
case "$what" in
  cli) configure=(-DLINKSIGHT_BUILD_TESTS=OFF -DLINKSIGHT_BUILD_BENCH=OFF)
       build=(--target linksight) ;;
  all) packages+=(
         libgtest-dev       # tests
         libbenchmark-dev   # bench/
         python3-numpy      # tools/trackers/som.py, the external-tracker tests' reference client
         clang              # the fuzz targets under libFuzzer (tools/fuzz.sh, ctest label fuzz)
         chromium           # the 3-D view's test: a real browser loads view.html headless
         slurm-wlm munge    # the slurm ctest: a real single-node Slurm (slurmctld, slurmd, sbatch) and munge
       )
       configure=(-DLINKSIGHT_BUILD_TESTS=ON -DLINKSIGHT_BUILD_BENCH=ON)
       build=() ;;
  *) echo "setup: LINKSIGHT_SETUP=$what: expected cli or all" >&2; exit 2 ;;
esac

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

# The configure options come before the caller's, which may override them. A unity build
# (CMake compiles each target's sources in batches of 8 as one file) takes a third off a
# fresh build's compile time, much of which is re-reading Eigen, CLI11 and nlohmann/json
# for every file (docs/reliability.md, CI time); for edit-compile loops pass
# -DCMAKE_UNITY_BUILD=OFF. The outputs' bits do not depend on it (tools/check_identical.sh).
cmake -S "$root" -B "$build_dir" -DCMAKE_UNITY_BUILD=ON "${configure[@]}" "$@" >/dev/null
cmake --build "$build_dir" -j "$(nproc)" "${build[@]}"
