#!/usr/bin/env bash
# The align benchmark side by side: rmvp's ICP with scale, Open3D point-to-plane ICP and
# small_gicp GICP (both from PyPI, in the virtual environment under target/) on the same 200k-point
# scan and 139k-vertex target (the Stanford bunny, ../shared/meshes, subdivided), in one run.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-system-deps.sh bench
out="$PWD/target/bench/align"
mkdir -p "$out"
venv=target/bench/venv
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c "import open3d, small_gicp" 2>/dev/null; then
  [ -x "$venv/bin/python" ] || /usr/bin/python3 -m venv "$venv"
  "$venv/bin/pip" install -q open3d small_gicp
fi
mesh="${RMVP_BENCH_MESH:-$PWD/../shared/meshes/bunny.ply}"
echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
RMVP_BENCH_MESH="$mesh" RMVP_BENCH_EXPORT="$out" cargo bench --quiet -p rmvp-align --bench align 2>/dev/null | tee "$out/rust.txt"
"$venv/bin/python" bench/align_reference.py "$out" | tee "$out/reference.txt"
