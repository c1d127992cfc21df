#!/usr/bin/env bash
# Two rmvp binaries on the same scene, one after the other, on the same threads: the whole
# training and mesh of `rmvp recon --mesh-only` with the defaults, seconds each. Usage:
# bench/recon-time.sh BEFORE_BINARY AFTER_BINARY [SCENE] [THREADS] (default the Mitsuba horse
# of ../shared/evalset, 2 threads).
set -euo pipefail
cd "$(dirname "$0")/.."
before=$1
after=$2
scene=${3:-../shared/evalset/horse}
threads=${4:-2}
out=target/bench/recon-time
mkdir -p "$out"
echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs); $scene, $threads threads"
for pair in "before:$before" "after:$after"; do
  name=${pair%%:*}
  binary=${pair#*:}
  rm -rf "${out:?}/$name"
  start=$(date +%s.%N)
  "$binary" --quiet --threads "$threads" recon "$scene" -o "$out/$name" --mesh-only
  end=$(date +%s.%N)
  awk -v n="$name" -v s="$start" -v e="$end" 'BEGIN { printf "%s: %.1f s\n", n, e - s }'
done
