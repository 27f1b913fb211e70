#!/usr/bin/env bash
# ci/slurm-up.sh - bring up a private one-node Slurm cluster on localhost.
#
# Starts munged, slurmctld and slurmd WITHOUT systemd, each in its own session,
# all configured from a private state dir, and waits until the node is idle.
#
#   State dir : ${LIGHTVOL_SLURM_DIR:-/tmp/lightvol-slurm}
#   Config    : $STATE/slurm.conf            (Slurm clients need SLURM_CONF)
#   Env file  : $STATE/env                   (". $STATE/env" sets SLURM_CONF)
#   Job log   : $STATE/jobcomp.txt           (one line per finished job)
#   Our PIDs  : $STATE/pids/{munged,slurmctld,slurmd}   ("PID STARTTIME")
#   Logs      : $STATE/log/
#
# Usage:
#   ci/slurm-up.sh && . "${LIGHTVOL_SLURM_DIR:-/tmp/lightvol-slurm}/env"
#   eval "$(ci/slurm-up.sh --print-env)"   # exports on stdout, summary on stderr
#
# Needs root (installs packages, runs slurmd, drops munged to user munge).
# Idempotent: if the daemons it recorded are still alive and the node answers,
# it starts nothing.  Stale state (dead daemons) is stopped and replaced.
# Tear down with ci/slurm-down.sh.
#
# Tunables (environment):
#   LIGHTVOL_SLURM_DIR        state dir                 (/tmp/lightvol-slurm)
#   LIGHTVOL_SLURM_TIMEOUT    seconds to wait for idle  (60)
#   LIGHTVOL_SLURMCTLD_PORT   slurmctld port            (6817)
#   LIGHTVOL_SLURMD_PORT      slurmd port               (6818)
#
# Concurrent calls (e.g. parallel tests each "ensuring" the cluster) are
# serialised with flock on $STATE.lock, which stays behind (an empty file).
# The state dir and all its parents must be world-searchable (munged checks).
set -euo pipefail

HERE=$(cd "$(dirname "$0")" && pwd)

STATE=${LIGHTVOL_SLURM_DIR:-/tmp/lightvol-slurm}
TIMEOUT=${LIGHTVOL_SLURM_TIMEOUT:-60}
CTLD_PORT=${LIGHTVOL_SLURMCTLD_PORT:-6817}
SLURMD_PORT=${LIGHTVOL_SLURMD_PORT:-6818}
PRINT_ENV=0

case "${1:-}" in
  --print-env) PRINT_ENV=1 ;;
  "") ;;
  -h|--help) sed -n '2,31p' "$0"; exit 0 ;;
  *) echo "slurm-up: unknown argument: $1" >&2; exit 2 ;;
esac

die() { echo "slurm-up: error: $*" >&2; exit 1; }

# The one-line summary goes to stdout, or to stderr with --print-env (so
# stdout carries nothing but export lines for eval).
summary() {
  if [ "$PRINT_ENV" = 1 ]; then
    echo "$*" >&2
    cat "$STATE/env"
  else
    echo "$*"
  fi
}

[ "$(id -u)" = 0 ] || die "must run as root (packages, slurmd, munge user)"

# One slurm-up/slurm-down at a time per state dir.  slurm-down.sh, when run
# from here, sees LIGHTVOL_SLURM_LOCKED=1 and does not lock again.  The
# daemons must not inherit fd 9, or they would hold the lock forever.
if [ "${LIGHTVOL_SLURM_LOCKED:-0}" != 1 ]; then
  mkdir -p "$(dirname "$STATE")"
  exec 9>"$STATE.lock"
  flock -w 300 9 || die "could not lock $STATE.lock within 300 s"
  export LIGHTVOL_SLURM_LOCKED=1
fi

# ---------------------------------------------------------------- processes --
# A recorded daemon is "PID STARTTIME"; STARTTIME (field 22 of /proc/PID/stat)
# protects against PID reuse, so we never signal a process we did not start.
proc_start() {
  local stat fld
  stat=$(cat "/proc/$1/stat" 2>/dev/null) || return 1
  stat=${stat##*) }            # drop "pid (comm) " - comm may contain spaces
  read -r -a fld <<<"$stat"    # fld[0] is field 3 (state), fld[19] field 22
  [ "${fld[0]}" != Z ] || return 1   # a zombie is dead (PID 1 may reap it late)
  echo "${fld[19]}"
}

# alive NAME: true if the daemon recorded under NAME is still our process.
alive() {
  local f="$STATE/pids/$1" pid st
  [ -r "$f" ] || return 1
  read -r pid st <"$f" || return 1
  [ -n "${pid:-}" ] && [ "$(proc_start "$pid" 2>/dev/null)" = "$st" ]
}

# ----------------------------------------------------------------- packages --
need_install=0
for c in munged munge unmunge slurmctld slurmd sinfo sbatch scontrol; do
  command -v "$c" >/dev/null 2>&1 || need_install=1
done
if [ "$need_install" = 1 ]; then
  # Keep the packages' maintainer scripts from starting system daemons: a
  # policy-rc.d that denies everything, only if the host has none of its own.
  tmp_policy=""
  if [ ! -e /usr/sbin/policy-rc.d ]; then
    tmp_policy=/usr/sbin/policy-rc.d
    printf '#!/bin/sh\nexit 101\n' >"$tmp_policy"
    chmod 755 "$tmp_policy"
    trap 'rm -f "$tmp_policy"' EXIT
  fi
  export DEBIAN_FRONTEND=noninteractive
  log=$(mktemp)
  if ! { apt-get update -q && apt-get install -y -q --no-install-recommends \
           slurm-wlm munge; } >"$log" 2>&1; then
    tail -n 30 "$log" >&2
    die "apt-get install slurm-wlm munge failed"
  fi
  rm -f "$log"
  if [ -n "$tmp_policy" ]; then rm -f "$tmp_policy"; trap - EXIT; fi
fi
command -v setpriv >/dev/null 2>&1 || die "setpriv (util-linux) not found"
getent passwd munge >/dev/null || die "user munge missing (munge package broken?)"

# ------------------------------------------------------------- idempotency --
NODE=$(hostname -s 2>/dev/null || hostname)
[ -n "$NODE" ] || die "cannot determine the short hostname"

if alive munged && alive slurmctld && alive slurmd && [ -r "$STATE/slurm.conf" ] &&
   up_state=$(SLURM_CONF=$STATE/slurm.conf timeout 10 sinfo -h -N -n "$NODE" -o %T 2>/dev/null) &&
   case "$up_state" in idle|mixed|allocated|completing) true ;; *) false ;; esac; then
  # Running jobs (mixed/allocated) are fine: do not disturb them.
  summary "slurm-up: already up (node $NODE $up_state); SLURM_CONF=$STATE/slurm.conf (or: . $STATE/env)"
  exit 0
fi

# Something is missing or dead: stop whatever of ours is left, start afresh.
if [ -d "$STATE" ]; then
  "$HERE/slurm-down.sh" >/dev/null
fi

# Refuse to run next to a foreign Slurm on the same ports.
for p in "$CTLD_PORT" "$SLURMD_PORT"; do
  if (exec 3<>"/dev/tcp/127.0.0.1/$p") 2>/dev/null; then
    die "port $p already in use (another Slurm?); set LIGHTVOL_SLURMCTLD_PORT/LIGHTVOL_SLURMD_PORT"
  fi
done

# ---------------------------------------------------------------- state dir --
mkdir -p "$STATE"
: >"$STATE/.lightvol-slurm"   # marks the dir as ours for slurm-down.sh
chmod 755 "$STATE"            # munged checks every dir on its socket's path
mkdir -p "$STATE/pids" "$STATE/run" "$STATE/log" "$STATE/ctld" "$STATE/spool" "$STATE/munge"

# Private munge instance: own key (0400, owned by munge), socket and seed;
# in --foreground mode munged logs to stderr, i.e. $STATE/log/munged.out.
# The dir must be world-searchable (munged checks) but only munge-writable.
chown munge:munge "$STATE/munge"
chmod 755 "$STATE/munge"
setpriv --reuid=munge --regid=munge --init-groups -- \
  mungekey --create --keyfile="$STATE/munge/munge.key" >/dev/null 2>&1 ||
  die "mungekey --create failed"
chmod 400 "$STATE/munge/munge.key"
MUNGE_SOCK=$STATE/munge/munge.socket

# Node hardware exactly as slurmd sees it: "slurmd -C" prints a NodeName=...
# line (plus an UpTime= line that we drop).  A RealMemory above what slurmd
# measures marks the node INVAL, so take its value and shave 1% for safety.
hw=$(slurmd -C 2>/dev/null | grep '^NodeName=' | head -n 1) || true
[ -n "$hw" ] || die "slurmd -C printed no NodeName line"
hw_val() { printf '%s\n' "$hw" | tr ' ' '\n' | sed -n "s/^$1=//p"; }
CPUS=$(hw_val CPUs); BOARDS=$(hw_val Boards); SPB=$(hw_val SocketsPerBoard)
CPS=$(hw_val CoresPerSocket); TPC=$(hw_val ThreadsPerCore); MEM=$(hw_val RealMemory)
MEM=$(( MEM * 99 / 100 )); [ "$MEM" -ge 1 ] || MEM=1

cat >"$STATE/slurm.conf" <<EOF
# Generated by ci/slurm-up.sh - private one-node cluster; do not edit.
ClusterName=lightvol
SlurmctldHost=$NODE(127.0.0.1)
SlurmctldPort=$CTLD_PORT
SlurmdPort=$SLURMD_PORT
# Everything runs as root: no ownership games with the state dir.
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$MUNGE_SOCK
StateSaveLocation=$STATE/ctld
SlurmdSpoolDir=$STATE/spool
SlurmctldPidFile=$STATE/run/slurmctld.pid
SlurmdPidFile=$STATE/run/slurmd.pid
SlurmctldLogFile=$STATE/log/slurmctld.log
SlurmdLogFile=$STATE/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
PlugStackConfig=$STATE/plugstack.conf
# No cgroups (containers, gVisor): plain /proc process tracking, no binding.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
# No slurmdbd, so sacct does not work: finished jobs are written here, one
# "key=value ..." line each (JobId, JobState, ExitCode, ArrayJobId, ...).
JobCompType=jobcomp/filetxt
JobCompLoc=$STATE/jobcomp.txt
MailProg=/bin/true
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/backfill
# Schedule at every event, with no batching delay, and rescan all pending
# jobs every second (defaults: 3 s batch delay, 60 s main loop, 30 s backfill).
SchedulerParameters=batch_sched_delay=0,sched_min_interval=0,sched_interval=1,bf_interval=1,default_queue_depth=1000
# Keep finished jobs in memory for "scontrol show job" (default 300 s).
MinJobAge=86400
MaxJobCount=100000
MaxArraySize=100001
# Short timeouts: everything is on localhost.
MessageTimeout=10
SlurmdTimeout=60
SlurmctldTimeout=60
InactiveLimit=0
KillWait=2
CompleteWait=0
Waittime=0
ReturnToService=2
NodeName=$NODE NodeAddr=127.0.0.1 NodeHostname=$NODE CPUs=$CPUS Boards=$BOARDS SocketsPerBoard=$SPB CoresPerSocket=$CPS ThreadsPerCore=$TPC RealMemory=$MEM State=UNKNOWN
PartitionName=debug Nodes=$NODE Default=YES MaxTime=INFINITE State=UP
EOF
: >"$STATE/plugstack.conf"    # keep /etc/slurm/plugstack.conf.d out
printf 'export SLURM_CONF=%s\nexport LIGHTVOL_SLURM_DIR=%s\n' \
  "$STATE/slurm.conf" "$STATE" >"$STATE/env"
export SLURM_CONF=$STATE/slurm.conf

# ------------------------------------------------------------------ daemons --
# start NAME CMD...: run CMD in the foreground mode of the daemon, in a new
# session (so the caller's job control / Ctrl-C / process-group kills do not
# reach it), and record "PID STARTTIME".  A non-interactive shell's background
# child is no process-group leader, so setsid execs instead of forking and $!
# is the daemon itself (checked below by its comm name).
start() {
  local name=$1; shift
  setsid "$@" </dev/null >>"$STATE/log/$name.out" 2>&1 9>&- &
  local pid=$! st
  st=$(proc_start "$pid") || fail "$name exited at once"
  echo "$pid $st" >"$STATE/pids/$name"
}

fail() {  # print why, the logs' tails, stop what we started, keep the logs
  echo "slurm-up: error: $*" >&2
  local f
  for f in "$STATE"/log/*; do
    [ -s "$f" ] || continue
    echo "----- tail $f" >&2
    tail -n 20 "$f" >&2
  done
  if [ -r "$STATE/slurm.conf" ]; then
    echo "----- sinfo" >&2; timeout 5 sinfo -N -l >&2 2>&1 || true
  fi
  LIGHTVOL_SLURM_KEEP_STATE=1 "$HERE/slurm-down.sh" >/dev/null 2>&1 || true
  echo "slurm-up: daemons stopped; logs kept in $STATE/log (ci/slurm-down.sh removes them)" >&2
  exit 1
}

t0=$(date +%s.%N)
deadline=$(( $(date +%s) + TIMEOUT ))
# wait_for NAME WHAT CMD...: poll CMD until it succeeds, the deadline passes,
# or the daemon recorded under NAME dies.
wait_for() {
  local name=$1 what=$2; shift 2
  until "$@" >/dev/null 2>&1; do
    alive "$name" || fail "$name died while waiting for $what"
    [ "$(date +%s)" -lt "$deadline" ] || fail "timed out after ${TIMEOUT}s waiting for $what"
    sleep 0.2
  done
}

munge_ok() { munge -n -S "$MUNGE_SOCK" | unmunge -S "$MUNGE_SOCK"; }
node_idle() { [ "$(timeout 5 sinfo -h -N -n "$NODE" -o %T)" = idle ]; }
comm_is() {  # comm_is NAME PREFIX: the recorded pid has exec'd the daemon
  local pid st; read -r pid st <"$STATE/pids/$1"
  case "$(cat "/proc/$pid/comm" 2>/dev/null)" in "$2"*) return 0 ;; esac
  return 1
}

cd /    # daemons must not pin the caller's working directory
start munged setpriv --reuid=munge --regid=munge --init-groups -- \
  munged --foreground --socket="$MUNGE_SOCK" --key-file="$STATE/munge/munge.key" \
  --pid-file="$STATE/munge/munged.pid" --seed-file="$STATE/munge/munged.seed"
wait_for munged "munged to exec" comm_is munged munged
wait_for munged "munged to answer" munge_ok

# -i: ignore (nonexistent) saved state; the state dir is fresh anyway.
start slurmctld slurmctld -D -i -f "$STATE/slurm.conf"
wait_for slurmctld "slurmctld to exec" comm_is slurmctld slurmctld
# Start slurmd only once slurmctld answers: a slurmd whose first registration
# finds no controller retries only a second later.
wait_for slurmctld "slurmctld to answer" timeout 5 scontrol ping
start slurmd slurmd -D -N "$NODE" -f "$STATE/slurm.conf"
wait_for slurmd "slurmd to exec" comm_is slurmd slurmd
wait_for slurmd "node $NODE to become idle" node_idle

t1=$(date +%s.%N)
summary "slurm-up: node $NODE idle ($CPUS CPUs) in $(awk "BEGIN { printf \"%.1f\", $t1 - $t0 }")s; SLURM_CONF=$STATE/slurm.conf (or: . $STATE/env)"
