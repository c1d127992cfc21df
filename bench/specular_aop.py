#!/usr/bin/python3
"""How much of a Mitsuba scene's stray AoP its rough specular lobe under the scene's own light
explains.

NeRSP's model polarizes the specular lobe across the mean normal's azimuth, so in the
normal's doubled-angle frame the lobe's S1, S2 have no off-axis part, and neither has the
diffuse lobe (along the azimuth). A rough surface reflects through many half vectors: under a
light that is not uniform, the lit ones are off the normal and their planes of incidence
turn the specular polarization. This script predicts that off-axis part from the ground
truth alone: for every interior training pixel (as `aop_residuals.py` takes them) it
integrates the GGX lobe of the true normal (roughness of the nearest front-facing vertex of
`gt/mesh.ply`, Smith masking, dielectric Fresnel at eta = 1.5) against `gt/env.exr` by Monte
Carlo, single bounce and nothing occluding the light. It prints the share of the measured
off-axis part that the prediction explains (R^2 at unit scale and at the scale that fits
best) and, bin by bin of DoP, the AoP's angle from the nearer of the true normal's planes
before and after the predicted off-axis part is taken away.

    rmvp dataset render-normals SCENE --mesh SCENE/gt/mesh.ply -o NORMALS
    bench/specular_aop.py SCENE NORMALS [--samples N] [--corrected OUT]

N microfacet normals a pixel (default 512). With --corrected, OUT becomes a copy of SCENE whose
azimuth maps (`input_azimuth_maps/`, the AoP that the tangent cue reads) have the predicted
off-axis part taken away; S0, S1, S2 stay as they are. Trained on, it shows what the tangent
cue would give if the model predicted the lobe's polarization as this script does (from the
true normals: an oracle). The environment is looked up as Mitsuba's
`envmap` does: u = atan2(x, -z) / 2 pi, v = acos(y) / pi (top row = +Y).

Needs numpy and OpenCV (`scripts/install-system-deps.sh bench`).
"""

import argparse
import json
import os
import shutil

os.environ.setdefault("OPENCV_IO_ENABLE_OPENEXR", "1")

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from aop_residuals import DOP_BINS, residual_degrees, view_geometry  # noqa: E402
from mesh_section import read_vertex_table  # noqa: E402

ETA = 1.5
# Views whose true normal is this close to the ray have no reliable azimuth (8-bit normals).
MAX_COS_VIEW = 0.95


def read_vertices(path):
    """Positions, normals and GGX roughness of the vertices of a PLY file."""
    table = read_vertex_table(path)

    def columns(*names):
        return np.stack([table[name] for name in names], axis=-1).astype(np.float64)

    return columns("x", "y", "z"), columns("nx", "ny", "nz"), table["roughness_0"]


def roughness_image(vertices, camera, shape):
    """Each pixel's roughness: that of the nearest front-facing vertex projected into the view
    (the nearest in depth where several land in one pixel)."""
    positions, normals, roughness = vertices
    K, R, t = (np.array(camera[k]) for k in ("K", "R", "t"))
    in_camera = positions @ R.T + t
    projected = in_camera @ K.T
    cols = (projected[:, 0] / projected[:, 2]).astype(int)
    rows = (projected[:, 1] / projected[:, 2]).astype(int)
    centre = -R.T @ t
    h, w = shape
    seen = (((centre - positions) * normals).sum(-1) > 0) & (cols >= 0) & (cols < w) & (rows >= 0) & (rows < h)
    image, depth = np.full(shape, np.nan), np.full(shape, np.inf)
    for k in np.nonzero(seen)[0]:
        if in_camera[k, 2] < depth[rows[k], cols[k]]:
            depth[rows[k], cols[k]], image[rows[k], cols[k]] = in_camera[k, 2], roughness[k]
    empty = np.isnan(image).astype(np.uint8)
    _, nearest = cv2.distanceTransformWithLabels(empty, cv2.DIST_L2, 5, labelType=cv2.DIST_LABEL_PIXEL)
    filled_rows, filled_cols = np.nonzero(empty == 0)
    by_label = np.zeros(nearest.max() + 1)
    by_label[nearest[filled_rows, filled_cols]] = image[filled_rows, filled_cols]
    return by_label[nearest]


def fresnel(c):
    """Dielectric reflectances (Rs, Rp) at incidence cosine `c`."""
    c = np.clip(c, 1e-4, 1.0)
    g = np.sqrt(ETA**2 - 1 + c * c)
    return ((c - g) / (c + g)) ** 2, ((ETA**2 * c - g) / (ETA**2 * c + g)) ** 2


def smith_g1(c, alpha):
    """Smith's GGX masking of a direction at cosine `c` to the normal."""
    c = np.clip(c, 1e-6, 1.0)
    return 2.0 / (1.0 + np.sqrt(1.0 + alpha * alpha * (1.0 - c * c) / (c * c)))


def environment(env, directions):
    """The mean-channel radiance of a lat-long map towards world `directions` (Mitsuba's map)."""
    h, w = env.shape
    u = (np.arctan2(directions[..., 0], -directions[..., 2]) / (2 * np.pi)) % 1.0
    v = np.arccos(np.clip(directions[..., 1], -1.0, 1.0)) / np.pi
    return env[np.clip((v * h).astype(int), 0, h - 1), np.clip((u * w).astype(int), 0, w - 1)]


def specular_stokes(n, d, x_r, y_r, alpha, camera, env, samples):
    """Monte Carlo S1, S2 (in the ray frame) of the GGX lobe around `n` seen along `d` under
    `env`: microfacet normals drawn from D(h) (n.h), weight G (v.h) / ((n.v) (n.h)), each
    reflection polarized by (Rs - Rp) / 2 across its own plane of incidence."""
    v = -d
    helper = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    b1 = np.cross(n, helper)
    b1 /= np.linalg.norm(b1, axis=-1, keepdims=True)
    b2 = np.cross(n, b1)
    xi = np.random.default_rng(0).random((samples, 2))
    theta = np.arctan(alpha[:, None] * np.sqrt(xi[None, :, 0] / (1.0 - xi[None, :, 0])))
    phi = 2 * np.pi * xi[None, :, 1]
    h = (
        (np.sin(theta) * np.cos(phi))[..., None] * b1[:, None]
        + (np.sin(theta) * np.sin(phi))[..., None] * b2[:, None]
        + np.cos(theta)[..., None] * n[:, None]
    )
    vh = (h * v[:, None]).sum(-1)
    light = 2 * vh[..., None] * h - v[:, None]
    nl = (light * n[:, None]).sum(-1)
    nv = (n * v).sum(-1)[:, None]
    weight = np.where(
        (nl > 0) & (vh > 0),
        smith_g1(nv, alpha[:, None]) * smith_g1(nl, alpha[:, None]) * vh / (np.clip(nv, 1e-3, 1.0) * np.cos(theta)),
        0.0,
    )
    # Camera to world: x_world = R^T x_camera, as rows: x_camera @ R.
    radiance = environment(env, light @ np.array(camera["R"]))
    rs, rp = fresnel(vh)
    polarized = 0.5 * (rs - rp) * weight * radiance
    across = np.cross(v[:, None], h)
    angle = np.arctan2((across * y_r[:, None]).sum(-1), (across * x_r[:, None]).sum(-1))
    return (polarized * np.cos(2 * angle)).mean(1), (polarized * np.sin(2 * angle)).mean(1)


def write_corrected_azimuth(path, g, inside, across):
    """Rewrite the azimuth map at `path` (16-bit, R = G = B = AoP / pi * 65535, alpha kept) with
    the AoP of the view's S1, S2 less `across` along the normal's off-axis direction on the
    `inside` pixels."""
    azimuth = g["azimuth"][inside]
    s1 = g["s1"][inside] + across * np.sin(2 * azimuth)
    s2 = g["s2"][inside] - across * np.cos(2 * azimuth)
    encoded = np.round(np.mod(0.5 * np.arctan2(s2, s1), np.pi) / np.pi * 65535).astype(np.uint16)
    image = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    for channel in range(3):
        image[..., channel][inside] = encoded
    cv2.imwrite(path, image)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scene")
    parser.add_argument("normals")
    parser.add_argument("--samples", type=int, default=512)
    parser.add_argument("--corrected", metavar="OUT")
    args = parser.parse_args()
    scene, normals, samples = args.scene, args.normals, args.samples
    if args.corrected:
        # Plain copies: the scene's files may be read-only.
        shutil.copytree(scene, args.corrected, copy_function=shutil.copyfile)
    cameras = json.load(open(f"{scene}/gt/cameras.json"))["cameras"]
    env = cv2.imread(f"{scene}/gt/env.exr", cv2.IMREAD_UNCHANGED).astype(np.float64).mean(axis=-1)
    vertices = read_vertices(f"{scene}/gt/mesh.ply")
    columns = {k: [] for k in ("measured_along", "measured_across", "predicted_across", "dop")}
    for index, camera in enumerate(cameras):
        if camera["split"] != "train":
            continue
        g = view_geometry(scene, normals, index, camera)
        inside = g["interior"] & (-(g["n"] * g["d"]).sum(-1) < MAX_COS_VIEW)
        n, d, x_r, y_r = (g[k][inside] for k in ("n", "d", "x_r", "y_r"))
        alpha = roughness_image(vertices, camera, inside.shape)[inside]
        q, u = specular_stokes(n, d, x_r, y_r, alpha, camera, env, samples)
        cos2, sin2 = np.cos(2 * g["azimuth"][inside]), np.sin(2 * g["azimuth"][inside])
        s0, s1, s2 = (g[k][inside] for k in ("s0", "s1", "s2"))
        predicted_across = -q * sin2 + u * cos2
        columns["measured_along"].append(s1 * cos2 + s2 * sin2)
        columns["measured_across"].append(-s1 * sin2 + s2 * cos2)
        columns["predicted_across"].append(predicted_across)
        columns["dop"].append(np.hypot(s1, s2) / np.maximum(s0, 1e-9))
        if args.corrected:
            path = f"{args.corrected}/input_azimuth_maps/{index:04d}.png"
            write_corrected_azimuth(path, g, inside, predicted_across)
    along, across, predicted, dop = (np.concatenate(columns[k]) for k in columns)
    scale = (across * predicted).sum() / (predicted * predicted).sum()

    def explained(k):
        return 1 - ((across - k * predicted) ** 2).sum() / (across**2).sum()

    before = residual_degrees(0.5 * np.arctan2(across, along), 0.0)
    after = residual_degrees(0.5 * np.arctan2(across - predicted, along), 0.0)
    print(
        f"{scene}: {len(along)} pixels; off-axis S1, S2 explained: R^2 {explained(1.0):.2f} at unit scale, "
        f"{explained(scale):.2f} at the best scale {scale:.2f}"
    )
    print("| DoP | pixels | residual median | without the predicted off-axis part |")
    print("| --- | --- | --- | --- |")
    for lo, hi in zip(DOP_BINS, DOP_BINS[1:]):
        bin_ = (dop >= lo) & (dop < hi)
        if bin_.any():
            print(
                f"| {lo:.2f}-{min(hi, 1):.2f} | {bin_.mean() * 100:.1f} % | {np.median(before[bin_]):.2f} "
                f"| {np.median(after[bin_]):.2f} |"
            )
    print(f"| all | 100 % | {np.median(before):.2f} | {np.median(after):.2f} |")


if __name__ == "__main__":
    main()
