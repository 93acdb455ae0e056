#!/bin/bash
# A single-node Slurm cluster on loopback, everything (munge key and socket, slurm.conf,
# state, logs, pid files) inside one directory: to try gridlight-workers.sbatch on one
# machine, and what tests/deploy_slurm.rs runs it on. Needs root and Debian's slurm-wlm and
# munge packages (slurmctld, slurmd, munged, sbatch, sinfo).
#
#   deploy/slurm/local-cluster.sh start DIR [CTLD_PORT SLURMD_PORT]   # prints: export SLURM_CONF=...
#   SLURM_CONF=DIR/slurm.conf sbatch ...
#   deploy/slurm/local-cluster.sh stop DIR
#
# The node gets CPUs=2 whatever the machine has, so that a job array of two one-CPU tasks
# runs at once; the controller must be named as this host's short name (Slurm checks it).
set -euo pipefail

usage() { echo "usage: $0 start|stop DIR [CTLD_PORT SLURMD_PORT]" >&2; exit 2; }
[ $# -ge 2 ] || usage
action=$1
dir=$(realpath -m "$2")

stop() {
    # Daemons first (they talk to munged while shutting down), then munged.
    for name in slurmd slurmctld munged; do
        pidfile="$dir/$name.pid"
        [ -f "$pidfile" ] || continue
        pid=$(cat "$pidfile")
        kill "$pid" 2>/dev/null || true
        for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
        kill -9 "$pid" 2>/dev/null || true
        rm -f "$pidfile"
    done
}

start() {
    for tool in munged slurmctld slurmd sinfo sbatch; do
        command -v "$tool" >/dev/null || { echo "$tool not found (apt-get install slurm-wlm munge)" >&2; exit 3; }
    done
    [ "$(id -u)" = 0 ] || { echo "needs root (slurmd runs jobs as their user)" >&2; exit 3; }
    local ctld_port=${3:-16817} slurmd_port=${4:-16818}
    mkdir -p "$dir"/{munge,state,spool,log}
    chmod 711 "$dir" "$dir/munge"
    head -c 1024 /dev/urandom >"$dir/munge/munge.key"
    chmod 400 "$dir/munge/munge.key"
    munged -f --key-file="$dir/munge/munge.key" --socket="$dir/munge/munge.sock" \
        --pid-file="$dir/munged.pid" --seed-file="$dir/munge/seed" \
        --log-file="$dir/log/munged.log"
    local host
    host=$(hostname -s)
    cat >"$dir/slurm.conf" <<EOF
ClusterName=gridlight-local
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
AuthType=auth/munge
AuthInfo=socket=$dir/munge/munge.sock
CredType=cred/munge
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
MailProg=/bin/true
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SchedulerType=sched/builtin
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
MpiDefault=none
SwitchType=switch/none
ReturnToService=2
NodeName=gridlight-node NodeHostname=localhost NodeAddr=127.0.0.1 CPUs=2 State=UNKNOWN
PartitionName=grid Nodes=gridlight-node Default=YES MaxTime=INFINITE State=UP
EOF
    export SLURM_CONF="$dir/slurm.conf"
    # Both daemons fork into the background and write their pid files.
    slurmctld -f "$SLURM_CONF" -L "$dir/log/slurmctld.log"
    slurmd -f "$SLURM_CONF" -N gridlight-node -L "$dir/log/slurmd.log"
    for _ in $(seq 100); do
        if sinfo -h -o %t 2>/dev/null | grep -qx idle; then
            echo "export SLURM_CONF=$SLURM_CONF"
            return 0
        fi
        sleep 0.2
    done
    echo "the node did not become idle in 20 s; logs in $dir/log" >&2
    sinfo >&2 || true
    exit 1
}

case $action in
    start) start "$@" ;;
    stop) stop ;;
    *) usage ;;
esac
