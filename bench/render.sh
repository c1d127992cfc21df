#!/usr/bin/env bash
# The render benchmark side by side: rmvp-render and Mitsuba 3 (llvm_ad_mono_polarized, from
# PyPI in a virtual environment under target/) on the same six 256x256 views at 64 spp of the
# Stanford bunny (69k triangles, ../shared/meshes) under the same environment, in one run;
# writes bench/results/render.json.
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
(cd bench/bvh_compare && cargo run --release --quiet -- "$mesh") | tee "$out/bvh.txt"
cargo build --release --quiet -p rmvp-testkit --bin bench-result
/usr/bin/python3 - "$rust" "$mitsuba" "$out/mitsuba.txt" "$out/bvh.txt" <<'PY' | target/release/bench-result render
import json, re, sys
rust, mitsuba = float(sys.argv[1]), float(sys.argv[2])
first = re.search(r"first view ([0-9.]+) s", open(sys.argv[3]).read()).group(1)
bvh = [line.rstrip("\n").split("\t")[1:] for line in open(sys.argv[4]) if line.startswith("row\t")]
json.dump({
    "title": "Rendering six views",
    "command": "bench/render.sh",
    "headline": f"{rust:.2f} s a view, Mitsuba 3 {mitsuba:.2f}",
    "about": "Six 256x256 views at 64 samples per pixel of the Stanford bunny (69,451 triangles) under the built-in "
             "environment, pplastic (alpha 0.1, eta 1.5). rmvp: `render/benches/render.rs` (RGB Stokes). Mitsuba 3.9.1 "
             "`llvm_ad_mono_polarized` (one channel), `bench/render_mitsuba.py`: the same cameras, environment and "
             "mesh, the `stokes` integrator around `direct` (the same budget and light transport), both on 2 threads, "
             "Mitsuba's first view (its JIT) left out of its time. The second table: ray casting alone "
             "(`bench/bvh_compare`: the bunny, one thread, the same rays, the same hits).",
    "tables": [
        {"columns": ["", "s a view", "first view"], "rows": [
            ["rmvp", f"{rust:.3f}", ""], ["Mitsuba 3", f"{mitsuba:.3f}", first]]},
        {"columns": ["query", "rmvp-render", "parry3d `TriMesh`"], "rows": bvh},
    ],
    "figures": {"rmvp_s_per_view": f"{rust:.3f}", "mitsuba_s_per_view": f"{mitsuba:.3f}"},
}, sys.stdout)
PY
cargo run --release --quiet -p rmvp-testkit --bin benchmarks-page
