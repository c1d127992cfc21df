#!/usr/bin/env bash
# Calibration on real photographs beside OpenCV's: `rmvp calibrate` and OpenCV 4.6's
# calibrateCamera (bench/opencv_calibrate.py, Debian's python3-opencv) on OpenCV's 13
# chessboard photographs (scripts/fetch-test-photographs.sh); writes
# bench/results/photographs.json. tests/photographs.rs holds rmvp to OpenCV's figures.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-system-deps.sh bench
scripts/fetch-test-photographs.sh
cargo build --release --quiet --bin rmvp
cargo build --release --quiet -p rmvp-testkit --bin bench-result
out=target/bench/photographs
mkdir -p "$out"
photos=target/photographs/opencv
target/release/rmvp --quiet calibrate --board chessboard --squares 10x7 --square-mm 25 "$photos"/left*.jpg \
  -o "$out/camera.json"
/usr/bin/python3 bench/opencv_calibrate.py "$photos" | tee "$out/opencv.txt"
/usr/bin/python3 - "$out/camera.json" "$out/opencv.txt" <<'PY' | target/release/bench-result photographs
import json, re, sys
camera = json.load(open(sys.argv[1]))
k = camera["k"]
theirs = re.search(r"(\d+) images: RMS ([0-9.]+) px, fx ([0-9.]+) fy ([0-9.]+) cx ([0-9.]+) cy ([0-9.]+)",
                   open(sys.argv[2]).read()).groups()
ours = f"{camera['rms_px']:.5f}"
json.dump({
    "title": "Calibration on real photographs",
    "command": "bench/photographs.sh",
    "headline": f"RMS {ours} px; OpenCV 4.6 {theirs[1]} px",
    "about": f"OpenCV's chessboard photographs (`left01-14.jpg` of Debian 12's `opencv-doc`, 640x480, {theirs[0]} "
             "used), `rmvp calibrate --board chessboard --squares 10x7` against OpenCV 4.6's `calibrateCamera` on the "
             "same pixels (`bench/opencv_calibrate.py`); the principal point differs by rmvp's half-pixel convention "
             "(pixel centres at +0.5).",
    "tables": [{"columns": ["", "RMS (px)", "fx", "fy", "cx", "cy"], "rows": [
        ["OpenCV 4.6", *theirs[1:]],
        ["`rmvp calibrate`", ours, f"{k[0][0]:.3f}", f"{k[1][1]:.3f}", f"{k[0][2]:.3f}", f"{k[1][2]:.3f}"],
    ]}],
    "figures": {"rms": ours, "opencv_rms": theirs[1]},
}, sys.stdout)
PY
cargo run --release --quiet -p rmvp-testkit --bin benchmarks-page
