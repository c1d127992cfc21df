#!/usr/bin/env bash
# Real photographs for the calibration tests: OpenCV's chessboard pictures (left01-14.jpg, a
# 640x480 camera, a 10x7-square board) as Debian 12 ships them in the opencv-doc package,
# taken out of the package into target/photographs/opencv (nothing installed). Idempotent.
set -euo pipefail
cd "$(dirname "$0")/.."
out=target/photographs/opencv
[ -f "$out/left14.jpg" ] && exit 0
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
if ! (cd "$work" && apt-get download -qq opencv-doc 2>/dev/null); then
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  $sudo apt-get update -qq
  (cd "$work" && apt-get download -qq opencv-doc)
fi
data=./usr/share/doc/opencv-doc/examples/data
dpkg-deb --fsys-tarfile "$work"/opencv-doc_*.deb | tar -x -C "$work" --wildcards "$data/left[01]*.jpg"
mkdir -p "$out"
cp "$work/$data"/left*.jpg "$out/"
echo "rmvp: OpenCV's chessboard photographs in $out" >&2
