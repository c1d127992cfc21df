#!/usr/bin/env bash
# The frame benchmark side by side: rmvp (Rust, OpenCV demosaicing) and the Python baseline
# (numpy + OpenCV) on the same 2448x2048 BayerRGPolarized12p frame, in one run.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-system-deps.sh bench
out=target/bench
mkdir -p "$out"
cargo run --release --quiet -- demo -o "$out/demo" >/dev/null
# The demo's first view's raw frame (its session keeps each view's frames under raw/).
frame=$(ls "$PWD/$out/demo/session/views/000/raw/"*.raw | head -n 1)
echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
RMVP_BENCH_FRAME="$frame" cargo bench --quiet -p rmvp-capture --bench frame 2>/dev/null | tee "$out/rust.txt"
/usr/bin/python3 bench/frame_python.py "$frame" | tee "$out/python.txt"
rust=$(awk '/^rust_ms_per_frame/ {print $2}' "$out/rust.txt")
python=$(awk '/^python_ms_per_frame/ {print $2}' "$out/python.txt")
awk -v r="$rust" -v p="$python" 'BEGIN { printf "rmvp %.2f ms (%.1f fps), python %.2f ms (%.1f fps): rmvp is %.1fx faster\n", r, 1000/r, p, 1000/p, p/r }'
cargo build --release --quiet -p rmvp-testkit --bin bench-result
/usr/bin/python3 - "$out/rust.txt" "$rust" "$python" <<'PY' | target/release/bench-result frame
import json, sys
stages = [line.rstrip("\n").split("\t")[1:] for line in open(sys.argv[1]) if line.startswith("stage_ms\t")]
rust, python = float(sys.argv[2]), float(sys.argv[3])
speedup = f"{python / rust:.1f}"
json.dump({
    "title": "A raw frame to Stokes, AoP and DoP",
    "command": "bench/frame.sh",
    "headline": f"{rust:.1f} ms a frame, {speedup}x numpy + OpenCV",
    "about": "A full 2448x2048 `BayerRGPolarized12p` frame (the demo's) through decoding, splitting into four "
             "1224x1024 RGGB sub-mosaics, OpenCV bilinear demosaicing, least-squares Stokes, AoP and DoP, 2 threads. "
             "rmvp: `capture/benches/frame.rs`, median of 40 frames after 3 warm-up frames, buffers reused as in a "
             "stream. Python: `bench/frame_python.py`, the same work as labs do it (numpy unpacking and slicing, "
             "`cv2.cvtColor`, numpy Stokes, AoP, DoP), median of 20, on the same frame in the same run; the stages "
             "are the Rust side's. OpenCV and numpy are Debian's.",
    "tables": [
        {"columns": ["", "ms a frame", "frames/s"], "rows": [
            ["rmvp", f"{rust:.2f}", f"{1e3 / rust:.1f}"], ["numpy + OpenCV", f"{python:.2f}", f"{1e3 / python:.1f}"]]},
        {"columns": ["stage", "ms"], "rows": stages},
    ],
    "figures": {"rmvp_ms": f"{rust:.2f}", "python_ms": f"{python:.2f}", "speedup": speedup},
}, sys.stdout)
PY
cargo run --release --quiet -p rmvp-testkit --bin benchmarks-page
