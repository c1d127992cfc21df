#!/usr/bin/env bash
# The figures of the tests whose outcome depends on random inputs (sensor noise, renderer
# samples, scan samples, a network's start), at several seeds through $RMVP_TEST_SEED (the
# suite runs at 0): the spread each test's bounds must stand clear of (docs/design.md,
# "Test bounds"). Usage: bench/test-margins.sh [--lab] [SEEDS...] (default seeds 0 1 2 3;
# with --lab, the simulated lab alone, about 8 minutes a seed).
set -euo pipefail
cd "$(dirname "$0")/.."
lab=false
if [ "${1:-}" = "--lab" ]; then
  lab=true
  shift
fi
seeds=("$@")
[ ${#seeds[@]} -gt 0 ] || seeds=(0 1 2 3)
out=target/bench/test-margins
mkdir -p "$out"
echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
# package, test binary, test name filter, the pattern of the lines that carry its figures
runs=(
  "rmvp-recon training analytic_sphere_converges sphere:|outputs:|normal maps:|surface shading"
  "rmvp-recon training the_curvature_term_sees curvature:"
  "rmvp-recon fixture the_fast_preset seed [0-9]+:"
  "rmvp-align icp known_similarity|far_starts|cropped_noisy alignment error"
  "rmvp-calib board rendered_boards corner error|deviations"
  "rmvp capture a_six_view|hdr_brackets view [0-9]|HDR S0"
)
$lab && runs=("rmvp lab a_lab_session calibrated|charuco poses|masks: IoU|colmap poses|scan aligned|release ground|normal MAE over")
for seed in "${seeds[@]}"; do
  for run in "${runs[@]}"; do
    read -r package binary filter pattern <<<"$run"
    log="$out/$binary-$seed.log"
    # Each test binary's tests one at a time, so that their lines do not interleave.
    RMVP_TEST_SEED=$seed cargo test --release -p "$package" --test "$binary" -- --test-threads 1 --nocapture \
      $(tr '|' ' ' <<<"$filter") >"$log" 2>&1 || { echo "seed $seed: $binary failed (see $log)"; continue; }
    # A test's first line follows libtest's "test NAME ... " on the same line.
    grep -oE "($pattern).*" "$log" | sed "s/^/seed $seed  $binary  /" || true
  done
done
