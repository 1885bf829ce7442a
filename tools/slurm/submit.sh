#!/bin/bash
# Submits a linksight sweep as a Slurm job array of N shards and a merge job that runs
# after every shard has ended (afterany: the merge's completeness check, not sbatch's exit
# codes, decides whether the sweep is whole).
#   tools/slurm/submit.sh N SWEEP-ARGS... --out DIR
# Prints the two job IDs. Re-submitting the same command resumes: complete shards are skipped.
set -euo pipefail
if [[ $# -lt 2 || ! "$1" =~ ^[1-9][0-9]*$ ]]; then
  echo "usage: tools/slurm/submit.sh N SWEEP-ARGS... --out DIR" >&2
  exit 2
fi
n=$1
shift
out=""
args=("$@")
for ((i = 0; i < ${#args[@]}; ++i)); do
  [[ "${args[i]}" == "--out" && $((i + 1)) -lt ${#args[@]} ]] && out="${args[i + 1]}"
done
if [[ -z "$out" ]]; then
  echo "submit.sh: --out DIR is required" >&2
  exit 2
fi
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
exe="${LINKSIGHT_EXE:-$(cd "$here/../.." && pwd)/build/tools/linksight}"
array=$(LINKSIGHT_EXE="$exe" sbatch --parsable --array="0-$((n - 1))" \
  --export=ALL,LINKSIGHT_EXE="$exe" "$here/sweep.sbatch" "$@")
array=${array%%;*}
merge=$(sbatch --parsable --dependency="afterany:$array" --job-name=linksight-merge \
  --output="slurm-%j-merge.out" --wrap "'$exe' sweep merge '$out'")
echo "array $array ($n shards), merge $merge: results in $out/cells.csv"
