#!/usr/bin/env bash
# Two rmvp binaries on the same scene, one after the other, on the same threads: the whole
# training and mesh of `rmvp recon --mesh-only` with the defaults, seconds each. Usage:
# bench/recon-time.sh BEFORE_BINARY AFTER_BINARY [SCENE] [THREADS] (default the Mitsuba horse
# of ../shared/evalset, 2 threads). Writes bench/results/recon-time.json.
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
  seconds=$(awk -v s="$start" -v e="$end" 'BEGIN { printf "%.1f", e - s }')
  echo "$name: $seconds s"
  eval "${name}_seconds=$seconds"
done
cargo build --release --quiet -p rmvp-testkit --bin bench-result
/usr/bin/python3 - "$before" "$before_seconds" "$after" "$after_seconds" "$scene" "$threads" <<'PY' | target/release/bench-result recon-time
import json, sys
before, before_s, after, after_s, scene, threads = sys.argv[1:]
json.dump({
    "title": "A whole reconstruction",
    "command": "bench/recon-time.sh BEFORE AFTER",
    "headline": f"{after_s} s on {threads} threads (before: {before_s} s)",
    "about": f"`rmvp --threads {threads} recon {scene} --mesh-only` with the defaults (the whole training and the "
             "mesh), two binaries one after the other on the same threads.",
    "tables": [{"columns": ["binary", "seconds"], "rows": [[f"before: `{before}`", before_s], [f"after: `{after}`", after_s]]}],
    "figures": {"before_seconds": before_s, "after_seconds": after_s},
}, sys.stdout)
PY
cargo run --release --quiet -p rmvp-testkit --bin benchmarks-page
