#!/usr/bin/env bash
# A real one-node Slurm cluster on this machine, for tests: Debian's slurm-wlm
# and munge packages (tools/setup.sh installs them), daemons started directly
# (no systemd in CI), everything in a private state directory so it touches
# neither /etc/slurm nor a system munged. Needs root (slurmd runs the jobs).
#
#   tools/slurm-local.sh start    start munged, slurmctld, slurmd from a clean job
#                                 state; wait (60 s at most) until the node is idle
#                                 (idempotent: exits 0 if it already runs and is idle)
#   tools/slurm-local.sh stop     cancel every job, stop the three daemons (logs stay)
#   tools/slurm-local.sh status   sinfo and squeue
#   tools/slurm-local.sh env      the line below, for eval
#
# Clients (sbatch, squeue, sinfo, scancel, scontrol) find the cluster through
# SLURM_CONF; start and env print, on stdout and alone there, the line
#   export SLURM_CONF=$SANDTABLE_SLURM_DIR/etc/slurm.conf
# so `eval "$(tools/slurm-local.sh start)"` starts it and sets the variable.
#
# SANDTABLE_SLURM_DIR  state directory (default /tmp/sandtable-slurm)
# SANDTABLE_SLURM_PORT slurmctld port, slurmd uses the next one (default 6817)
set -euo pipefail

dir=${SANDTABLE_SLURM_DIR:-/tmp/sandtable-slurm}
case $dir in /*) ;; *) dir=$PWD/$dir ;; esac
port=${SANDTABLE_SLURM_PORT:-6817}
conf=$dir/etc/slurm.conf
sock=$dir/munge/munge.socket.2
node=$(hostname -s)
export SLURM_CONF=$conf
timeout_s=60

log() { echo "slurm-local: $*" >&2; }
die() { log "$*"; exit 1; }

pid_file() {
  case $1 in
    munged) echo "$dir/munge/munged.pid" ;;
    *) echo "$dir/run/$1.pid" ;;
  esac
}

# Whether process $1 runs and is $2: not a zombie (PID 1 of a container may
# reap late) and not a reused pid.
pid_is() {
  local stat
  [[ $1 =~ ^[0-9]+$ ]] || return 1
  stat=$(cat "/proc/$1/stat" 2>/dev/null) || return 1
  [[ $stat == "$1 ($2) "* ]] && [[ ${stat#*) } != Z* ]]
}

# The pid of daemon $1 when it is alive, else nothing (and status 1).
alive() {
  local pid
  pid=$(cat "$(pid_file "$1")" 2>/dev/null) || return 1
  pid_is "$pid" "$1" || return 1
  echo "$pid"
}

node_state() { sinfo -h -n "$node" -o %t 2>/dev/null | head -n1 || true; }

show_logs() {
  local f
  for f in "$dir"/log/*.log; do
    [ -f "$f" ] || continue
    echo "==> $f <==" >&2
    tail -n 25 "$f" >&2
  done
}

# Waits (bounded) until the node is idle; resumes it when it comes up down or
# drained (the reason is printed first).
wait_idle() {
  local deadline=$((SECONDS + timeout_s)) state
  while :; do
    state=$(node_state)
    case $state in
      idle) return 0 ;;
      down | drain | drng | drained | fail | inval)
        log "node $node is $state ($(sinfo -h -n "$node" -o %E 2>/dev/null)); resuming it"
        scontrol update nodename="$node" state=resume >&2 || true ;;
    esac
    if [ $SECONDS -ge $deadline ]; then
      log "node $node not idle after ${timeout_s}s (state '${state}')"
      sinfo >&2 || true
      show_logs
      return 1
    fi
    sleep 0.5
  done
}

write_conf() {
  local cpus mem_mb
  cpus=$(nproc)
  mem_mb=$(awk '/^MemTotal:/ { print int($2 / 1024 * 0.95) }' /proc/meminfo)
  cat >"$conf" <<EOF
# Written by tools/slurm-local.sh: a one-node test cluster; rewritten by each start.
ClusterName=sandtable
SlurmctldHost=$node(127.0.0.1)
SlurmctldPort=$port
SlurmdPort=$((port + 1))
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$sock
MpiDefault=none
MailProg=/bin/true
ProctrackType=proctrack/pgid
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/backfill
# Start a job on submit or on a freed CPU at once, not after up to 3 s.
SchedulerParameters=batch_sched_delay=0
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
# The node is what this file says (no drain for a hardware mismatch).
SlurmdParameters=config_overrides
ReturnToService=2
SlurmctldTimeout=30
SlurmdTimeout=30
KillWait=5
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/run/slurmctld.pid
SlurmdPidFile=$dir/run/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
NodeName=$node NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$mem_mb State=UNKNOWN
PartitionName=debug Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF
}

start_munged() {
  local key=$dir/munge/munge.key i
  if [ ! -s "$key" ]; then
    if command -v mungekey >/dev/null 2>&1; then
      mungekey --create --keyfile="$key" --force
    else
      dd if=/dev/urandom of="$key" bs=1024 count=1 status=none
    fi
  fi
  chmod 0400 "$key"
  rm -f "$sock" "$sock.lock"
  munged --force --key-file="$key" --socket="$sock" --pid-file="$(pid_file munged)" \
    --log-file="$dir/log/munged.log" --seed-file="$dir/munge/munged.seed" \
    </dev/null >>"$dir/log/munged.out" 2>&1 || { show_logs; die "munged did not start"; }
  for ((i = 0; i < 50; i++)); do
    munge -n -S "$sock" 2>/dev/null | unmunge -S "$sock" >/dev/null 2>&1 && return 0
    sleep 0.2
  done
  show_logs
  die "munged does not answer on $sock"
}

start() {
  [ "$(id -u)" -eq 0 ] || die "needs root (slurmd runs jobs as their users)"
  local d
  for d in slurmctld slurmd munged sinfo; do
    command -v "$d" >/dev/null || die "$d missing: apt-get install slurm-wlm munge (tools/setup.sh)"
  done

  local running=0
  for d in munged slurmctld slurmd; do alive "$d" >/dev/null && running=$((running + 1)); done
  if [ $running -eq 3 ] && [ -f "$conf" ]; then
    wait_idle || exit 1
    log "already running, node $node idle"
    echo "export SLURM_CONF=$conf"
    return 0
  fi
  if [ $running -gt 0 ]; then
    log "partly running; restarting"
    stop
  fi

  local t0=$SECONDS
  mkdir -p "$dir"/{etc,munge,run,log}
  chmod 0755 "$dir"
  chmod 0711 "$dir/munge"  # clients of every user reach the socket; the key stays 0400
  # A clean slate: no jobs or node states recovered from an earlier run.
  rm -rf "$dir/state" "$dir/spool"
  mkdir -p "$dir/state" "$dir/spool"
  rm -f "$dir"/run/*.pid
  write_conf

  start_munged
  slurmctld -f "$conf" </dev/null >>"$dir/log/slurmctld.out" 2>&1 || { show_logs; die "slurmctld did not start"; }
  local deadline=$((SECONDS + timeout_s))
  until scontrol ping 2>/dev/null | grep -q 'is UP'; do
    if [ $SECONDS -ge $deadline ]; then show_logs; die "slurmctld does not answer"; fi
    sleep 0.3
  done
  slurmd -f "$conf" -N "$node" </dev/null >>"$dir/log/slurmd.out" 2>&1 || { show_logs; die "slurmd did not start"; }
  wait_idle || exit 1
  log "started in $((SECONDS - t0))s: node $node idle, logs in $dir/log"
  echo "export SLURM_CONF=$conf"
}

# Stops daemon $1 (SIGTERM, then SIGKILL after 15 s).
stop_one() {
  local pid i
  pid=$(alive "$1") || return 0
  kill -TERM "$pid" 2>/dev/null || true
  for ((i = 0; i < 150; i++)); do
    pid_is "$pid" "$1" || { rm -f "$(pid_file "$1")"; log "stopped $1 ($pid)"; return 0; }
    sleep 0.1
  done
  log "$1 ($pid) ignored SIGTERM; killing it"
  kill -KILL "$pid" 2>/dev/null || true
  rm -f "$(pid_file "$1")"
}

stop() {
  local i
  if alive slurmctld >/dev/null && [ -f "$conf" ]; then
    # Jobs outlive slurmd (slurmstepd is its own process): cancel them first.
    scancel --partition=debug 2>/dev/null || true
    for ((i = 0; i < 50; i++)); do
      [ -z "$(squeue -h -t running,completing -o %i 2>/dev/null)" ] && break
      sleep 0.2
    done
  fi
  stop_one slurmd
  stop_one slurmctld
  stop_one munged
}

status() {
  local d pid
  for d in munged slurmctld slurmd; do
    if pid=$(alive "$d"); then echo "$d: running ($pid)"; else echo "$d: not running"; fi
  done
  if alive slurmctld >/dev/null; then
    sinfo
    squeue
  fi
}

case ${1:-} in
  start) start ;;
  stop) stop ;;
  status) status ;;
  env) echo "export SLURM_CONF=$conf" ;;
  *) echo "usage: $0 start|stop|status|env  (state in \$SANDTABLE_SLURM_DIR, default /tmp/sandtable-slurm)" >&2; exit 2 ;;
esac
