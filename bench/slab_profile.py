#!/usr/bin/env python3
"""Cross-section of meshes through their vertical axis: the heights (y) of the vertices
within a thin slab |x| < 0.015, binned by z, clustered into the surfaces they belong to.

Used on the evaluation set's bowl to see how deep a reconstruction carved its concavity
(docs/benchmarks.md, "How deep the bowl is carved"): the true inner floor at z = 0 lies at
y = -0.26, a lid over the opening at about +0.37.

    python3 bench/slab_profile.py MESH.ply [MESH.ply ...]

Reads the binary little-endian PLY files that rmvp writes (x, y, z first among float vertex
properties); standard library only.
"""
import struct
import sys

SLAB = 0.015  # half-width of the slab around the plane x = 0
BIN = 0.1  # z step of the profile
GAP = 0.03  # heights further apart than this belong to different surfaces


def vertices(path):
    data = open(path, "rb").read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    if "format binary_little_endian 1.0" not in header:
        sys.exit(f"{path}: not a binary little-endian PLY")
    count, stride, in_vertex = 0, 0, False
    for line in header:
        words = line.split()
        if words[:2] == ["element", "vertex"]:
            count, in_vertex = int(words[2]), True
        elif words[:1] == ["element"]:
            in_vertex = False
        elif in_vertex and words[:2] == ["property", "float"]:
            stride += 4
        elif in_vertex and words[:1] == ["property"]:
            sys.exit(f"{path}: vertex property {words[-1]} is not a float")
    return [struct.unpack_from("<3f", data, end + i * stride) for i in range(count)]


def profile(path):
    bins = {}
    for x, y, z in vertices(path):
        if abs(x) < SLAB and z >= -BIN / 2:
            bins.setdefault(round(z / BIN), []).append(y)
    print(path)
    for b in sorted(bins):
        surfaces = []
        for y in sorted(bins[b]):
            if surfaces and y - surfaces[-1][-1] < GAP:
                surfaces[-1].append(y)
            else:
                surfaces.append([y])
        print(f"  z={b * BIN:+.1f}: " + "  ".join(f"y {s[0]:+.2f}..{s[-1]:+.2f}" for s in surfaces))


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    for mesh in sys.argv[1:]:
        profile(mesh)
