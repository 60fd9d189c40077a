#!/usr/bin/env bash
# A private single-node SLURM cluster for the tests: munged, slurmctld and slurmd started as root
# (no systemd, no accounting) from a configuration written to DIR, with the node's real CPUs and
# memory. Debian's packages are installed with apt-get where missing.
#
#   slurm_setup.sh start DIR   install where missing, configure, start, wait until the node is idle
#   slurm_setup.sh stop DIR    cancel this cluster's jobs and stop its three daemons
#
# SLURM commands reach it with SLURM_CONF=DIR/slurm.conf. While it runs, /etc/slurm/slurm.conf is a
# link to that file too: snakemake's job step drops SLURM_CONF from the environment of its srun. The
# script refuses to replace a configuration of the machine's own or of another running test cluster.
# Environment: SLURMCTLD_PORT (default 6817), SLURMD_PORT (default 6818), SLURM_START_TIMEOUT_S
# (default 60). Exit 0 on success, 2 on a bad argument, 77 when a prerequisite is missing (not root,
# no apt-get, /etc/slurm/slurm.conf taken), 1 when something failed.
set -euo pipefail
export PATH=$PATH:/usr/sbin:/sbin  # the daemons, for a caller whose PATH lacks them

usage() { echo "usage: $0 start|stop DIR" >&2; exit 2; }
[ $# -eq 2 ] || usage
action=$1
[ "$action" = start ] || [ "$action" = stop ] || usage

missing() { echo "slurm_setup: $*" >&2; exit 77; }
fail() { echo "slurm_setup: $*" >&2; exit 1; }

ctld_port=${SLURMCTLD_PORT:-6817}
slurmd_port=${SLURMD_PORT:-6818}
timeout_s=${SLURM_START_TIMEOUT_S:-60}

in_range() {  # in_range NAME VALUE MIN MAX: VALUE is an integer in [MIN, MAX], else exit 2
    if ! [[ $2 =~ ^[0-9]+$ ]] || [ "$2" -lt "$3" ] || [ "$2" -gt "$4" ]; then
        echo "slurm_setup: $1 = '$2' must be an integer in [$3, $4]" >&2
        exit 2
    fi
}
in_range SLURMCTLD_PORT "$ctld_port" 1024 65535
in_range SLURMD_PORT "$slurmd_port" 1024 65535
in_range SLURM_START_TIMEOUT_S "$timeout_s" 1 3600
[ "$(id -u)" -eq 0 ] || missing "must run as root to start slurmd and munged"

mkdir -p "$2"
dir=$(cd "$2" && pwd)
conf=$dir/slurm.conf
system_conf=/etc/slurm/slurm.conf
marker=created-by-slurm_setup
export SLURM_CONF=$conf

alive() {  # alive PIDFILE: the daemon whose pid is in PIDFILE runs
    [ -s "$1" ] && kill -0 "$(cat "$1")" 2>/dev/null
}

install_packages() {
    local need=()
    command -v munged >/dev/null || need+=(munge)
    command -v slurmctld >/dev/null || need+=(slurmctld)
    command -v slurmd >/dev/null || need+=(slurmd)
    command -v sinfo >/dev/null && command -v sbatch >/dev/null || need+=(slurm-client)
    [ ${#need[@]} -eq 0 ] && return 0
    command -v apt-get >/dev/null || missing "apt-get not found, cannot install ${need[*]}"
    echo "slurm_setup: installing ${need[*]}" >&2
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -q >"$dir/apt.log" 2>&1 || fail "apt-get update failed, see $dir/apt.log"
    apt-get install -y -q --no-install-recommends "${need[@]}" >>"$dir/apt.log" 2>&1 \
        || fail "apt-get install ${need[*]} failed, see $dir/apt.log"
}

write_config() {
    local host node
    host=$(hostname -s)
    # the node's real CPUs, sockets, cores, threads and memory, as slurmd detects them
    node=$(slurmd -C | head -n 1 | sed -e "s/^NodeName=[^ ]*/NodeName=$host NodeAddr=127.0.0.1/")
    cat >"$conf" <<EOF
ClusterName=plugsim
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$dir/munge/munge.socket.2
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
MpiDefault=none
ReturnToService=2
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/none
# finished jobs stay visible to squeue (the status command without accounting) for 10 min
MinJobAge=600
$node State=UNKNOWN
PartitionName=debug Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF
}

link_config() {
    if [ -L "$system_conf" ]; then
        local target other
        target=$(readlink "$system_conf")
        [ "$target" = "$conf" ] && return 0
        other=$(dirname "$target")
        if [ -e "$target" ]; then  # a dangling link (its cluster's directory removed) is replaced
            [ -e "$other/$marker" ] \
                || missing "$system_conf links to $target, not a test cluster's; not replacing it"
            alive "$other/slurmctld.pid" && missing "another test cluster runs from $other"
        fi
    elif [ -e "$system_conf" ]; then
        missing "$system_conf exists (this machine's own SLURM configuration); not replacing it"
    fi
    mkdir -p "$(dirname "$system_conf")"
    ln -sfn "$conf" "$system_conf"
}

start_munge() {
    alive "$dir/munge/munged.pid" && return 0
    mkdir -p "$dir/munge"
    chmod 700 "$dir/munge"
    if [ ! -s "$dir/munge/munge.key" ]; then
        head -c 1024 /dev/urandom >"$dir/munge/munge.key"
        chmod 400 "$dir/munge/munge.key"
    fi
    munged --force --socket="$dir/munge/munge.socket.2" --key-file="$dir/munge/munge.key" \
        --pid-file="$dir/munge/munged.pid" --log-file="$dir/munge/munged.log" \
        --seed-file="$dir/munge/munged.seed" || fail "munged did not start, see $dir/munge/munged.log"
}

wait_idle() {
    local state="" t=0
    while [ "$t" -lt "$timeout_s" ]; do
        state=$(sinfo -h -N -o %T 2>/dev/null | head -n 1 || true)
        [ "$state" = idle ] && return 0
        sleep 1
        t=$((t + 1))
    done
    fail "the node is '${state:-not reported}' after ${timeout_s} s, not idle;" \
        "see $dir/slurmctld.log and $dir/slurmd.log"
}

start() {
    install_packages
    mkdir -p "$dir/state" "$dir/spool"
    touch "$dir/$marker"
    [ -s "$conf" ] || write_config
    link_config
    start_munge
    alive "$dir/slurmctld.pid" || slurmctld -f "$conf" \
        || fail "slurmctld did not start, see $dir/slurmctld.log"
    alive "$dir/slurmd.pid" || slurmd -f "$conf" || fail "slurmd did not start, see $dir/slurmd.log"
    wait_idle
    echo "slurm_setup: node $(hostname -s) idle (SLURM_CONF=$conf)" >&2
}

stop_daemon() {  # stop_daemon PIDFILE: SIGTERM, then SIGKILL after 10 s
    alive "$1" || return 0
    local pid t=0
    pid=$(cat "$1")
    kill "$pid" 2>/dev/null || true
    while kill -0 "$pid" 2>/dev/null && [ "$t" -lt 20 ]; do sleep 0.5; t=$((t + 1)); done
    kill -9 "$pid" 2>/dev/null || true
}

stop() {
    if alive "$dir/slurmctld.pid"; then
        scancel --user="$(id -un)" 2>/dev/null || true
        local t=0  # let slurmd end the cancelled jobs' steps before it stops
        while [ -n "$(squeue -h -t RUNNING,COMPLETING -o %i 2>/dev/null)" ] && [ "$t" -lt 20 ]; do
            sleep 0.5
            t=$((t + 1))
        done
    fi
    stop_daemon "$dir/slurmd.pid"
    stop_daemon "$dir/slurmctld.pid"
    stop_daemon "$dir/munge/munged.pid"
    if [ -L "$system_conf" ] && [ "$(readlink "$system_conf")" = "$conf" ]; then
        rm -f "$system_conf"
    fi
}

"$action"
