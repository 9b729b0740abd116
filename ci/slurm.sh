#!/usr/bin/env bash
# Owns a private one-node Slurm cluster (munged, slurmctld, slurmd) for testing examples/slurm on this machine.
#
#   bash ci/slurm.sh start    install slurm-wlm and munge if missing, write the config, start the daemons, wait until
#                             the node is idle; prints `export SLURM_CONF=...` on stdout (so: eval "$(... start)")
#   bash ci/slurm.sh stop     cancel every job, stop the daemons by their recorded process ids (safe to repeat)
#   bash ci/slurm.sh status   the daemons' pids and sinfo; exits 1 unless all three run
#   bash ci/slurm.sh env      prints `export SLURM_CONF=...`
#
# Everything (config, munge key and socket, state, spool, logs, pid files) lives in PATHWAVE_SLURM_DIR (default
# /tmp/pathwave-slurm), so nothing in /etc is touched beyond what apt installs, and the system's own munge/slurm
# services, if any, are neither used nor disturbed. Other settings: PATHWAVE_SLURM_PORT (slurmctld's port, default
# 6817; slurmd takes the next one), PATHWAVE_SLURM_START_TIMEOUT (seconds, default 60), PATHWAVE_SLURM_NO_INSTALL=1
# (fail instead of installing packages, for callers that must not change the machine).
set -euo pipefail

DIR=${PATHWAVE_SLURM_DIR:-/tmp/pathwave-slurm}
PORT=${PATHWAVE_SLURM_PORT:-6817}
START_TIMEOUT=${PATHWAVE_SLURM_START_TIMEOUT:-60}
CONF=$DIR/slurm.conf
DAEMONS=(munged slurmctld slurmd) # start order; stop goes in reverse
PACKAGES=(slurm-wlm munge)

say() { echo "ci/slurm.sh: $*" >&2; }
die() {
  say "error: $*"
  exit 1
}

# munged's socket path must fit in sockaddr_un (108 bytes), and slurm reads some paths unquoted.
case $DIR in
  /*) ;;
  *) DIR=$(pwd)/$DIR && CONF=$DIR/slurm.conf ;;
esac
[[ $DIR =~ ^[A-Za-z0-9_./-]+$ ]] || die "PATHWAVE_SLURM_DIR must be a plain path (letters, digits, _ . / -): $DIR"
[ ${#DIR} -le 80 ] || die "PATHWAVE_SLURM_DIR is too long for munge's socket path (80 characters at most): $DIR"

pidfile() { echo "$DIR/$1.pid"; }

# The pid recorded for daemon $1, if that process is still alive and still that daemon (pids get reused).
live_pid() {
  local f pid
  f=$(pidfile "$1")
  [ -f "$f" ] || return 1
  pid=$(cat "$f" 2>/dev/null) || return 1
  [[ $pid =~ ^[0-9]+$ ]] || return 1
  [ -r "/proc/$pid/cmdline" ] || return 1
  { tr '\0' ' ' <"/proc/$pid/cmdline"; } 2>/dev/null | grep -q -- "$1" || return 1
  echo "$pid"
}

log_tails() {
  local f
  for f in "$DIR"/log/*; do
    [ -s "$f" ] || continue
    # slurmctld and slurmd write their log file and, in the foreground, the same lines to their .out too.
    [[ $f != *.out ]] || [ ! -s "${f%.out}.log" ] || continue
    echo "----- tail of $f" >&2
    tail -n 25 "$f" >&2
  done
}

install_packages() {
  local missing=() p added_policy=
  for p in "${PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  [ "${PATHWAVE_SLURM_NO_INSTALL:-}" != 1 ] ||
    die "not installed: ${missing[*]} (PATHWAVE_SLURM_NO_INSTALL=1 forbids installing)"
  command -v apt-get >/dev/null || die "not installed: ${missing[*]}, and there is no apt-get to install them"
  SUDO=()
  [ "$(id -u)" -eq 0 ] || SUDO=(sudo)
  # The packages' postinst would start the system's munge/slurm services, which would then run on untracked. A
  # policy-rc.d that denies every start prevents that (Docker images ship one already); one we add is removed again.
  if [ ! -e /usr/sbin/policy-rc.d ]; then
    trap '"${SUDO[@]}" rm -f /usr/sbin/policy-rc.d' EXIT
    trap 'exit 130' INT TERM
    printf '#!/bin/sh\n# added by pathwave ci/slurm.sh while it installs packages\nexit 101\n' |
      "${SUDO[@]}" tee /usr/sbin/policy-rc.d >/dev/null
    "${SUDO[@]}" chmod 755 /usr/sbin/policy-rc.d
    added_policy=1
  fi
  mkdir -p "$DIR/log"
  local t0=$SECONDS apt_log=$DIR/log/apt.log
  say "installing ${missing[*]} with apt (log: $apt_log)"
  if ! { "${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -qq &&
    "${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}"; } \
    >"$apt_log" 2>&1; then
    tail -n 30 "$apt_log" >&2
    die "installing ${missing[*]} with apt failed (above: the end of $apt_log)"
  fi
  say "installed ${missing[*]} in $((SECONDS - t0)) s"
  if [ -n "$added_policy" ]; then
    "${SUDO[@]}" rm -f /usr/sbin/policy-rc.d
    trap - EXIT INT TERM
  fi
}

# The slurm binaries live in /usr/sbin, which a non-root PATH may lack.
find_bin() {
  local b
  b=$(PATH=$PATH:/usr/sbin:/sbin command -v "$1") || die "$1 not found after installing ${PACKAGES[*]}"
  echo "$b"
}

write_config() {
  local host cpus mem user
  host=$(hostname -s)
  cpus=$(nproc)
  mem=$(awk '/^MemTotal:/ { print int($2 / 1024) }' /proc/meminfo)
  user=$(id -un)
  mkdir -p "$DIR"/{state,spool,log,munge}
  # munged wants its socket directory searchable by all, or other users could not reach it.
  chmod 755 "$DIR/munge"
  cat >"$CONF.tmp" <<EOF
# Written by pathwave ci/slurm.sh: one node ($host), localhost only, no cgroups, no accounting.
ClusterName=pathwave
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$PORT
SlurmdPort=$((PORT + 1))
SlurmUser=$user
SlurmdUser=$user
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$DIR/munge/munge.socket
StateSaveLocation=$DIR/state
SlurmdSpoolDir=$DIR/spool
SlurmctldPidFile=$DIR/log/slurmctld.pidfile
SlurmdPidFile=$DIR/log/slurmd.pidfile
SlurmctldLogFile=$DIR/log/slurmctld.log
SlurmdLogFile=$DIR/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MpiDefault=none
MailProg=/bin/true
ReturnToService=2
# Several array tasks share the node, one core each by default, rather than the node going to one job at a time.
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
# Use the CPUs and memory below even if the hardware detected differs (a container's nproc is often less).
SlurmdParameters=config_overrides
# Finished jobs stay visible to scontrol for 10 minutes: without accounting that is how a waiting caller sees them.
MinJobAge=600
SlurmdTimeout=60
NodeName=$host NodeAddr=127.0.0.1 NodeHostname=$host CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
  mv "$CONF.tmp" "$CONF"
  # A key of our own: munge's system key (if any) is root's, and a fresh one per state dir keeps instances apart.
  if [ ! -s "$DIR/munge/munge.key" ]; then
    (umask 077 && head -c 1024 /dev/urandom >"$DIR/munge/munge.key")
  fi
  chmod 400 "$DIR/munge/munge.key"
}

# Starts daemon $1 as "$@" detached from the caller (its own session, stdio to a log file) and records its pid.
# stdout/stderr must not be the caller's: a test harness reading them would otherwise wait for the daemons' exit.
launch() {
  local name=$1
  shift
  # The marker lets stop find what the daemons forked (slurmstepd) without matching processes by name.
  PATHWAVE_SLURM_INSTANCE=$DIR SLURM_CONF=$CONF setsid "$@" </dev/null >>"$DIR/log/$name.out" 2>&1 &
  local pid=$!
  echo "$pid" >"$(pidfile "$name")"
  # Until the background shell has exec'd the daemon, its command line is this script's, and live_pid would take
  # it for a daemon that exited (a loaded CI machine once showed that window). Wait for the exec, or the exit.
  local _
  for _ in $(seq 100); do
    { tr '\0' ' ' <"/proc/$pid/cmdline"; } 2>/dev/null | grep -q -- "$name" && return 0
    [ -e "/proc/$pid" ] || return 0
    sleep 0.05
  done
}

node_state() { SLURM_CONF=$CONF timeout 10 sinfo -h -N -o '%T' 2>/dev/null | head -n 1; }

start() {
  # Any answer will do: a node busy with jobs is not idle, and restarting would kill them.
  local state
  if [ "$(running_count)" -eq ${#DAEMONS[@]} ] && state=$(node_state) && [ -n "$state" ]; then
    say "already running in $DIR (node $state)"
    echo "export SLURM_CONF=$CONF"
    return 0
  fi
  stop_daemons quiet # a partial or stale instance: begin afresh
  install_packages
  local munged slurmctld slurmd
  munged=$(find_bin munged)
  slurmctld=$(find_bin slurmctld)
  slurmd=$(find_bin slurmd)
  write_config
  local t0=$SECONDS
  launch munged "$munged" --foreground --force --key-file="$DIR/munge/munge.key" --socket="$DIR/munge/munge.socket" \
    --pid-file="$DIR/munge/munged.pid" --seed-file="$DIR/munge/munged.seed"
  for _ in $(seq 50); do
    [ -S "$DIR/munge/munge.socket" ] && break
    live_pid munged >/dev/null || break
    sleep 0.1
  done
  [ -S "$DIR/munge/munge.socket" ] || fail_start "munged did not create its socket"
  # -c: begin with no jobs, whatever an earlier instance left in the state directory.
  launch slurmctld "$slurmctld" -D -c -f "$CONF"
  launch slurmd "$slurmd" -D -f "$CONF" -N "$(hostname -s)"
  state=
  while [ $((SECONDS - t0)) -lt "$START_TIMEOUT" ]; do
    local d
    for d in "${DAEMONS[@]}"; do
      live_pid "$d" >/dev/null || fail_start "$d exited during start"
    done
    state=$(node_state)
    [ "$state" = idle ] && break
    sleep 0.5
  done
  [ "$state" = idle ] ||
    fail_start "the node is not idle after ${START_TIMEOUT} s (state: ${state:-no answer from slurmctld})"
  say "started munged, slurmctld, slurmd in $((SECONDS - t0)) s; config $CONF"
  echo "export SLURM_CONF=$CONF"
}

fail_start() {
  say "error: start failed: $1"
  SLURM_CONF=$CONF timeout 10 sinfo -R >&2 2>/dev/null || true
  log_tails
  stop_daemons quiet
  exit 1
}

running_count() {
  local d n=0
  for d in "${DAEMONS[@]}"; do
    live_pid "$d" >/dev/null && n=$((n + 1))
  done
  echo $n
}

# Processes that carry this instance's marker in their environment: the daemons and the slurmstepd they fork.
instance_pids() {
  local e pid
  for e in /proc/[0-9]*/environ; do
    pid=${e#/proc/}
    pid=${pid%/environ}
    [ "$pid" = $$ ] && continue
    { tr '\0' '\n' <"$e"; } 2>/dev/null | grep -qxF "PATHWAVE_SLURM_INSTANCE=$DIR" && echo "$pid"
  done
  return 0
}

wait_gone() { # pid, seconds
  local i
  for ((i = 0; i < $2 * 10; i++)); do
    kill -0 "$1" 2>/dev/null || return 0
    # An exited daemon stays a zombie until the container's init reaps it, which some never do.
    [ "$(awk '{ print $3 }' "/proc/$1/stat" 2>/dev/null)" != Z ] || return 0
    sleep 0.1
  done
  return 1
}

stop_daemons() {
  local quiet=${1:-} pid d i
  # Jobs first, so that slurmd's job steps end with it rather than run on without their daemon.
  if pid=$(live_pid slurmctld) && live_pid slurmd >/dev/null; then
    local jobs
    mapfile -t jobs < <(SLURM_CONF=$CONF timeout 10 squeue -h -o %i 2>/dev/null || true)
    if [ ${#jobs[@]} -gt 0 ]; then
      [ -n "$quiet" ] || say "cancelling jobs: ${jobs[*]}"
      SLURM_CONF=$CONF timeout 10 scancel "${jobs[@]}" 2>/dev/null || true
      for ((i = 0; i < 150; i++)); do
        [ -z "$(SLURM_CONF=$CONF timeout 10 squeue -h -o %i 2>/dev/null || true)" ] && break
        sleep 0.2
      done
    fi
  fi
  for ((i = ${#DAEMONS[@]} - 1; i >= 0; i--)); do
    d=${DAEMONS[i]}
    if pid=$(live_pid "$d"); then
      [ -n "$quiet" ] || say "stopping $d (pid $pid)"
      kill -TERM "$pid" 2>/dev/null || true
      if ! wait_gone "$pid" 20; then
        say "$d (pid $pid) ignored SIGTERM for 20 s; killing it"
        kill -KILL "$pid" 2>/dev/null || true
        wait_gone "$pid" 5 || say "warning: $d (pid $pid) is still alive"
      fi
    fi
    rm -f "$(pidfile "$d")"
  done
  for pid in $(instance_pids); do
    say "killing leftover process $pid ($({ tr '\0' ' ' <"/proc/$pid/cmdline"; } 2>/dev/null || echo gone))"
    kill -KILL "$pid" 2>/dev/null || true
  done
}

status() {
  local d pid ok=0
  for d in "${DAEMONS[@]}"; do
    if pid=$(live_pid "$d"); then
      echo "$d: running, pid $pid"
    else
      echo "$d: not running"
      ok=1
    fi
  done
  if [ $ok -eq 0 ]; then
    echo "SLURM_CONF=$CONF"
    SLURM_CONF=$CONF timeout 10 sinfo || ok=1
  fi
  return $ok
}

case ${1:-} in
  start) start ;;
  stop)
    stop_daemons
    say "stopped (state in $DIR)"
    ;;
  status) status ;;
  env) echo "export SLURM_CONF=$CONF" ;;
  *)
    echo "usage: $0 start|stop|status|env" >&2
    exit 2
    ;;
esac
