#!/usr/bin/env bash
# The render benchmark side by side: rmvp-render and Mitsuba 3 (llvm_ad_mono_polarized, from
# PyPI in a virtual environment under target/) on the same six 256x256 views at 64 spp of the
# Stanford bunny (69k triangles, ../shared/meshes) under the same environment, in one run.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-system-deps.sh bench
out="$PWD/target/bench/render"
mkdir -p "$out"
venv=target/bench/venv
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c "import mitsuba, numpy" 2>/dev/null; then
  /usr/bin/python3 -m venv "$venv"
  "$venv/bin/pip" install -q mitsuba==3.9.1 numpy
fi
mesh="${RMVP_BENCH_MESH:-$PWD/../shared/meshes/bunny.ply}"
echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
RMVP_BENCH_MESH="$mesh" RMVP_BENCH_EXPORT="$out" cargo bench --quiet -p rmvp-render --bench render 2>/dev/null | tee "$out/rust.txt"
"$venv/bin/python" bench/render_mitsuba.py "$out" 2>/dev/null | tee "$out/mitsuba.txt"
rust=$(awk '/^rust_s_per_view/ {print $2}' "$out/rust.txt")
mitsuba=$(awk '/^mitsuba_s_per_view/ {print $2}' "$out/mitsuba.txt")
awk -v r="$rust" -v m="$mitsuba" 'BEGIN { printf "rmvp %.3f s per view, Mitsuba %.3f s per view (after its JIT): rmvp takes %.2fx its time\n", r, m, r/m }'
echo "BVH against parry3d (single thread, same rays):"
(cd bench/bvh_compare && cargo run --release --quiet -- "$mesh")
