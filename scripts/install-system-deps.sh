#!/usr/bin/env bash
# Install the Debian 12 packages rmvp builds against. Idempotent: when everything is present it
# only runs dpkg-query and returns in well under a second.
#   scripts/install-system-deps.sh          what building and testing need
#   scripts/install-system-deps.sh bench    also the Python baseline of bench/ (numpy, OpenCV)
set -euo pipefail

packages=(
  pkg-config
  libopencv-dev     # demosaicing (opencv crate, links the system OpenCV 4.6)
  clang libclang-dev # the opencv crate generates its bindings with libclang at build time
  libaravis-dev      # GenICam cameras (aravis 0.8: USB3 Vision, GigE Vision, the simulated camera)
  libusb-1.0-0-dev   # required by aravis-0.8.pc
  chromium           # headless browser for the live-preview page test
  colmap             # camera poses by structure from motion (rmvp poses --method colmap), CPU SIFT
  slurmctld slurmd slurm-client munge # rmvp batch --slurm; its test starts a one-node cluster
)
if [ "${1:-}" = bench ]; then
  packages+=(python3-numpy python3-opencv) # same OpenCV 4.6 as the Rust side
  packages+=(python3-venv libllvm19)         # Mitsuba 3 (from PyPI) and its LLVM back end
fi

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
