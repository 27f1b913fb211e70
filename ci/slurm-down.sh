#!/usr/bin/env bash
# ci/slurm-down.sh - stop the one-node Slurm cluster started by ci/slurm-up.sh.
#
# Stops exactly the daemons recorded in $STATE/pids/ (slurmd, slurmctld,
# munged) by PID - TERM, wait, then KILL - and removes the state dir.  Other
# Slurm or munge daemons on the machine are never touched.  Safe to run when
# nothing is up.
#
#   LIGHTVOL_SLURM_DIR          state dir (/tmp/lightvol-slurm), as for slurm-up
#   LIGHTVOL_SLURM_KEEP_STATE=1 stop the daemons but keep the dir (logs)
#
# The lock file $STATE.lock (shared with slurm-up.sh) is left in place.
set -euo pipefail

STATE=${LIGHTVOL_SLURM_DIR:-/tmp/lightvol-slurm}
MARK="$STATE/.lightvol-slurm"     # written by slurm-up.sh before anything else

# Serialise with slurm-up.sh (which sets LIGHTVOL_SLURM_LOCKED=1 when it
# calls us while holding the lock itself).
if [ "${LIGHTVOL_SLURM_LOCKED:-0}" != 1 ] && [ -d "$(dirname "$STATE")" ]; then
  exec 9>"$STATE.lock"
  flock -w 300 9 || { echo "slurm-down: error: could not lock $STATE.lock" >&2; exit 1; }
fi

if [ ! -d "$STATE" ]; then
  echo "slurm-down: nothing up ($STATE absent)"
  exit 0
fi
if [ ! -e "$MARK" ]; then
  # Not ours: never rm -rf a directory slurm-up.sh did not create.
  rmdir "$STATE" 2>/dev/null && { echo "slurm-down: nothing up (removed empty $STATE)"; exit 0; }
  echo "slurm-down: error: $STATE exists but was not made by slurm-up.sh; not touching it" >&2
  exit 1
fi

# Start time (field 22 of /proc/PID/stat) of PID; guards against PID reuse.
proc_start() {
  local stat fld
  stat=$(cat "/proc/$1/stat" 2>/dev/null) || return 1
  stat=${stat##*) }            # drop "pid (comm) " - comm may contain spaces
  read -r -a fld <<<"$stat"    # fld[0] is field 3 (state), fld[19] field 22
  [ "${fld[0]}" != Z ] || return 1   # a zombie is dead (PID 1 may reap it late)
  echo "${fld[19]}"
}

# pid_of NAME: print the recorded PID if that process is still the one we
# started (same start time); fail otherwise.
pid_of() {
  local f="$STATE/pids/$1" pid st
  [ -r "$f" ] || return 1
  read -r pid st <"$f" || return 1
  [ -n "${pid:-}" ] && [ "$(proc_start "$pid" 2>/dev/null)" = "$st" ] && echo "$pid"
}

stopped=()

# stop NAME...: TERM the named daemons, wait up to 10 s, KILL what is left.
stop() {
  local name pid pids=()
  for name in "$@"; do
    if pid=$(pid_of "$name"); then
      kill -TERM "$pid" 2>/dev/null || true
      pids+=("$name:$pid")
    fi
  done
  [ "${#pids[@]}" -gt 0 ] || return 0
  for _ in $(seq 50); do
    local left=0
    for name in "${pids[@]}"; do
      pid_of "${name%%:*}" >/dev/null && left=1
    done
    [ "$left" = 0 ] && break
    sleep 0.2
  done
  for name in "${pids[@]}"; do
    if pid=$(pid_of "${name%%:*}"); then
      kill -KILL "$pid" 2>/dev/null || true
    fi
    stopped+=("${name%%:*}")
  done
  # Give KILLed processes a moment to disappear.
  for _ in $(seq 25); do
    local left=0
    for name in "${pids[@]}"; do
      pid_of "${name%%:*}" >/dev/null && left=1
    done
    [ "$left" = 0 ] && break
    sleep 0.2
  done
}

# 1. Cancel jobs still queued or running on our cluster, so no slurmstepd or
#    job processes outlive the daemons.  Best effort, only if our ctld is up.
if pid_of slurmctld >/dev/null && [ -r "$STATE/slurm.conf" ]; then
  export SLURM_CONF=$STATE/slurm.conf
  jobs=$(timeout 10 squeue -h -o %F 2>/dev/null | sort -u) || jobs=""
  if [ -n "$jobs" ]; then
    # shellcheck disable=SC2086
    timeout 10 scancel $jobs >/dev/null 2>&1 || true
    for _ in $(seq 25); do
      [ -z "$(timeout 5 squeue -h -o %A 2>/dev/null)" ] && break
      sleep 0.2
    done
  fi
fi

# 2. Slurm daemons first (they talk to munged while shutting down), then munged.
stop slurmd slurmctld
stop munged

# 3. Leftovers of a job that would not die (normally scancel above ended them):
#    slurmstepd inherits SLURM_CONF=$STATE/slurm.conf from our slurmd, and job
#    processes get it too, plus SLURM_JOB_ID; that pair identifies them.  Plain
#    shells that merely sourced $STATE/env have no SLURM_JOB_ID and are spared,
#    and so are this script and its ancestors.
ancestors=" "
p=$$
while [ -n "$p" ] && [ "$p" -gt 1 ]; do
  ancestors+="$p "
  p=$(awk '{ sub(/.*\) /, ""); print $2 }' "/proc/$p/stat" 2>/dev/null) || break
done
for d in /proc/[0-9]*; do
  pid=${d#/proc/}
  case "$ancestors" in *" $pid "*) continue ;; esac
  grep -qzxF "SLURM_CONF=$STATE/slurm.conf" "$d/environ" 2>/dev/null || continue
  comm=$(cat "$d/comm" 2>/dev/null) || continue
  if [ "$comm" = slurmstepd ] || grep -qz '^SLURM_JOB_ID=' "$d/environ" 2>/dev/null; then
    kill -KILL "$pid" 2>/dev/null && stopped+=("$comm:$pid")
  fi
done

if [ "${LIGHTVOL_SLURM_KEEP_STATE:-0}" = 1 ]; then
  echo "slurm-down: stopped ${stopped[*]:-nothing}; kept $STATE"
else
  rm -rf -- "$STATE"
  echo "slurm-down: stopped ${stopped[*]:-nothing}; removed $STATE"
fi
