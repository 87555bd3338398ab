#!/usr/bin/env bash
# A one-node Slurm cluster on localhost, for CI and for the batch tests.
#
#   scripts/slurm_local.sh install   # slurm-wlm and munge from Debian (apt), if missing
#   scripts/slurm_local.sh start     # munged, slurmctld, slurmd; prints `export SLURM_CONF=…`
#   scripts/slurm_local.sh stop      # stops the daemons this script started
#
# Everything lives under $AGENTSTAR_SLURM_DIR (default /tmp/agentstar-slurm): the
# configuration, state, spool, logs, pid files and munge's socket. It is meant to run as root
# in a container without systemd: process tracking by /proc (no cgroups), no task plugin, no
# accounting database (so `sacct` answers nothing and `agentstar batch status` relies on
# `squeue` and the job files). The daemons listen on localhost only.
set -euo pipefail

dir="${AGENTSTAR_SLURM_DIR:-/tmp/agentstar-slurm}"
conf="$dir/slurm.conf"
node="localhost"

log() { echo "slurm_local: $*" >&2; }

install() {
  if command -v slurmctld >/dev/null 2>&1 && command -v slurmd >/dev/null 2>&1 \
    && command -v munged >/dev/null 2>&1 && command -v sbatch >/dev/null 2>&1; then
    log "slurm and munge are installed"
    return 0
  fi
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends slurm-wlm munge >/dev/null
}

write_conf() {
  local cpus mem_mb
  cpus="$(nproc)"
  # What slurmd would report, less a margin for the system (slurmd refuses a node whose
  # configured memory exceeds what it finds).
  mem_mb="$(awk '/^MemTotal:/ { printf "%d", $2 / 1024 * 0.9 }' /proc/meminfo)"
  mkdir -p "$dir/state" "$dir/spool" "$dir/log" "$dir/munge"
  cat >"$conf" <<EOF
# Written by scripts/slurm_local.sh: one node, this machine, localhost only.
ClusterName=agentstar
SlurmctldHost=$node(127.0.0.1)
SlurmctldPort=6817
SlurmdPort=6818
AuthType=auth/munge
AuthInfo=socket=$dir/munge/munge.socket
CredType=cred/munge
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU_Memory
# A job that names no memory takes 1 GB per CPU, not the whole node.
DefMemPerCPU=1000
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MpiDefault=none
ReturnToService=2
SchedulerType=sched/backfill
# Quick turnaround for tests: a killed task is reaped promptly.
KillWait=2
MinJobAge=300
InactiveLimit=0
SlurmctldTimeout=30
SlurmdTimeout=30
NodeName=$node NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$mem_mb State=UNKNOWN
PartitionName=debug Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF
}

running() { [ -f "$1" ] && kill -0 "$(cat "$1")" 2>/dev/null; }

start() {
  command -v slurmctld >/dev/null 2>&1 || { log "slurmctld is not installed (scripts/slurm_local.sh install)"; exit 1; }
  write_conf
  export SLURM_CONF="$conf"
  if ! running "$dir/munged.pid"; then
    local key=/etc/munge/munge.key
    if [ ! -s "$key" ]; then
      key="$dir/munge/munge.key"
      [ -s "$key" ] || { dd if=/dev/urandom of="$key" bs=1 count=1024 status=none; chmod 400 "$key"; }
    fi
    munged --force --key-file="$key" --socket="$dir/munge/munge.socket" \
      --pid-file="$dir/munged.pid" --log-file="$dir/log/munged.log" --seed-file="$dir/munge/munge.seed"
  fi
  running "$dir/slurmctld.pid" || slurmctld -f "$conf"
  running "$dir/slurmd.pid" || slurmd -f "$conf" -N "$node"
  # Wait (bounded) for the node to be idle.
  local i
  for i in $(seq 1 60); do
    if sinfo -h -N -o '%T' 2>/dev/null | grep -Eq '^(idle|mixed|allocated)'; then
      log "cluster up ($(nproc) CPUs) in ${i}x0.5 s; SLURM_CONF=$conf"
      echo "export SLURM_CONF=$conf"
      return 0
    fi
    sleep 0.5
  done
  log "the node did not come up within 30 s; logs in $dir/log:"
  tail -n 20 "$dir"/log/*.log >&2 || true
  exit 1
}

stop() {
  local p
  for p in slurmd slurmctld munged; do
    if running "$dir/$p.pid"; then
      kill "$(cat "$dir/$p.pid")" || true
    fi
  done
  log "stopped"
}

case "${1:-}" in
  install) install ;;
  start) start ;;
  stop) stop ;;
  *) echo "usage: $0 install|start|stop" >&2; exit 2 ;;
esac
