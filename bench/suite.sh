#!/usr/bin/env bash
# The test suite as a benchmark: `./run test` in a fresh clone of this checkout's commit (beside
# it, the same ../shared), timed from start to end with its tests counted; writes
# bench/results/suite.json. The crates come from cargo's cache where it has them, the system
# packages from apt-get where they are missing.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet -p rmvp-testkit --bin bench-result
work=target/bench/suite
rm -rf "$work"
mkdir -p "$work"
ln -s "$(cd .. && pwd)/shared" "$work/shared"
git clone --quiet . "$work/rmvp"
commit=$(git -C "$work/rmvp" rev-parse --short HEAD)
start=$(date +%s)
# Each line of the log begins with the seconds since the start: where the time goes.
set +e
(cd "$work/rmvp" && ./run test) 2>&1 | while IFS= read -r line; do
  printf '%5d s  %s\n' $((EPOCHSECONDS - start)) "$line"
done > "$work/log.txt"
status=${PIPESTATUS[0]}
set -e
end=$(date +%s)
if [ "$status" -ne 0 ]; then
  tail -n 40 "$work/log.txt" >&2
  echo "bench/suite.sh: ./run test failed (exit $status); the full log is $work/log.txt" >&2
  exit "$status"
fi
rust=$(grep -oE 'test result: ok\. [0-9]+ passed' "$work/log.txt" | awk '{ n += $4 } END { print n + 0 }')
python=$(grep -oE '[0-9]+ passed' "$work/log.txt" | tail -n 1 | awk '{ print $1 }')
seconds=$((end - start))
minutes="$((seconds / 60)) min $((seconds % 60)) s"
cat <<JSON | target/release/bench-result suite
{
  "title": "The test suite",
  "command": "bench/suite.sh",
  "headline": "$minutes from a fresh clone ($rust Rust and $python Python tests)",
  "about": "\`./run test\` in a fresh clone (\`git clone\`), nothing else running: every Rust test, the Python package built into \`.venv\` and its tests, rustfmt and clippy; the crates from cargo's cache where it has them. CI's budget is 25 minutes.",
  "tables": [{"columns": ["figure", "value"], "rows": [["\`./run test\`", "$minutes"], ["Rust tests", "$rust"], ["Python tests", "$python"]]}],
  "figures": {"minutes": "$minutes", "rust_tests": "$rust", "python_tests": "$python"},
  "commit": "$commit"
}
JSON
cargo run --release --quiet -p rmvp-testkit --bin benchmarks-page
