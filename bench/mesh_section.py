#!/usr/bin/python3
"""A cross-section of meshes through one plane, drawn as a picture: where a reconstruction
leaves a concavity uncarved, or a thin part too thick, which a normal error only hints at.

    bench/mesh_section.py OUT.png TRUE.ply RECONSTRUCTION.ply [RECONSTRUCTION.ply ...]
                          [--axis x] [--width 0.01] [--labels "a;b;..."]

Draws the vertices within --width of the plane through the origin across --axis (x, y or z),
the true mesh in black dots, each reconstruction in its own colour (blue, red, green, orange,
purple), in the scene's unit-sphere coordinates, cropped to what is drawn, with a legend
below; the labels (separated by semicolons) default to the reconstructions' folder names.
Reads binary little-endian or ASCII PLY with x, y, z among its vertex properties.

Needs numpy and OpenCV (`scripts/install-system-deps.sh bench`).
"""

import argparse
import os

import numpy as np

SIZE = 600
SCALE = 250
COLOURS = [(200, 80, 0), (0, 0, 220), (0, 150, 0), (0, 140, 255), (160, 0, 160)]
TYPES = {"float": "<f4", "float32": "<f4", "double": "<f8", "uchar": "u1", "uint8": "u1", "char": "i1",
         "int8": "i1", "short": "<i2", "ushort": "<u2", "int": "<i4", "int32": "<i4", "uint": "<u4"}


def read_vertex_table(path):
    """The vertex element of a PLY file as a numpy structured array, one field per property."""
    raw = open(path, "rb").read()
    end = raw.index(b"end_header") + len(b"end_header")
    end = raw.index(b"\n", end) + 1
    header = raw[:end].decode("ascii").splitlines()
    count, props, in_vertex = 0, [], False
    for line in header:
        words = line.split()
        if words[:1] == ["element"]:
            in_vertex = words[1] == "vertex"
            if in_vertex:
                count = int(words[2])
        elif words[:1] == ["property"] and in_vertex:
            if words[1] not in TYPES:
                raise ValueError(f"{path}: vertex property {words[-1]} of type {words[1]}, not a scalar")
            props.append((words[2], TYPES[words[1]]))
    dtype = np.dtype(props)
    if any("ascii" in line for line in header):
        rows = raw[end:].decode("ascii").splitlines()[:count]
        return np.array([tuple(float(v) for v in row.split()[: len(props)]) for row in rows], dtype=dtype)
    if len(raw) - end < dtype.itemsize * count:
        raise ValueError(f"{path}: {count} vertices declared, the file is shorter")
    return np.frombuffer(raw[end:], dtype=dtype, count=count)


def read_positions(path):
    """The vertex positions of a PLY file (n x 3)."""
    table = read_vertex_table(path)
    return np.stack([table["x"], table["y"], table["z"]], axis=-1).astype(np.float64)


def main():
    import cv2  # only to draw: the readers above serve scripts without OpenCV

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out")
    parser.add_argument("truth")
    parser.add_argument("reconstructions", nargs="+")
    parser.add_argument("--axis", choices="xyz", default="x")
    parser.add_argument("--width", type=float, default=0.01)
    parser.add_argument("--labels")
    args = parser.parse_args()
    across = "xyz".index(args.axis)
    u, v = [k for k in range(3) if k != across]
    if args.axis == "x":
        u, v = 2, 1  # z to the right, y up
    labels = args.labels.split(";") if args.labels else [
        os.path.basename(os.path.dirname(os.path.abspath(p))) for p in args.reconstructions]
    image = np.full((SIZE, SIZE, 3), 255, np.uint8)

    def draw(points, colour, radius):
        for p in points[np.abs(points[:, across]) < args.width]:
            centre = (int(SIZE / 2 + SCALE * p[u]), int(SIZE / 2 - SCALE * p[v]))
            cv2.circle(image, centre, radius, colour, -1)

    entries = []
    for i, path in enumerate(args.reconstructions):
        colour = COLOURS[i % len(COLOURS)]
        draw(read_positions(path), colour, 1)
        entries.append((labels[i], colour))
    draw(read_positions(args.truth), (0, 0, 0), 2)
    entries.append(("truth", (0, 0, 0)))
    rows = np.nonzero((image < 255).any(axis=(1, 2)))[0]
    image = image[max(rows.min() - 10, 0) : rows.max() + 11] if len(rows) else image
    legend = np.full((22 * len(entries) + 8, SIZE, 3), 255, np.uint8)
    for i, (text, colour) in enumerate(entries):
        cv2.putText(legend, text, (10, 20 + 22 * i), cv2.FONT_HERSHEY_SIMPLEX, 0.55, colour, 2)
    cv2.imwrite(args.out, np.vstack([image, legend]))


if __name__ == "__main__":
    main()
