#!/usr/bin/env bash
# Quick-start command 1: set up, build, and run the main job on the default scene:
#   linksight run scenes/default.yaml --compare chain-fit,paper,paper-centred,accelerated-som --out out/default
# Extra arguments go to `linksight run` (e.g. --set seed=3, --frames 60).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
# Only what the CLI needs: its packages and its target (tests and benches: tools/test.sh).
LINKSIGHT_SETUP=cli bash "$root/tools/setup.sh"
exe="${LINKSIGHT_BUILD_DIR:-$root/build}/tools/linksight"
cd "$root"
"$exe" run scenes/default.yaml --compare chain-fit,paper,paper-centred,accelerated-som --out out/default --force "$@"
