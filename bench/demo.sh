#!/usr/bin/env bash
# The demo as a benchmark: `rmvp demo` with its defaults, the binary built first, timed from
# start to end; writes bench/results/demo.json from the run's report.json and the time.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-system-deps.sh build
cargo build --release --quiet --bin rmvp
cargo build --release --quiet -p rmvp-testkit --bin bench-result
out=target/bench/demo-run
rm -rf "$out"
start=$(date +%s.%N)
target/release/rmvp demo -o "$out"
end=$(date +%s.%N)
written=$(du -sb "$out" | cut -f1)
/usr/bin/python3 - "$out/report.json" "$start" "$end" "$written" <<'PY' | target/release/bench-result demo
import json, sys
report = json.load(open(sys.argv[1]))
seconds = float(sys.argv[3]) - float(sys.argv[2])
written = f"{int(sys.argv[4]) / 1e9:.1f} GB"
recon = report["reconstruction"]
aop, s0 = report["aop_error_deg"], report["s0_rel_error"]
total, trained = f"{seconds:.0f}", f"{recon['seconds']:.0f}"
normal, chamfer, fscore = f"{recon['normal_mae_deg']:.2f}", f"{recon['chamfer']:.4f}", f"{recon['f_score']:.3f}"
json.dump({
    "title": "The demo",
    "command": "bench/demo.sh",
    "headline": f"{total} s ({trained} s reconstructing); normal error {normal} degrees",
    "about": "`rmvp demo` with its defaults, the binary built, nothing else running: the spot on the simulated "
             "turntable (6 views of 2448x2048 raw frames, 4 dark frames, 16 spp), its truth, poses, masks, the "
             f"dataset (1224x1024), the reconstruction ({recon['preset']} preset, {recon['iterations']} iterations, "
             "mesh at 256^3) evaluated; the "
             "figures are its `report.json`'s. Training is deterministic on one machine whatever its thread "
             "count; across machines rounding differs (0.1 degrees on the spot).",
    "tables": [{"columns": ["figure", "value"], "rows": [
        ["in all / reconstruction", f"{total} s / {trained} s"],
        ["captured AoP against the rendered, median (90 %), pixels with DoP > 0.05",
         f"{aop['median']:.2f} degrees ({aop['p90']:.2f})"],
        ["captured S0 against the rendered, median", f"{100 * s0['median']:.1f} %"],
        ["Chamfer (object radius 1) / F-score", f"{chamfer} / {fscore}"],
        ["normal MAE over the six views", f"{normal} degrees"],
        ["written", written],
    ]}],
    "figures": {"seconds": total, "recon_seconds": trained, "normal": normal, "chamfer": chamfer, "written": written},
}, sys.stdout)
PY
cargo run --release --quiet -p rmvp-testkit --bin benchmarks-page
