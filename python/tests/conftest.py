"""Where the outside material is (``shared/`` beside the checkout, or the variables the Rust
suites read), and a PNG reader of numpy and zlib alone, so that files are read here without
rmvp."""

import os
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

SHARED = Path(__file__).resolve().parents[3] / "shared"


def shared(variable: str, folder: str) -> Path:
    return Path(os.environ.get(variable, SHARED / folder))


@pytest.fixture(scope="session")
def fixtures() -> Path:
    return shared("RMVP_FIXTURES", "fixtures")


@pytest.fixture(scope="session")
def real_raw() -> Path:
    return shared("RMVP_REAL_RAW", "real_raw")


def read_png(path: Path) -> np.ndarray:
    """A non-interlaced grey, grey-alpha, RGB or RGBA PNG of 8 or 16 bits as (H, W[, C])."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", path
    at, idat = 8, b""
    while at < len(data):
        (length,) = struct.unpack(">I", data[at : at + 4])
        kind, body = data[at + 4 : at + 8], data[at + 8 : at + 8 + length]
        if kind == b"IHDR":
            width, height, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        at += 12 + length
    assert interlace == 0 and depth in (8, 16), path
    channels = {0: 1, 4: 2, 2: 3, 6: 4}[colour]
    bpp = channels * depth // 8
    stride = width * bpp
    raw = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(height, stride + 1)
    out = np.zeros((height, stride), np.int32)
    previous = np.zeros(stride, np.int32)
    for y in range(height):
        kind, line = raw[y, 0], raw[y, 1:].astype(np.int32)
        row = line.copy()
        if kind == 2:
            row = (line + previous) & 255
        elif kind in (1, 3, 4):
            # Sequential along the row: each byte depends on the one bpp before it.
            for x in range(stride):
                left = row[x - bpp] if x >= bpp else 0
                up = previous[x]
                if kind == 1:
                    predicted = left
                elif kind == 3:
                    predicted = (left + up) // 2
                else:
                    corner = previous[x - bpp] if x >= bpp else 0
                    p = left + up - corner
                    pa, pb, pc = abs(p - left), abs(p - up), abs(p - corner)
                    predicted = left if pa <= pb and pa <= pc else up if pb <= pc else corner
                row[x] = (line[x] + predicted) & 255
        out[y] = row
        previous = row
    pixels = out.astype(np.uint8)
    if depth == 16:
        pixels = pixels.reshape(height, -1, 2)
        pixels = (pixels[..., 0].astype(np.uint16) << 8) | pixels[..., 1]
    pixels = pixels.reshape(height, width, channels)
    return pixels[..., 0] if channels == 1 else pixels
