"""The Python baseline of the frame benchmark: what labs run today.

One 2448x2048 BayerRGPolarized12p frame: unpack with numpy, slice into the four polarizer
sub-mosaics and demosaic each with cv2.cvtColor (the first stage of polanalyser's
`demosaicing`), then Stokes, AoP and DoP with numpy (closed-form least squares, channel-mean
AoP/DoP: the same work as `rmvp`). Prints the median time per frame.

usage: python3 bench/frame_python.py FRAME.raw [ROUNDS]
"""
import sys
import time

import cv2
import numpy as np

W, H = 2448, 2048


def unpack_12p(buf):
    b = np.frombuffer(buf, np.uint8).reshape(-1, 3).astype(np.uint16)
    out = np.empty((b.shape[0], 2), np.uint16)
    out[:, 0] = b[:, 0] | ((b[:, 1] & 0x0F) << 8)
    out[:, 1] = (b[:, 1] >> 4) | (b[:, 2] << 4)
    return out.reshape(H, W)


def process(buf):
    raw = unpack_12p(buf)
    # Cell [90 135; 45 0] in the image frame (+y down; the vendor's names are [90 45; 135 0],
    # counted towards image up); each sub-mosaic is GenICam BayerRG = OpenCV BayerBG.
    code = cv2.COLOR_BayerBG2RGB
    i090 = cv2.cvtColor(np.ascontiguousarray(raw[0::2, 0::2]), code)
    i135 = cv2.cvtColor(np.ascontiguousarray(raw[0::2, 1::2]), code)
    i045 = cv2.cvtColor(np.ascontiguousarray(raw[1::2, 0::2]), code)
    i000 = cv2.cvtColor(np.ascontiguousarray(raw[1::2, 1::2]), code)
    gain = np.float32(1.0 / 4095.0)
    i0, i45, i90, i135 = (x.astype(np.float32) * gain for x in (i000, i045, i090, i135))
    s0 = 0.5 * (i0 + i45 + i90 + i135)
    s1 = i0 - i90
    s2 = i45 - i135
    m0, m1, m2 = s0.mean(axis=2), s1.mean(axis=2), s2.mean(axis=2)
    aop = np.mod(0.5 * np.arctan2(m2, m1), np.pi)
    dop = np.sqrt(m1 * m1 + m2 * m2) / np.where(m0 > 0, m0, np.float32(1.0))
    return s0, s1, s2, aop, dop


def main():
    path = sys.argv[1]
    rounds = int(sys.argv[2]) if len(sys.argv) > 2 else 20
    buf = open(path, "rb").read()
    assert len(buf) == W * H * 3 // 2, f"{path}: not a 2448x2048 12p frame"
    for _ in range(3):
        process(buf)
    times = []
    for _ in range(rounds):
        start = time.perf_counter()
        process(buf)
        times.append((time.perf_counter() - start) * 1e3)
    times.sort()
    ms = times[len(times) // 2]
    print(f"python (numpy {np.__version__}, OpenCV {cv2.__version__}, {cv2.getNumThreads()} threads): "
          f"{ms:.2f} ms per frame = {1e3 / ms:.1f} frames/s (median of {rounds})")
    print(f"python_ms_per_frame {ms:.3f}")


if __name__ == "__main__":
    main()
