#!/usr/bin/env bash
# A one-node SLURM on this machine, without systemd: munge, slurmctld and slurmd on localhost,
# one partition `debug` with four task slots per core of this machine. For trying the job-array
# scripts before a real cluster, and for CI (.ci/run starts it; host-sim/tests/all/slurm.rs
# submits to it).
#
#   docs/cluster/local-slurm.sh start   # install-free: needs Debian's slurm-wlm and munge, root
#   docs/cluster/local-slurm.sh status
#   docs/cluster/local-slurm.sh stop
#
# Everything it writes is under /etc/munge, /etc/slurm, /var/{lib,log,run,spool}/{munge,slurm*}.
set -euo pipefail

host=$(hostname -s)
cpus=$(nproc)
mem_mb=$(awk '/MemTotal/ { print int($2 / 1024) - 512 }' /proc/meminfo)
conf=/etc/slurm/slurm.conf
run=/run/local-slurm

# Whether a process named $1 runs: a zombie (a daemon killed with its parent still about, as a
# killed CI run leaves one) answers nothing and does not count.
alive() {
    for p in $(pgrep -x "$1"); do
        case "$(ps -o stat= -p "$p" 2>/dev/null)" in
            Z* | '') ;;
            *) return 0 ;;
        esac
    done
    return 1
}

start() {
    command -v slurmctld >/dev/null && command -v munged >/dev/null || {
        echo "needs Debian's slurm-wlm and munge (apt-get install slurm-wlm munge)" >&2
        exit 1
    }
    mkdir -p /etc/munge /var/log/munge /run/munge /var/lib/munge "$run" \
        /etc/slurm /var/spool/slurmctld /var/spool/slurmd /var/log/slurm
    if [ ! -s /etc/munge/munge.key ]; then
        mungekey -c -k /etc/munge/munge.key
    fi
    chown -R munge:munge /etc/munge /var/log/munge /run/munge /var/lib/munge
    chmod 400 /etc/munge/munge.key
    if ! munge -n 2>/dev/null | unmunge >/dev/null 2>&1; then
        runuser -u munge -- munged
        for _ in $(seq 50); do munge -n 2>/dev/null | unmunge >/dev/null 2>&1 && break; sleep 0.1; done
    fi
    cat > "$conf" <<EOF
ClusterName=local
SlurmctldHost=$host
AuthType=auth/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SlurmUser=root
SlurmdUser=root
StateSaveLocation=/var/spool/slurmctld
SlurmdSpoolDir=/var/spool/slurmd
SlurmctldPidFile=$run/slurmctld.pid
SlurmdPidFile=$run/slurmd.pid
SlurmctldLogFile=/var/log/slurm/slurmctld.log
SlurmdLogFile=/var/log/slurm/slurmd.log
ReturnToService=2
KillWait=10
MinJobAge=600
# One node, few jobs: the scheduler's passes every second (default 60 s and 30 s), so that a
# pending task starts and a dependency that can no longer be met is said within seconds.
SchedulerParameters=sched_interval=1,bf_interval=1
# Four task slots per core (config_overrides: slurmd takes the configured count, not the
# hardware's): a test's tasks are short and spend most of their time in SLURM's own start-up and
# completion, so on a 2-core machine eight of them side by side beat two at a time.
SlurmdParameters=config_overrides
NodeName=$host CPUs=$((cpus * 4)) RealMemory=$mem_mb State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
    # A running controller rereads the file; one that does not answer (left over from a run
    # that was killed) is replaced.
    if ! { alive slurmctld && scontrol reconfigure 2>/dev/null; }; then
        pkill -x slurmctld 2>/dev/null || true
        for _ in $(seq 100); do alive slurmctld || break; sleep 0.1; done
        slurmctld -c
    fi
    alive slurmd || slurmd
    for _ in $(seq 100); do
        if sinfo -h -o '%t' 2>/dev/null | grep -qE '^(idle|mix|alloc)'; then
            sinfo
            return
        fi
        sleep 0.2
    done
    echo "the node did not come up:" >&2
    sinfo >&2 || true
    tail -20 /var/log/slurm/slurmctld.log /var/log/slurm/slurmd.log >&2 || true
    exit 1
}

stop() {
    for d in slurmd slurmctld munged; do
        pkill -x "$d" 2>/dev/null || true
        for _ in $(seq 100); do alive "$d" || break; sleep 0.1; done
    done
}

case "${1:-}" in
    start) start ;;
    stop) stop ;;
    status) sinfo && squeue ;;
    *) echo "usage: $0 start|stop|status" >&2; exit 2 ;;
esac
