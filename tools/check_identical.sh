#!/usr/bin/env bash
# Byte-identical outputs of two linksight builds: a reference and this tree's build.
#
#   bash tools/check_identical.sh [--ref REV | --ref-bin BIN] [--frames N] [--keep DIR]
#
# Runs the same commands with both binaries, each in its own source tree (scenes, meshes,
# test data), and compares every output file's sha256:
#   run        every shipped scene, --compare chain-fit,paper,paper-centred,accelerated-som,
#              --no-figures
#   render     static and occluder_pass (depth, labels, clouds, truth, occlusion)
#   track      the occluder_pass clouds, every mode, both LSQ inits, random-sample SOM init
#   sweep      a 2x2 grid (noise.scale x occlusion fraction), three modes
#   simulate   default; synth (analytic clouds)
#   calibrate-noise on tests/data/sr305-hand (noise block, report.txt, stats.json)
# Wall-clock columns and keys (time_ms, device_ms, time_ms_*, cell_wall_s,
# timing_ms_per_frame, mean_time_ms) differ between any two runs and are left out before
# hashing; nothing else is. Exit 0: identical; 1: a difference (the files are listed).
#
# --ref REV builds REV's `linksight` target in a git worktree (build-ref/); --ref-bin uses
# a binary already built, run from this tree. Default: the revision in tools/identical_ref,
# the last commit whose outputs the refactors since must reproduce.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
frames=60
ref=""
ref_bin=""
keep=""
while (($#)); do
  case "$1" in
    --ref) ref=$2; shift 2 ;;
    --ref-bin) ref_bin=$2; shift 2 ;;
    --frames) frames=$2; shift 2 ;;
    --keep) keep=$2; shift 2 ;;
    *) echo "check_identical: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
[[ -n "$ref" || -n "$ref_bin" ]] || ref=$(tr -d '[:space:]' <"$root/tools/identical_ref")

build_dir=${LINKSIGHT_BUILD_DIR:-$root/build}
new_bin=$build_dir/tools/linksight
[[ -x "$new_bin" ]] || { echo "check_identical: build $new_bin first (tools/setup.sh)" >&2; exit 2; }

ref_root=$root
if [[ -z "$ref_bin" ]]; then
  ref_root=$root/build-ref/src
  if [[ ! -d "$ref_root" ]] || [[ "$(git -C "$ref_root" rev-parse HEAD)" != "$(git -C "$root" rev-parse "$ref^{commit}")" ]]; then
    git -C "$root" worktree remove --force "$ref_root" 2>/dev/null || rm -rf "$ref_root"
    git -C "$root" worktree prune
    git -C "$root" worktree add --detach "$ref_root" "$ref" >/dev/null
  fi
  # A unity build, as tools/setup.sh's: the bits do not depend on it (check_identical of a
  # unity build against a separate-files reference was identical).
  cmake -S "$ref_root" -B "$root/build-ref/build" -DCMAKE_UNITY_BUILD=ON -DLINKSIGHT_BUILD_TESTS=OFF \
        -DLINKSIGHT_BUILD_BENCH=OFF >/dev/null
  cmake --build "$root/build-ref/build" --target linksight -j "$(nproc)" >/dev/null
  ref_bin=$root/build-ref/build/tools/linksight
fi

work=${keep:-$(mktemp -d)}
[[ -n "$keep" ]] || trap 'rm -rf "$work"' EXIT
mkdir -p "$work"

# record BIN SRC_ROOT OUT: every command's outputs under OUT.
record() {
  local bin=$1 src=$2 out=$3
  rm -rf "$out" && mkdir -p "$out"
  (
    cd "$src"
    local modes=chain-fit,paper,paper-centred,accelerated-som
    for scene in scenes/*.yaml; do
      local name
      name=$(basename "$scene" .yaml)
      "$bin" run "$scene" --frames "$frames" --compare "$modes" --no-figures --quiet \
        --threads 2 --out "$out/run/$name"
    done
    for scene in static occluder_pass; do
      "$bin" render --scene "scenes/$scene.yaml" --frames "$frames" --threads 2 --quiet \
        --out "$out/render/$scene"
    done
    # track names its --input in summary.json: relative, so both trees write the same.
    (
      cd "$out"
      local clouds=render/occluder_pass/clouds
      "$bin" track --input $clouds --mode chain-fit --quiet --out track/chain_fit
      "$bin" track --input $clouds --mode paper --init pca --quiet --out track/paper_pca
      "$bin" track --input $clouds --mode paper --init paper --quiet --out track/paper_paper
      "$bin" track --input $clouds --mode paper-centred --quiet --out track/paper_centred
      "$bin" track --input $clouds --mode accelerated-som --quiet --out track/som_line
      "$bin" track --input $clouds --mode accelerated-som --som-init random-sample --seed 3 \
        --quiet --out track/som_random
    )
    "$bin" sweep --scene scenes/default.yaml --axis noise.scale=0,1 \
      --axis occlusion.fraction=0.1,0.3 --set occlusion.at=middle --compare chain-fit,paper,accelerated-som \
      --frames $((frames < 12 ? frames : 12)) --threads 2 --no-figures --quiet --out "$out/sweep"
    "$bin" simulate --scene scenes/default.yaml --frames "$frames" --quiet --out "$out/simulate"
    "$bin" synth --frames $((frames < 10 ? frames : 10)) --out "$out/synth" >/dev/null
    mkdir -p "$out/calibrate"
    "$bin" calibrate-noise --input tests/data/sr305-hand/frames \
      --intrinsics tests/data/sr305-hand/intrinsics.json --out "$out/calibrate/noise.yaml" \
      --report "$out/calibrate/report" >/dev/null
  )
}

# manifest OUT: "sha256  path" of every file, wall-clock fields removed first.
manifest() {
  python3 - "$1" <<'EOF'
import csv, hashlib, io, json, os, re, sys
root = sys.argv[1]
TIMING = re.compile(r"^(time_ms.*|device_ms|cell_wall_s|timing_ms_per_frame|mean_time_ms)$")
def drop(v):
    if isinstance(v, dict):
        return {k: drop(x) for k, x in v.items() if not TIMING.match(k)}
    if isinstance(v, list):
        return [drop(x) for x in v]
    return v
for d, _, files in sorted(os.walk(root)):
    for f in sorted(files):
        p = os.path.join(d, f)
        data = open(p, "rb").read()
        if f.endswith(".csv"):
            rows = list(csv.reader(io.StringIO(data.decode())))
            if rows:
                keep = [i for i, c in enumerate(rows[0]) if not TIMING.match(c)]
                buf = io.StringIO()
                csv.writer(buf, lineterminator="\n").writerows([[r[i] for i in keep] for r in rows])
                data = buf.getvalue().encode()
        elif f.endswith(".json"):
            data = json.dumps(drop(json.loads(data)), sort_keys=True).encode()
        print(hashlib.sha256(data).hexdigest(), os.path.relpath(p, root))
EOF
}

echo "check_identical: reference $ref_bin (tree $ref_root), new $new_bin, $frames frames"
record "$ref_bin" "$ref_root" "$work/ref"
record "$new_bin" "$root" "$work/new"
manifest "$work/ref" >"$work/ref.sha256"
manifest "$work/new" >"$work/new.sha256"
n=$(wc -l <"$work/new.sha256")
if diff -u "$work/ref.sha256" "$work/new.sha256" >"$work/diff.txt"; then
  echo "check_identical: $n output files identical"
else
  echo "check_identical: outputs differ (- reference, + new):" >&2
  grep -E '^[-+][0-9a-f]' "$work/diff.txt" >&2 || true
  exit 1
fi
