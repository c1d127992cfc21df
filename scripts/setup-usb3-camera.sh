#!/usr/bin/env bash
# One-time set-up of a lab machine for the FLIR USB3 Vision camera (run as root):
#  - the udev rule that gives the plugdev group access to USB3 Vision devices;
#  - the kernel's USB buffer memory (usbcore.usbfs_memory_mb, default 16 MB, far too little for
#    2448x2048 frames at 75 frames/s: aravis then loses frames). Set now, and for every boot.
set -euo pipefail
[ "$(id -u)" -eq 0 ] || { echo "run as root (sudo $0)" >&2; exit 1; }
here="$(cd "$(dirname "$0")" && pwd)"
install -m 0644 "$here/udev/40-rmvp-usb3vision.rules" /etc/udev/rules.d/40-rmvp-usb3vision.rules
udevadm control --reload-rules && udevadm trigger || true
memory_mb=1000
if [ -w /sys/module/usbcore/parameters/usbfs_memory_mb ]; then
  echo "$memory_mb" > /sys/module/usbcore/parameters/usbfs_memory_mb
fi
echo "options usbcore usbfs_memory_mb=$memory_mb" > /etc/modprobe.d/rmvp-usbfs.conf
echo "rmvp: udev rule installed; usbfs_memory_mb = $(cat /sys/module/usbcore/parameters/usbfs_memory_mb 2>/dev/null || echo '?')"
echo "rmvp: if usbcore is built into the kernel, also add usbcore.usbfs_memory_mb=$memory_mb to the kernel command line (GRUB_CMDLINE_LINUX in /etc/default/grub, then update-grub)."
echo "rmvp: add operators to the plugdev group (usermod -aG plugdev NAME), then replug the camera."
