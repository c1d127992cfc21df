#!/usr/bin/python3
"""Normal error binned by how curved the true surface is at each pixel.

The curvature is read from the true normal map: the largest angle between a pixel's true
normal and those two pixels away (the eight neighbours at that distance), in degrees: a flat
face reads 0 (up to the maps' quantisation), a crease tens of degrees. It is a measure in
pixels, so it depends on the views' size and framing. Pixels within two of the mask's edge are
left out, so the silhouette does not count as curvature.

    rmvp dataset render-normals SCENE --mesh SCENE/gt/mesh.ply -o TRUE
    bench/error_by_curvature.py TRUE RUN_A/normals RUN_B/normals ...

Each RUN is the `normals/` folder of a reconstruction (`NNN.png`, the views in the scene's
order, as `rmvp recon` writes them); TRUE holds `NNN_normal.png` and `NNN_mask.png`. The
views every folder has are compared on the pixels every reconstruction covers.

Needs numpy and OpenCV (`scripts/install-system-deps.sh bench`).
"""

import os
import sys

import cv2
import numpy as np

BINS = [0.0, 1.0, 3.0, 6.0, 10.0, 20.0, 180.0]


def read_normals(path):
    """A normal map written by rmvp (8 or 16 bits, RGB = (n + 1) / 2) as unit vectors."""
    image = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    if image is None:
        raise FileNotFoundError(path)
    scale = 65535.0 if image.dtype == np.uint16 else 255.0
    normals = image[..., ::-1].astype(np.float64) / scale * 2.0 - 1.0
    return normals / np.maximum(np.linalg.norm(normals, axis=2, keepdims=True), 1e-9)


def angle(a, b):
    """Angle between unit vector images, degrees."""
    return np.degrees(np.arccos(np.clip((a * b).sum(axis=2), -1.0, 1.0)))


def curvature(normals):
    """The largest angle between each pixel's normal and those two pixels away."""
    largest = np.zeros(normals.shape[:2])
    for dy in (-2, 0, 2):
        for dx in (-2, 0, 2):
            shifted = np.roll(np.roll(normals, dy, axis=0), dx, axis=1)
            largest = np.maximum(largest, angle(shifted, normals))
    return largest


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    truth, runs = sys.argv[1], sys.argv[2:]
    curved, errors = [], [[] for _ in runs]
    view = 0
    while os.path.exists(os.path.join(truth, f"{view:03d}_normal.png")) and all(
        os.path.exists(os.path.join(run, f"{view:03d}.png")) for run in runs
    ):
        true = read_normals(os.path.join(truth, f"{view:03d}_normal.png"))
        mask = cv2.imread(os.path.join(truth, f"{view:03d}_mask.png"), cv2.IMREAD_GRAYSCALE) > 0
        inside = cv2.erode(mask.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
        predicted = [read_normals(os.path.join(run, f"{view:03d}.png")) for run in runs]
        for p in predicted:
            inside &= np.isfinite(p).all(axis=2)
        curved.append(curvature(true)[inside])
        for k, p in enumerate(predicted):
            errors[k].append(angle(p, true)[inside])
        view += 1
    if view == 0:
        sys.exit("no view found in every folder")
    curved = np.concatenate(curved)
    errors = [np.concatenate(e) for e in errors]
    print(f"{view} views, {len(curved)} pixels; normal MAE in degrees, one column per run")
    print("| curvature (degrees over 2 px) | share | " + " | ".join(runs) + " |")
    print("| --- | --- |" + " --- |" * len(runs))
    print("| all | 100 % | " + " | ".join(f"{e.mean():.2f}" for e in errors) + " |")
    for lo, hi in zip(BINS[:-1], BINS[1:]):
        pick = (curved >= lo) & (curved < hi)
        if pick.any():
            cells = " | ".join(f"{e[pick].mean():.2f}" for e in errors)
            print(f"| {lo:g}-{hi:g} | {100 * pick.mean():.0f} % | {cells} |")


if __name__ == "__main__":
    main()
