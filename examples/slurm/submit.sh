#!/usr/bin/env bash
# Renders one image on a Slurm cluster: a job array of PARTS render tasks, then a merge job that runs once all succeed.
#
#   examples/slurm/submit.sh [--wait] SCENE OUT PARTS SPP [render options...]
#
# Task i runs `pathwave render SCENE --spp SPP --part auto/PARTS -o OUT.parts/part-i.exr [render options]` (pathwave
# reads i from SLURM_ARRAY_TASK_ID), and the merge job `pathwave merge OUT.parts/part-*.exr -o OUT`. The result is
# bit-identical to `pathwave render SCENE --spp SPP --film-stats -o OUT [render options]` on one machine.
#
# OUT.parts/ also holds each job's log (render-ARRAY_i.out, merge-ID.out) and the two job scripts. The jobs run in
# the current directory (relative paths in the render options keep working), so it, SCENE and OUT must be on a
# filesystem that every node shares. The pathwave binary is $PATHWAVE, else `pathwave` on PATH.
#
# Prints render_job=ID and merge_job=ID on stdout. With --wait it then waits for the merge: exit 0 once OUT is
# written, 1 (with the failing job's log) if a task or the merge failed, 124 after PATHWAVE_SUBMIT_TIMEOUT seconds
# (default 3600) with the jobs left queued. sbatch's own variables (SBATCH_PARTITION, SBATCH_ACCOUNT,
# SBATCH_TIMELIMIT, ...) apply to both jobs, e.g. SBATCH_TIMELIMIT=30 for 30 minutes.
set -euo pipefail

say() { echo "submit.sh: $*" >&2; }
die() {
  say "error: $*"
  exit 1
}
usage() {
  sed -n '4p' "$0" | sed 's/^# *//; s/^/usage: /' >&2
  exit 2
}

wait_for_merge=
case ${1:-} in
  --wait) wait_for_merge=1 && shift ;;
  -h | --help) usage ;;
esac
[ $# -ge 4 ] || usage
scene=$1 out=$2 parts=$3 spp=$4
shift 4
render_opts=("$@")

[[ $parts =~ ^[1-9][0-9]*$ ]] || die "PARTS must be a positive integer, not '$parts'"
[[ $spp =~ ^[1-9][0-9]*$ ]] || die "SPP must be a positive integer, not '$spp'"
[ "$parts" -le "$spp" ] || die "PARTS ($parts) is more than SPP ($spp): some parts would have no samples"
for o in "${render_opts[@]}"; do
  case $o in
    -o | --output | --output=* | --part | --part=* | --samples | --samples=* | --spp | --spp=*)
      die "render option $o is set by this script (from OUT, PARTS and SPP); leave it out"
      ;;
  esac
done
timeout_s=${PATHWAVE_SUBMIT_TIMEOUT:-3600}
[[ $timeout_s =~ ^[0-9]+$ ]] || die "PATHWAVE_SUBMIT_TIMEOUT must be a number of seconds, not '$timeout_s'"
for tool in sbatch scontrol; do
  command -v "$tool" >/dev/null ||
    die "$tool not found: this needs the Slurm client tools (and SLURM_CONF, if not the system's)"
done

[ -f "$scene" ] || die "scene not found: $scene"
scene=$(realpath "$scene")
out=$(realpath -m "$out")
[ -d "$(dirname "$out")" ] || die "the folder for OUT does not exist: $(dirname "$out")"

# The jobs may start on another node with another PATH: give them the binary's absolute path when it is known here.
pw=${PATHWAVE:-pathwave}
if [[ $pw == */* ]]; then
  [ -x "$pw" ] || die "PATHWAVE is not an executable file: $pw"
  pw=$(realpath "$pw")
elif command -v "$pw" >/dev/null; then
  pw=$(command -v "$pw")
else
  say "note: $pw is not on this host's PATH; the jobs will look for it on their nodes' PATH"
fi

partdir=$out.parts
mkdir -p "$partdir"
# Parts left from an earlier submission (perhaps with another PARTS) would make the merge refuse the set.
stale=("$partdir"/part-*.exr)
if [ -e "${stale[0]}" ]; then
  say "removing the parts of an earlier submission from $partdir (${#stale[@]} files)"
  rm -f -- "${stale[@]}"
fi

# Each argument shell-quoted, after a space: the job scripts must pass on every option exactly as given here.
qw() {
  local a
  for a; do printf ' %q' "$a"; done
}
render_script=$partdir/render.sbatch
redo="SLURM_ARRAY_TASK_ID=i bash$(qw "$render_script")"
cat >"$render_script" <<EOF
#!/usr/bin/env bash
# One part of$(qw "$out") (written by examples/slurm/submit.sh). pathwave takes the part from SLURM_ARRAY_TASK_ID.
# To redo part i by hand: $redo
set -euo pipefail
exec$(qw "$pw" render "$scene" --spp "$spp" --part "auto/$parts" -o) $(printf %q "$partdir")/part-"\$SLURM_ARRAY_TASK_ID".exr$(qw "${render_opts[@]}")
EOF
cat >"$partdir/merge.sbatch" <<EOF
#!/usr/bin/env bash
# Merges the parts into$(qw "$out") (written by examples/slurm/submit.sh).
set -euo pipefail
exec$(qw "$pw" merge) $(printf %q "$partdir")/part-*.exr -o$(qw "$out")
EOF

# --wait's last resort, should the merge job be forgotten before it is seen: is OUT newer than this?
touch "$partdir/.submitted"

# Strips the ";cluster" that --parsable adds on multi-cluster setups.
submit() {
  local id
  id=$(sbatch --parsable "$@") || return 1
  echo "${id%%;*}"
}

array_id=$(submit --job-name=pathwave-render --array="0-$((parts - 1))" --chdir="$PWD" \
  --output="$partdir/render-%A_%a.out" "$render_script") || die "sbatch refused the render array (its message is above)"
# kill-on-invalid-dep: once the array has ended with a failed task, Slurm cancels the merge rather than leave it
# pending for ever (Reason=DependencyNeverSatisfied).
if ! merge_id=$(submit --job-name=pathwave-merge --dependency="afterok:$array_id" --kill-on-invalid-dep=yes \
  --chdir="$PWD" --output="$partdir/merge-%j.out" "$partdir/merge.sbatch"); then
  scancel "$array_id" 2>/dev/null || true
  die "sbatch refused the merge job (its message is above); cancelled render array $array_id"
fi
say "render array $array_id (tasks 0-$((parts - 1))) and merge job $merge_id submitted; logs in $partdir"
echo "render_job=$array_id"
echo "merge_job=$merge_id"
[ -n "$wait_for_merge" ] || exit 0

# ---- --wait: poll scontrol (works without accounting; finished jobs stay visible for the cluster's MinJobAge).

field() { # NAME, from one line of `scontrol show job -o`
  sed -n "s/.*[[:space:]]$1=\([^[:space:]]*\).*/\1/p" <<<" $2"
}

# The array's tasks that ended badly, one "TASK STATE EXITCODE" a line.
failed_tasks() {
  local line state
  while IFS= read -r line; do
    state=$(field JobState "$line")
    case $state in
      FAILED | CANCELLED | TIMEOUT | NODE_FAIL | OUT_OF_MEMORY | BOOT_FAIL | DEADLINE | PREEMPTED)
        echo "$(field ArrayTaskId "$line") $state $(field ExitCode "$line")"
        ;;
    esac
  done < <(scontrol show job -o "$array_id" 2>/dev/null || true)
}

fail() {
  say "error: $1"
  local task state code
  while read -r task state code; do
    say "render task ${array_id}_$task ended $state (exit code $code); tail of $partdir/render-${array_id}_$task.out:"
    tail -n 20 "$partdir/render-${array_id}_$task.out" >&2 2>/dev/null || say "(no log)"
  done < <(failed_tasks)
  if [ -s "$partdir/merge-$merge_id.out" ]; then
    say "tail of $partdir/merge-$merge_id.out:"
    tail -n 20 "$partdir/merge-$merge_id.out" >&2
  fi
  say "no image written; cancel what is left with: scancel $array_id $merge_id"
  exit 1
}

# Slurm without accounting forgets a job MinJobAge seconds after it ends; then only OUT itself can tell.
vanished() {
  if [ -f "$out" ] && [ "$out" -nt "$partdir/.submitted" ]; then
    say "wrote $out"
    exit 0
  fi
  local config final
  config=$(scontrol show config 2>/dev/null || true)
  if command -v sacct >/dev/null && ! grep -q 'AccountingStorageType *= *accounting_storage/none' <<<"$config"; then
    final=$(sacct -n -X -P -o State -j "$merge_id" 2>/dev/null | head -n 1 || true)
    fail "merge job $merge_id left the queue as ${final:-unknown}, and $out was not written"
  fi
  fail "merge job $merge_id left the queue without writing $out"
}

start=$SECONDS
while :; do
  if info=$(scontrol show job -o "$merge_id" 2>&1); then
    state=$(field JobState "$info")
    reason=$(field Reason "$info")
    case $state in
      COMPLETED)
        [ -f "$out" ] || fail "merge job $merge_id completed but $out does not exist"
        say "wrote $out in $((SECONDS - start)) s"
        exit 0
        ;;
      PENDING)
        # Without kill-on-invalid-dep (or before Slurm acts on it) a failed task leaves the merge pending for ever.
        [ "$reason" != DependencyNeverSatisfied ] || fail "a render task failed, so merge job $merge_id can never run"
        ;;
      CANCELLED)
        if [ "$reason" = DependencyNeverSatisfied ]; then
          fail "a render task failed, so Slurm cancelled merge job $merge_id"
        fi
        fail "merge job $merge_id was cancelled"
        ;;
      FAILED | TIMEOUT | NODE_FAIL | OUT_OF_MEMORY | BOOT_FAIL | DEADLINE | PREEMPTED)
        fail "merge job $merge_id ended $state (exit code $(field ExitCode "$info"))"
        ;;
    esac
  elif grep -qi 'invalid job id' <<<"$info"; then
    vanished
  fi
  # A task that failed while others still render would cancel the merge anyway; say so without waiting for them.
  [ -z "$(failed_tasks)" ] || fail "a render task failed, so merge job $merge_id will not run"
  if [ $((SECONDS - start)) -ge "$timeout_s" ]; then
    say "error: timed out after $timeout_s s (PATHWAVE_SUBMIT_TIMEOUT); merge job $merge_id is ${state:-unknown}"
    say "the jobs are still queued: watch them with squeue -j $array_id,$merge_id, or scancel $array_id $merge_id"
    exit 124
  fi
  sleep 2
done
