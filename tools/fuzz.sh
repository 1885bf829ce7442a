#!/usr/bin/env bash
# Runs one fuzz target under libFuzzer for a while (issue 19; docs/reliability.md):
#   bash tools/fuzz.sh TARGET SECONDS [libFuzzer flags...]
# TARGET: ply depth_png intrinsics nodes_csv frames answer scene grid shard mesh (or
# `list`). Builds build-fuzz/ with clang (-fsanitize=fuzzer-no-link,address,undefined on
# every library, -fsanitize=fuzzer on the target), starts from tests/fuzz/corpus/TARGET
# (read only) and keeps what it finds in build-fuzz/tests/fuzz/found/TARGET. A crash
# leaves crash-* in the current folder: add it to the corpus as a regression once fixed.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
targets="ply depth_png intrinsics nodes_csv frames answer scene grid shard mesh"
target=${1:-}
seconds=${2:-}
if [ "$target" = list ]; then echo "$targets"; exit 0; fi
if [ -z "$target" ] || [ -z "$seconds" ] || ! [[ " $targets " == *" $target "* ]]; then
  echo "usage: tools/fuzz.sh TARGET SECONDS [libFuzzer flags...]; TARGET: $targets" >&2
  exit 2
fi
shift 2
build=${LINKSIGHT_FUZZ_BUILD_DIR:-$root/build-fuzz}
# clang and every library come with tools/setup.sh (tools/test.sh runs it).
command -v clang++ >/dev/null || { echo "fuzz: clang++ is missing: run bash tools/setup.sh" >&2; exit 1; }
cmake -S "$root" -B "$build" -DCMAKE_CXX_COMPILER=clang++ \
  -DCMAKE_BUILD_TYPE=RelWithDebInfo "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG" \
  -DLINKSIGHT_FUZZ=ON -DLINKSIGHT_BUILD_BENCH=OFF \
  "-DCMAKE_CXX_FLAGS=-fsanitize=fuzzer-no-link,address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=all" \
  >/dev/null
cmake --build "$build" -j "$(nproc)" --target "linksight_fuzz_$target"
found="$build/tests/fuzz/found/$target"
mkdir -p "$found"
# The one leak suppression: Debian's assimp on malformed STL (tests/fuzz/lsan.supp).
export LSAN_OPTIONS=suppressions=$root/tests/fuzz/lsan.supp
exec "$build/tests/fuzz/linksight_fuzz_$target" -max_total_time="$seconds" -rss_limit_mb=2048 \
  -timeout=20 -print_final_stats=1 "$@" "$found" "$root/tests/fuzz/corpus/$target"
