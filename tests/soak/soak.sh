#!/usr/bin/env bash
# Soak test (issue 19, part 5; ctest label `soak`, by hand, not in CI; docs/reliability.md):
#   bash tests/soak/soak.sh LINKSIGHT_EXE REPO_ROOT [WORK_DIR]
# 1. `run` of the default scene for LINKSIGHT_SOAK_MINUTES (30) minutes of simulated time
#    with every mode: its resident memory, sampled every 0.5 s, must not grow after the first
#    tenth of the run (at most 5% or 16 MiB above it), and its first 300 frames must equal
#    a short run's of the same scene (every column but the times).
# 2. A sweep of LINKSIGHT_SOAK_CELLS (10,000) cells in 4 shards: a shard's memory must not
#    grow with its cells, the merge must hold every cell, and the rows of a 200-cell sweep
#    over part of the grid must equal the big sweep's rows for those cells.
# Prints the figures; exits non-zero on the first broken check.
set -euo pipefail
exe=$1
root=$2
work=${3:-$(mktemp -d -t linksight_soak.XXXXXX)}
minutes=${LINKSIGHT_SOAK_MINUTES:-30}
cells=${LINKSIGHT_SOAK_CELLS:-10000}
mkdir -p "$work"
echo "soak: in $work; $(lscpu | sed -n 's/^Model name: *//p'), $(nproc) cores"

# Runs "$@" in the background, sampling its VmRSS (KiB) every $sample_s s into $samples. Often
# enough that a shard of the sweep, 35 s on a quiet 2-core machine, gives the check below
# enough samples (every 2 s it gave 18, which could not tell).
sample_s=0.5
sampled() {
  local samples=$1
  shift
  : >"$samples"
  "$@" &
  local pid=$!
  while kill -0 "$pid" 2>/dev/null; do
    awk '/^VmRSS/ {print $2}' "/proc/$pid/status" 2>/dev/null >>"$samples" || true
    sleep "$sample_s"
  done
  wait "$pid"
}

# No growth after the first tenth (at least 20 s: the start-up): the largest sample of the
# rest (at least 10 s of it) within 5% (or 16 MiB) of the largest of the first tenth.
flat() {
  python3 - "$1" "$2" "$sample_s" <<'PY'
import math, sys
v = [int(x) for x in open(sys.argv[1]) if x.strip()]
startup = math.ceil(20 / float(sys.argv[3]))  # samples in 20 s
if len(v) < startup + math.ceil(10 / float(sys.argv[3])):
    sys.exit(f"{sys.argv[2]}: only {len(v)} memory samples (too short to tell)")
cut = max(startup, len(v) // 10)
head = max(v[:cut])
rest = max(v[cut:])
growth = rest - head
print(f"{sys.argv[2]}: RSS after the first tenth {head / 1024:.1f} MiB, at most {rest / 1024:.1f} MiB later "
      f"({len(v)} samples, growth {growth / 1024:+.1f} MiB)")
if growth > max(0.05 * head, 16 * 1024):
    sys.exit(f"{sys.argv[2]}: memory grows")
PY
}

# Same rows in the columns both files have, except times, for rows whose column
# `key` is below `below`, ignoring `skip` columns.
same_rows() {
  python3 - "$@" <<'PY'
import csv, sys
a, b, key, below = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
skip = set(sys.argv[5].split(",")) if len(sys.argv) > 5 and sys.argv[5] else set()
def rows(f):
    out = []
    for r in csv.DictReader(open(f)):
        if int(r[key]) < below:
            out.append(tuple((k, v) for k, v in r.items() if "time" not in k and k not in skip))
    return out
ra, rb = rows(a), rows(b)
if ra != rb:
    sys.exit(f"{a} and {b} differ in their first {below} ({len(ra)} and {len(rb)} rows)")
print(f"identical: {len(ra)} rows of {a.split('/')[-1]} below {key} {below}")
PY
}

seconds=$(python3 -c "print(format($minutes * 60, 'g'))")
modes=chain-fit,paper,paper-centred,accelerated-som
start=$(date +%s)
sampled "$work/run.rss" "$exe" run "$root/scenes/default.yaml" --set "duration_s=$seconds" \
  --compare "$modes" --no-figures --quiet --force --out "$work/long"
echo "soak: run of $seconds s simulated ($(python3 -c "import json;print(json.load(open('$work/long/summary.json'))['frames'])") frames, 4 modes): $(( $(date +%s) - start )) s"
flat "$work/run.rss" "run"
"$exe" run "$root/scenes/default.yaml" --set "duration_s=$seconds" --frames 300 --compare "$modes" \
  --no-figures --quiet --force --out "$work/short"
same_rows "$work/long/frames.csv" "$work/short/frames.csv" frame 300
same_rows "$work/long/nodes.csv" "$work/short/nodes.csv" frame 300

side=$(python3 -c "import math;print(math.isqrt($cells))")
values=$(python3 -c "print(','.join(str(i) for i in range(1, $side + 1)))")
noise=$(python3 -c "print(','.join(format(i / $side, 'g') for i in range($side)))")
grid=(--scene "$root/scenes/static.yaml" --axis "noise.scale=$noise" --axis "seed=$values"
      --frames 1 --compare paper --no-figures --quiet)
rm -rf "$work/sweep"
start=$(date +%s)
for shard in 0 1 2 3; do
  sampled "$work/shard$shard.rss" "$exe" sweep "${grid[@]}" --shard "$shard/4" --out "$work/sweep"
done
echo "soak: sweep of $((side * side)) cells in 4 shards: $(( $(date +%s) - start )) s"
flat "$work/shard0.rss" "sweep shard 0/4"
"$exe" sweep merge --no-figures "$work/sweep" >/dev/null
rows=$(($(wc -l <"$work/sweep/cells.csv") - 1))
[ "$rows" -eq $((side * side)) ] || { echo "soak: merged $rows rows, expected $((side * side))" >&2; exit 1; }
echo "soak: merged $rows cells"
# Part of the grid on its own: the first two noise values, every seed.
part=$(python3 -c "print(','.join(format(i / $side, 'g') for i in range(2)))")
"$exe" sweep --scene "$root/scenes/static.yaml" --axis "noise.scale=$part" --axis "seed=$values" \
  --frames 1 --compare paper --no-figures --quiet --force --out "$work/part"
same_rows "$work/sweep/cells.csv" "$work/part/cells.csv" cell $((2 * side)) cell
echo "soak: passed"
