#!/usr/bin/env bash
# A throwaway single-node Slurm cluster without systemd, for the farm tests.
#
#   cluster.sh start DIR   writes DIR/slurm.conf and a MUNGE key, starts munged, slurmctld and
#                          slurmd in the background (PIDs in DIR/pids), waits until the node is idle,
#                          and prints `export SLURM_CONF=DIR/slurm.conf`.
#   cluster.sh stop DIR    stops every daemon listed in DIR/pids by its PID (TERM, then KILL).
#
# DIR must not exist or be empty. Everything (state, spool, logs, sockets) lives under it; the
# daemons run as the calling user (root in CI). Ports are picked at random among free ones, so two
# clusters on one machine do not collide.
set -euo pipefail
umask 022

die() { echo "cluster.sh: $*" >&2; exit 1; }

port_free() { ! (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null; }

pick_port() {
    local p
    for _ in $(seq 50); do
        p=$((20000 + RANDOM % 30000))
        if port_free "$p" && port_free "$((p + 1))"; then echo "$p"; return; fi
    done
    die "no free port pair found"
}

wait_for() { # wait_for SECONDS DESCRIPTION COMMAND...
    local limit=$1 what=$2; shift 2
    for _ in $(seq $((limit * 5))); do
        if "$@" >/dev/null 2>&1; then return 0; fi
        sleep 0.2
    done
    echo "cluster.sh: timed out waiting for $what" >&2
    return 1
}

start() {
    local dir=$1
    mkdir -p "$dir"
    dir=$(cd "$dir" && pwd)
    [ -z "$(ls -A "$dir")" ] || die "$dir is not empty"
    chmod 0755 "$dir"
    mkdir -p "$dir/munge" "$dir/state" "$dir/spool" "$dir/log"
    chmod 0700 "$dir/munge" "$dir/state" "$dir/spool"
    : >"$dir/pids"

    local host; host=$(hostname -s)
    local port; port=$(pick_port)
    local sock="$dir/munge/munge.socket.2"

    # MUNGE: a fresh key, private files (munged refuses group-writable ones).
    dd if=/dev/urandom of="$dir/munge/munge.key" bs=1024 count=1 status=none
    chmod 0400 "$dir/munge/munge.key"
    munged --foreground --force --socket="$sock" --key-file="$dir/munge/munge.key" \
        --pid-file="$dir/munge/munged.pid" --log-file="$dir/log/munged.log" \
        --seed-file="$dir/munge/munged.seed" >>"$dir/log/munged.out" 2>&1 &
    echo "munged $!" >>"$dir/pids"
    wait_for 10 "munged" test -S "$sock" || { cat "$dir/log/munged.log" >&2; stop "$dir"; exit 1; }

    cat >"$dir/slurm.conf" <<CONF
ClusterName=wavefront-ci
SlurmctldHost=$host
SlurmctldPort=$port
SlurmdPort=$((port + 1))
SlurmUser=$(id -un)
SlurmdUser=$(id -un)
AuthType=auth/munge
AuthInfo=socket=$sock
CredType=cred/munge
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
MpiDefault=none
SwitchType=switch/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
EnforcePartLimits=ALL
ReturnToService=2
JobCompType=jobcomp/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MinJobAge=600
NodeName=$host CPUs=2 State=UNKNOWN
PartitionName=ci Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
    export SLURM_CONF="$dir/slurm.conf"

    slurmctld -D -c -f "$SLURM_CONF" >>"$dir/log/slurmctld.out" 2>&1 &
    echo "slurmctld $!" >>"$dir/pids"
    wait_for 20 "slurmctld" scontrol ping || { tail -20 "$dir/log/slurmctld.log" >&2; stop "$dir"; exit 1; }

    slurmd -D -f "$SLURM_CONF" >>"$dir/log/slurmd.out" 2>&1 &
    echo "slurmd $!" >>"$dir/pids"
    node_idle() { sinfo -h -n "$host" -o '%t' | grep -qx 'idle'; }
    wait_for 30 "node $host to become idle" node_idle || { tail -20 "$dir/log/slurmd.log" >&2; stop "$dir"; exit 1; }

    echo "export SLURM_CONF=$SLURM_CONF"
}

stop() {
    local dir=$1 name pid
    [ -f "$dir/pids" ] || return 0
    # Newest first: slurmd, slurmctld, then munged.
    tac "$dir/pids" | while read -r name pid; do
        kill -TERM "$pid" 2>/dev/null || continue
        for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
        if kill -0 "$pid" 2>/dev/null; then
            echo "cluster.sh: $name ($pid) ignored TERM; killing it" >&2
            kill -KILL "$pid" 2>/dev/null || true
        fi
    done
    : >"$dir/pids"
}

case "${1:-}" in
    start) [ $# -eq 2 ] || die "usage: cluster.sh start DIR"; start "$2" ;;
    stop) [ $# -eq 2 ] || die "usage: cluster.sh stop DIR"; stop "$2" ;;
    *) die "usage: cluster.sh start|stop DIR" ;;
esac
