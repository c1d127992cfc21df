#!/usr/bin/env bash
# Install the Debian 12 packages rmvp needs, for what is asked. Idempotent: when everything is
# present it only runs dpkg-query and returns in well under a second.
#   scripts/install-system-deps.sh [build]  building rmvp (and running it: the demo, capture,
#                                           calibration, reconstruction, datasets, local batches)
#   scripts/install-system-deps.sh colmap   also COLMAP, for `rmvp poses --method colmap`
#   scripts/install-system-deps.sh slurm    also Slurm's client commands, for `rmvp batch --slurm`
#   scripts/install-system-deps.sh python   also Python's venv and pip, for the `rmvp` Python
#                                           package (`./run python`)
#   scripts/install-system-deps.sh test     what the tests start: COLMAP, a one-node Slurm
#                                           (daemons and munge), Chromium (the preview page)
#                                           and Python (the package's tests)
#   scripts/install-system-deps.sh bench    the tests' packages and the benchmarks' Python
#                                           references (numpy, OpenCV, Mitsuba's LLVM)
set -euo pipefail

purpose="${1:-build}"
packages=(
  build-essential    # the C and C++ compilers and linker cargo calls
  pkg-config
  libopencv-dev      # demosaicing (opencv crate, links the system OpenCV 4.6)
  clang libclang-dev # the opencv crate generates its bindings with libclang at build time
  libaravis-dev      # GenICam cameras (aravis 0.8: USB3 Vision, GigE Vision, the simulated camera)
  libusb-1.0-0-dev   # required by aravis-0.8.pc
)
colmap=(colmap)                                   # camera poses by structure from motion, CPU SIFT
slurm_client=(slurm-client)                       # sbatch, squeue, sacct, scontrol
slurm_node=(slurmctld slurmd slurm-client munge)  # the one-node cluster the batch test starts
browser=(chromium)                                # headless browser for the live-preview page test
python=(python3-venv python3-pip)                 # a virtual environment the Python package installs into
case "$purpose" in
  build) ;;
  colmap) packages+=("${colmap[@]}") ;;
  slurm) packages+=("${slurm_client[@]}") ;;
  python) packages+=("${python[@]}") ;;
  test) packages+=("${colmap[@]}" "${slurm_node[@]}" "${browser[@]}" "${python[@]}") ;;
  bench)
    packages+=("${colmap[@]}" "${slurm_node[@]}" "${browser[@]}" "${python[@]}")
    packages+=(python3-numpy python3-opencv) # same OpenCV 4.6 as the Rust side
    packages+=(python3-venv libllvm19)       # Mitsuba 3 (from PyPI) and its LLVM back end
    ;;
  *)
    echo "usage: scripts/install-system-deps.sh [build|colmap|slurm|python|test|bench]" >&2
    exit 2
    ;;
esac

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if ((${#missing[@]})); then
  echo "rmvp: installing Debian packages: ${missing[*]}" >&2
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -qq
  $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

if ! command -v cargo >/dev/null 2>&1; then
  echo "rmvp: cargo not found; install a Rust toolchain (1.89 or newer, e.g. with rustup) first" >&2
  exit 1
fi
