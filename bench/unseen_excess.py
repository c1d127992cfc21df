#!/usr/bin/python3
"""Where a reconstruction has surface the truth has not, and whether any training view could
have told: of the mesh's vertices farther from the true surface than twice the F-score
threshold (1 % of the truth's bounding-box diagonal), how many lie outside the training masks'
visual hull (some view sees background there), how many are seen past (some view sees them in
front of the true surface) and how many lie where no training view sees (behind the true
surface in every view that frames them), with the box of each.

    bench/unseen_excess.py SCENE RECONSTRUCTION.ply

SCENE is a scene with its ground truth (mesh, per-view masks and depth), e.g. a quality
bench's `target/tmp/bench-quality/256x256/float/nersp`. Needs numpy and the rmvp Python
package (`./run python`, then `.venv/bin/python bench/unseen_excess.py ...`).
"""

import argparse

import numpy as np
import rmvp

from mesh_section import read_positions


def nearest_distance(points, surface_points):
    """The distance from each point to the nearest of `surface_points` (chunked brute force)."""
    out = np.empty(len(points))
    for i in range(0, len(points), 2000):
        d = ((points[i:i + 2000, None, :] - surface_points[None]) ** 2).sum(-1)
        out[i:i + 2000] = np.sqrt(d.min(1))
    return out


def project(view, points):
    """Pixel column and row of each point in `view`, its camera depth, and whether it is framed."""
    x = points @ np.asarray(view.R).T + np.asarray(view.t)
    u = x @ np.asarray(view.K).T
    with np.errstate(divide="ignore", invalid="ignore"):
        col, row = u[:, 0] / u[:, 2], u[:, 1] / u[:, 2]
    framed = (x[:, 2] > 0) & (col >= 0) & (row >= 0) & (col < view.width) & (row < view.height)
    return col, row, x[:, 2], framed


def single_channel(image):
    image = np.asarray(image)
    return image[..., 0] if image.ndim == 3 else image


def box(points):
    lo, hi = points.min(0), points.max(0)
    return ", ".join(f"{'xyz'[k]} {lo[k]:.3f} .. {hi[k]:.3f}" for k in range(3))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene")
    parser.add_argument("mesh")
    args = parser.parse_args()
    scene = rmvp.read_scene(args.scene)
    if scene.mesh is None:
        raise SystemExit(f"{args.scene}: no true mesh")
    vertices = np.asarray(scene.mesh.vertices, np.float64)
    faces = np.asarray(scene.mesh.faces)
    truth = np.concatenate([vertices, vertices[faces].mean(1)])
    threshold = 0.01 * np.linalg.norm(vertices.max(0) - vertices.min(0))
    mesh = read_positions(args.mesh)
    excess = mesh[nearest_distance(mesh, truth) > 2 * threshold]
    print(f"{len(excess)} of {len(mesh)} vertices ({100 * len(excess) / len(mesh):.1f} %) farther than "
          f"{2 * threshold:.4f} from the truth (its box: {box(vertices)})")
    if len(excess) == 0:
        return
    outside_hull = np.zeros(len(excess), bool)
    seen_past = np.zeros(len(excess), bool)
    for view in scene.views:
        if view.split != "train":
            continue
        col, row, depth, framed = project(view, excess)
        at = np.where(framed)[0]
        c, r = col[at].astype(int), row[at].astype(int)
        if view.mask is not None:
            outside_hull[at[single_channel(view.mask)[r, c] < 128]] = True
        if view.depth is not None:
            surface = single_channel(view.depth)[r, c]
            seen_past[at[(surface <= 0) | (depth[at] < surface - threshold)]] = True
    unseen = ~(seen_past | outside_hull)
    for name, which in [("outside the visual hull", outside_hull), ("seen past", seen_past),
                        ("where no training view sees", unseen)]:
        share = f"{which.sum()} ({100 * which.mean():.1f} %)"
        print(f"{name}: {share}" + (f"; {box(excess[which])}" if which.any() else ""))


if __name__ == "__main__":
    main()
