#!/usr/bin/env bash
# ctest `slurm`: starts a real single-node Slurm (munged, slurmctld, slurmd) under a
# temporary directory, as the current user and without systemd, submits a small linksight
# sweep with tools/slurm/submit.sh (a 3-element job array and the merge job after it) and
# checks that the merged cells.csv is byte-identical to a single local process's.
#   bash tests/slurm/run_slurm_sweep.sh LINKSIGHT-EXE SOURCE-ROOT
# Every daemon (and any job step still alive) is stopped by PID on exit, pass or fail, and
# the temporary directory removed; LINKSIGHT_SLURM_KEEP=1 keeps it for a post-mortem.
set -euo pipefail
# munged refuses a group-writable pid or log directory: do not inherit a umask of 002.
umask 022

if [[ $# -ne 2 ]]; then
  echo "usage: $0 LINKSIGHT-EXE SOURCE-ROOT" >&2
  exit 2
fi
log() { echo "slurm-test: $*"; }
fail() { echo "slurm-test: FAIL: $*" >&2; exit 1; }

# Missing Slurm is a failure, not a skip: CI must not pass without having run this.
# Debian puts the daemons in /usr/sbin, which a non-root PATH often lacks.
PATH="$PATH:/usr/sbin"
for b in munged slurmctld slurmd slurmstepd sbatch squeue sinfo scontrol scancel munge unmunge; do
  command -v "$b" >/dev/null 2>&1 ||
    fail "'$b' not found: install slurm-wlm and munge (bash tools/setup.sh does)"
done
exe=$(realpath "$1")
root=$(realpath "$2")
[[ -x "$exe" ]] || fail "linksight binary '$exe' is not executable"
[[ -f "$root/tools/slurm/submit.sh" ]] || fail "'$root' is not the linksight source root"

# Whatever Slurm this runs inside (a CI job may itself be a Slurm job) must not leak in:
# SLURM_ARRAY_TASK_ID would turn the local run into a shard, SBATCH_* would change sbatch.
while read -r v; do unset "$v"; done < <(compgen -e | grep -E '^(SLURM|SBATCH|SALLOC|SRUN)_' || true)

user=$(id -un)
host=$(uname -n)
host=${host%%.*}  # the short name, as slurmd derives it
ncpu=$(nproc)
# sweep.sbatch asks for 2 CPUs per task; a 1-CPU runner would leave it pending forever, so
# declare at least 2 and let slurmd trust the file (SlurmdParameters=config_overrides).
((ncpu >= 2)) || ncpu=2

tmp=$(mktemp -d "${TMPDIR:-/tmp}/linksight-slurm.XXXXXX")
conf="$tmp/slurm.conf"
# Every process this test starts, the job steps included, carries this in its
# environment: cleanup finds stray slurmstepd/job processes by it (not by name).
export SLURM_CONF="$conf"
pids=()

# Prints the environment-tagged PIDs (ours only: SLURM_CONF names this run's temp dir).
tagged_pids() {
  local p
  for p in /proc/[0-9]*; do
    p=${p#/proc/}
    [[ "$p" == "$$" || "$p" == "$BASHPID" ]] && continue
    tr '\0' '\n' 2>/dev/null <"/proc/$p/environ" | grep -qxF "SLURM_CONF=$conf" && echo "$p"
  done
  return 0
}

dump_logs() {
  local f
  for f in "$tmp"/work/slurm-*.out "$tmp"/log/*.log "$tmp"/log/*.stderr; do
    [[ -s "$f" ]] || continue
    echo "----- ${f#"$tmp"/} (last 60 lines) -----"
    tail -n 60 "$f"
  done
}

# A process is gone once it has exited, even while still a zombie child of this shell.
alive() { [[ "$(sed 's/.*) //' "/proc/$1/stat" 2>/dev/null | cut -c1)" =~ ^[^ZX]$ ]]; }

# SIGTERM, up to 5 s for a clean exit, then SIGKILL.
stop_pids() {
  local n p any
  (($#)) || return 0
  kill -TERM "$@" 2>/dev/null || true
  for ((n = 0; n < 50; ++n)); do
    any=0
    for p in "$@"; do alive "$p" && any=1; done
    ((any)) || return 0
    sleep 0.1
  done
  kill -KILL "$@" 2>/dev/null || true
}

cleanup() {
  local rc=$?
  set +e
  trap - EXIT INT TERM
  if ((rc != 0)); then
    echo "slurm-test: failed (exit $rc); logs from $tmp:" >&2
    dump_logs >&2
  fi
  # Jobs first (while slurmctld is up), then the daemons in reverse start order, then any
  # job process that outlived slurmd (slurmstepd detaches from it).
  [[ -n "${array_job:-}" ]] && scancel "$array_job" ${merge_job:+"$merge_job"} >/dev/null 2>&1
  local i
  for ((i = ${#pids[@]} - 1; i >= 0; --i)); do stop_pids "${pids[i]}"; done
  for i in "${pids[@]}"; do wait "$i" 2>/dev/null; done
  # shellcheck disable=SC2046
  stop_pids $(tagged_pids)
  if [[ "${LINKSIGHT_SLURM_KEEP:-0}" == 1 ]]; then
    echo "slurm-test: kept $tmp" >&2
  else
    rm -rf "$tmp"
  fi
  exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

# Polls CMD every 0.2 s for up to SECONDS; returns 1 on timeout.
wait_for() {
  local secs=$1 n
  shift
  for ((n = 0; n < secs * 5; ++n)); do
    "$@" >/dev/null 2>&1 && return 0
    sleep 0.2
  done
  return 1
}

# A free port pair (SlurmctldPort, SlurmdPort), starting from one derived from our PID so
# that concurrent runs rarely try the same one; ss shows any socket on it, TIME_WAIT too.
port_free() {
  if command -v ss >/dev/null 2>&1; then
    [[ -z "$(ss -Htan "( sport = :$1 )" 2>/dev/null)" ]]
  else
    # bash connects: a listener answers; a closed port refuses.
    if (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null; then return 1; fi
  fi
}
port=""
for ((i = 0; i < 200; ++i)); do
  p=$((20000 + ($$ * 2 + i * 2) % 20000))
  if port_free "$p" && port_free $((p + 1)); then port=$p; break; fi
done
[[ -n "$port" ]] || fail "no free TCP port pair found in 20000-39999"

mkdir -p "$tmp"/{munge,state,spool,log,run,work}
# mktemp makes 0700; the munge socket directory must be 0755 (reachable by every client,
# writable only by munged's user) and so must the path to it.
chmod 755 "$tmp" "$tmp/munge"

# --- munge: its own key and socket, nothing from /etc/munge or /run/munge -------------
sock="$tmp/munge/munge.socket"
key="$tmp/munge/munge.key"
if command -v mungekey >/dev/null 2>&1; then
  mungekey --create --keyfile="$key" >/dev/null
else
  dd if=/dev/urandom of="$key" bs=1024 count=1 status=none
fi
chmod 0400 "$key"
munged -F --socket="$sock" --key-file="$key" --pid-file="$tmp/run/munged.pid" \
  --log-file="$tmp/log/munged.log" --seed-file="$tmp/munge/munged.seed" \
  >"$tmp/log/munged.stderr" 2>&1 &
pids+=($!)
munge_ok() { munge -n -S "$sock" | unmunge -S "$sock"; }
wait_for 20 munge_ok || fail "munged did not come up on $sock"

# --- slurm.conf: one node, this user, everything under $tmp ------------------------------
cat >"$conf" <<EOF
ClusterName=linksighttest
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$port
SlurmdPort=$((port + 1))
SlurmUser=$user
SlurmdUser=$user
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$sock
StateSaveLocation=$tmp/state
SlurmdSpoolDir=$tmp/spool
SlurmctldPidFile=$tmp/run/slurmctld.pid
SlurmdPidFile=$tmp/run/slurmd.pid
# No cgroups in a container: track processes through /proc, bind no tasks.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerParameters=batch_sched_delay=0
SlurmdParameters=config_overrides
ReturnToService=2
MpiDefault=none
SwitchType=switch/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
PlugStackConfig=$tmp/plugstack.conf
MailProg=/bin/true
NodeName=$host NodeAddr=127.0.0.1 CPUs=$ncpu RealMemory=100 State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
# An empty SPANK stack: none of the host's /etc/slurm/plugstack.conf plugins.
: >"$tmp/plugstack.conf"

# In the foreground (-D) and without a LogFile, the daemons log to stderr.
slurmctld -D -i -f "$conf" >"$tmp/log/slurmctld.log" 2>&1 &
pids+=($!)
slurmd -D -f "$conf" -N "$host" >"$tmp/log/slurmd.log" 2>&1 &
pids+=($!)
node_idle() { [[ "$(sinfo -h -n "$host" -o %T)" == idle ]]; }
wait_for 30 node_idle || fail "node $host not idle after 30 s (sinfo: $(sinfo -h -o '%T %E' 2>&1))"
log "Slurm up as $user (ports $port/$((port + 1)), $tmp)"

# --- the sweep: locally in one process, then as an array + merge ----------------------------
# Absolute paths: the jobs run in the submit directory ($tmp/work), not here.
# shellcheck disable=SC2054  # the commas are linksight's value lists
sweep=(--scene "$root/scenes/robustness_static.yaml" --axis noise.scale=0,1
  --axis occlusion.fraction=0,0.3 --compare paper,accelerated-som --frames 4
  --set occlusion.from_s=0.05 --set occlusion.to_s=0.09)  # the board in frame 2 only
start=$SECONDS
# Bounded waits: a ctest TIMEOUT kills with SIGKILL, which skips the cleanup trap.
timeout 120 "$exe" sweep "${sweep[@]}" --out "$tmp/local" --no-figures --quiet
# Submitting from $tmp/work puts the slurm-*.out files there, for dump_logs.
out=$(cd "$tmp/work" && LINKSIGHT_EXE="$exe" timeout 60 bash "$root/tools/slurm/submit.sh" 3 \
  "${sweep[@]}" --out "$tmp/slurm")
log "$out"
[[ "$out" =~ ^array\ ([0-9]+)\ .*merge\ ([0-9]+): ]] || fail "cannot read job IDs from submit.sh"
array_job=${BASH_REMATCH[1]}
merge_job=${BASH_REMATCH[2]}

# Done when no job is pending, running or completing (this cluster runs only ours); a
# failing squeue is not "done". sbatch's exit codes say nothing about the result.
jobs_gone() {
  local q
  q=$(squeue -h -o %i) && [[ -z "$q" ]]
}
wait_for 120 jobs_gone || fail "jobs still queued after 120 s: $(squeue -h -o '%i %T %r' 2>&1)"
log "jobs ended after $((SECONDS - start)) s; merge job: $(scontrol -o show job "$merge_job" |
  grep -o 'JobState=[A-Z_]* .*ExitCode=[0-9:]*' | sed 's/ Reason.*ExitCode/ ExitCode/')"

# --- the checks ---------------------------------------------------------------------------
for i in 0 1 2; do
  [[ -s "$tmp/slurm/shard_${i}_of_3.csv" ]] || fail "shard_${i}_of_3.csv missing: the array did not run shard $i"
done
[[ -s "$tmp/slurm/cells.csv" ]] || fail "no merged cells.csv: the merge job did not finish"
cmp "$tmp/local/cells.csv" "$tmp/slurm/cells.csv" ||
  fail "merged cells.csv differs from the single-process run"
log "PASS: 3 shards merged byte-identical to the local run ($(($(wc -l <"$tmp/local/cells.csv") - 1)) rows)"
