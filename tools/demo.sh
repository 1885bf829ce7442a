#!/usr/bin/env bash
# Quick-start command 1: set up, build, and run the main job on the default input.
# Until the simulator lands this is `linksight track` on a synthetic cloud sequence.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
bash "$root/tools/setup.sh"
exe="${LINKSIGHT_BUILD_DIR:-$root/build}/tools/linksight"
out="$root/out/demo"
"$exe" synth --out "$out/frames" --frames 60 --seed 1
"$exe" track --input "$out/frames" --out "$out/track"
echo "demo: true nodes in $out/frames/truth.csv, tracked nodes in $out/track/nodes.csv"
