#!/usr/bin/env bash
# The frame benchmark side by side: rmvp (Rust, OpenCV demosaicing) and the Python baseline
# (numpy + OpenCV) on the same 2448x2048 BayerRGPolarized12p frame, in one run.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-system-deps.sh bench
out=target/bench
mkdir -p "$out"
cargo run --release --quiet -- demo -o "$out/demo" >/dev/null
frame="$PWD/$out/demo/frame.raw"
echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
RMVP_BENCH_FRAME="$frame" cargo bench --quiet -p rmvp-capture --bench frame 2>/dev/null | tee "$out/rust.txt"
/usr/bin/python3 bench/frame_python.py "$frame" | tee "$out/python.txt"
rust=$(awk '/^rust_ms_per_frame/ {print $2}' "$out/rust.txt")
python=$(awk '/^python_ms_per_frame/ {print $2}' "$out/python.txt")
awk -v r="$rust" -v p="$python" 'BEGIN { printf "rmvp %.2f ms (%.1f fps), python %.2f ms (%.1f fps): rmvp is %.1fx faster\n", r, 1000/r, p, 1000/p, p/r }'
