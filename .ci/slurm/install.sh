#!/usr/bin/env bash
# Installs Debian's Slurm and MUNGE packages (controller, node daemon, client commands) when they
# are not there yet. Nothing is started: `cluster.sh start` runs a throwaway cluster without
# systemd. Needs root (CI runs as root).
set -euo pipefail
if command -v sbatch >/dev/null && command -v slurmctld >/dev/null && command -v slurmd >/dev/null \
    && command -v munged >/dev/null; then
    exit 0
fi
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
apt-get install -y -qq --no-install-recommends slurmctld slurmd slurm-client munge >/dev/null
