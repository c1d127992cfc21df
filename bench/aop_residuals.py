#!/usr/bin/python3
"""How far a scene's AoP strays from its true normals, by degree of polarization.

NeRSP's geometric cue assumes that a pixel's AoP is parallel (diffuse) or perpendicular
(specular) to the azimuth of the surface normal in the ray's Stokes frame. This script
measures that assumption on a scene in the NeRSP layout with its ground truth: for every
training pixel inside the mask (eroded by two pixels, away from the silhouette) it takes the
AoP of the channel-mean Stokes vector, the true normal's azimuth and the angle between them
modulo 90 degrees (0: one of the two planes exactly; 45: as far from both as an angle can
be, 22.5 on average for a random AoP), and prints the share of pixels, the residual and the
share that reads as specular, bin by bin of DoP.

    rmvp dataset render-normals SCENE --mesh SCENE/gt/mesh.ply -o NORMALS
    bench/aop_residuals.py SCENE NORMALS [K]

With K, S1 and S2 are first averaged over K x K pixels inside the mask: if the residual were
pixel noise, it would fall.

Needs numpy and OpenCV (`scripts/install-system-deps.sh bench`).
"""

import json
import sys

import cv2
import numpy as np

DOP_BINS = [0.0, 0.01, 0.02, 0.05, 0.1, 0.2, 1.01]


def masked_average(image, mask, size):
    """`image` averaged over `size` x `size` pixels, counting only those inside `mask`."""
    inside = mask.astype(np.float64)
    return cv2.blur(image * inside, (size, size)) / np.maximum(cv2.blur(inside, (size, size)), 1e-9)


def view_geometry(scene, normals, index, camera):
    """One training view's channel-mean Stokes images, its interior pixels (inside the scene's
    and the true mask, eroded by two pixels), each pixel's ray `d`, Stokes frame `(x_r, y_r)`
    and true normal `n`, all in the camera frame, and the normal's `azimuth` in that frame."""
    K = np.array(camera["K"])
    s0, s1, s2 = (np.load(f"{scene}/s{k}/{index:04d}.npy").mean(axis=2).astype(np.float64) for k in range(3))
    mask = cv2.imread(f"{scene}/mask/{index:04d}.png", cv2.IMREAD_GRAYSCALE) > 127
    true_mask = cv2.imread(f"{normals}/{camera['name']}_mask.png", cv2.IMREAD_GRAYSCALE) > 127
    encoded = cv2.imread(f"{normals}/{camera['name']}_normal.png", cv2.IMREAD_UNCHANGED)
    normal_world = encoded[:, :, ::-1].astype(np.float64) / 255 * 2 - 1
    h, w = mask.shape
    rows, cols = np.mgrid[0:h, 0:w]
    pixels = np.stack([cols + 0.5, rows + 0.5, np.ones((h, w))], axis=-1)
    d = pixels @ np.linalg.inv(K).T
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    # The ray's Stokes frame: camera x made perpendicular to the ray, y = d x x_r (image down).
    x_r = np.array([1.0, 0.0, 0.0]) - d[..., :1] * d
    x_r /= np.linalg.norm(x_r, axis=-1, keepdims=True)
    y_r = np.cross(d, x_r)
    n = normal_world @ np.array(camera["R"]).T
    n /= np.linalg.norm(n, axis=-1, keepdims=True) + 1e-12
    azimuth = np.arctan2((n * y_r).sum(-1), (n * x_r).sum(-1))
    interior = cv2.erode((mask & true_mask).astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    return dict(s0=s0, s1=s1, s2=s2, mask=mask, interior=interior, d=d, x_r=x_r, y_r=y_r, n=n, azimuth=azimuth)


def residual_degrees(aop, azimuth):
    """The angle between an AoP and the nearer of a normal azimuth's two planes, degrees."""
    apart = np.mod(aop - azimuth, np.pi)
    return np.degrees(np.minimum(np.minimum(apart, np.pi - apart), np.abs(apart - np.pi / 2)))


def view_residuals(scene, normals, index, camera, average=1):
    """Residual (degrees), DoP and specular-type flag of one view's interior pixels, S1 and S2
    averaged over `average` x `average` pixels first."""
    g = view_geometry(scene, normals, index, camera)
    s0, s1, s2 = g["s0"], g["s1"], g["s2"]
    if average > 1:
        s1, s2 = (masked_average(s, g["mask"], average) for s in (s1, s2))
    azimuth = g["azimuth"]
    aop = 0.5 * np.arctan2(s2, s1)
    dop = np.hypot(s1, s2) / np.maximum(s0, 1e-9)
    apart = np.mod(aop - azimuth, np.pi)
    specular = np.abs(apart - np.pi / 2) < np.minimum(apart, np.pi - apart)
    interior = g["interior"]
    return residual_degrees(aop, azimuth)[interior], dop[interior], specular[interior]


def main():
    if len(sys.argv) not in (3, 4):
        sys.exit(__doc__)
    scene, normals = sys.argv[1:3]
    average = int(sys.argv[3]) if len(sys.argv) == 4 else 1
    cameras = json.load(open(f"{scene}/gt/cameras.json"))["cameras"]
    parts = [view_residuals(scene, normals, i, c, average) for i, c in enumerate(cameras) if c["split"] == "train"]
    residual, dop, specular = (np.concatenate(p) for p in zip(*parts))
    print(f"{scene}: {len(residual)} pixels, residual median {np.median(residual):.2f} deg")
    print("| DoP | pixels | residual median | mean | over 15 deg | specular-type |")
    print("| --- | --- | --- | --- | --- | --- |")
    for lo, hi in zip(DOP_BINS, DOP_BINS[1:]):
        bin_ = (dop >= lo) & (dop < hi)
        if bin_.any():
            r = residual[bin_]
            print(
                f"| {lo:.2f}-{min(hi, 1):.2f} | {bin_.mean() * 100:.1f} % | {np.median(r):.2f} | {r.mean():.2f} "
                f"| {np.mean(r > 15) * 100:.1f} % | {specular[bin_].mean() * 100:.0f} % |"
            )


if __name__ == "__main__":
    main()
