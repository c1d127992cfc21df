"""The pairs COLMAP verified in a posed session, each judged against reference poses: the
figures of docs/design.md's COLMAP paragraph (and of MIN_VERIFIED_MATCHES in
calib/src/poses/colmap.rs).

    python3 bench/colmap_pairs.py SESSION REFERENCE.json

SESSION has been posed by `rmvp poses --method colmap` (its `colmap/database.db`), and
REFERENCE.json is a pose set of the same views from `rmvp poses --method charuco`. A pair's
inlier matches are right where their Sampson distance to the reference's epipolar geometry is
under 2 px (distortion ignored: the simulated lab's is small); a pair is wrong where fewer than
half are. Prints, for the wrong pairs and the right ones, their inlier counts, and each wrong
pair with the angle between its views. Needs numpy.
"""
import json
import sqlite3
import sys

import numpy as np

PAIR_ID_BASE = 2147483647  # COLMAP's pair id: id1 * base + id2, id1 < id2
RIGHT_PX = 2.0


def pose(camera):
    return (np.array(camera["k"], float), np.array(camera["r"], float), np.array(camera["t"], float))


def sampson(k, r1, t1, r2, t2, x1, x2):
    r = r2 @ r1.T
    t = t2 - r @ t1
    cross = np.array([[0, -t[2], t[1]], [t[2], 0, -t[0]], [-t[1], t[0], 0]])
    k_inv = np.linalg.inv(k)
    f = k_inv.T @ cross @ r @ k_inv
    fx1, ftx2 = x1 @ f.T, x2 @ f
    num = np.sum(x2 * fx1, axis=1) ** 2
    den = fx1[:, 0] ** 2 + fx1[:, 1] ** 2 + ftx2[:, 0] ** 2 + ftx2[:, 1] ** 2
    return np.sqrt(num / den), np.degrees(np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1)))


def main(session, reference):
    views = {v["name"]: pose(v["camera"]) for v in json.load(open(reference))["views"]}
    db = sqlite3.connect(f"{session}/colmap/database.db")
    names = {i: name.rsplit(".", 1)[0] for i, name in db.execute("select image_id, name from images")}
    points = {}
    for i, rows, cols, data in db.execute("select image_id, rows, cols, data from keypoints"):
        xy = np.frombuffer(data, np.float32).reshape(rows, cols)[:, :2].astype(float)
        points[i] = np.c_[xy, np.ones(rows)]
    right, wrong = [], []
    for pair, rows, cols, data in db.execute("select pair_id, rows, cols, data from two_view_geometries"):
        if rows == 0:
            continue
        i2 = pair % PAIR_ID_BASE
        i1 = (pair - i2) // PAIR_ID_BASE
        a, b = names[i1], names[i2]
        if a not in views or b not in views:
            continue
        matches = np.frombuffer(data, np.uint32).reshape(rows, cols)
        (k, r1, t1), (_, r2, t2) = views[a], views[b]
        distance, angle = sampson(k, r1, t1, r2, t2, points[i1][matches[:, 0]], points[i2][matches[:, 1]])
        share = float(np.mean(distance < RIGHT_PX))
        (right if share >= 0.5 else wrong).append((rows, a, b, angle, share))
    print(f"{len(right) + len(wrong)} verified pairs: {len(wrong)} mostly wrong, {len(right)} right")
    print("wrong pairs' inliers:", sorted(w[0] for w in wrong))
    print("right pairs' fewest inliers:", sorted(r[0] for r in right)[:12])
    for rows, a, b, angle, share in sorted(wrong):
        print(f"  wrong {a}-{b}: {rows} inliers, views {angle:.0f} degrees apart, {100 * share:.0f} % right")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
