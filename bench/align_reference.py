"""The references of the align benchmark: Open3D point-to-plane ICP and small_gicp GICP on the
scan and target that `cargo bench -p rmvp-align --bench align` exported. Neither solves for
scale, so both start from the usual rescale (centroids matched, RMS radii matched), then run
6-DoF ICP from the 20-degree offset. Times include what each needs to prepare (normals,
covariances, trees); reading the files is excluded.

usage: python bench/align_reference.py EXPORT_DIR
"""
import json
import sys
import time

import numpy as np
import open3d as o3d
import small_gicp


def errors(found, truth):
    """Rotation error (deg), scale error (%), translation error of a 4x4 similarity."""
    def split(m):
        s = np.cbrt(np.linalg.det(m[:3, :3]))
        return m[:3, :3] / s, s, m[:3, 3]
    (ra, sa, ta), (rb, sb, tb) = split(found), split(truth)
    angle = np.degrees(np.arccos(np.clip((np.trace(ra @ rb.T) - 1) / 2, -1, 1)))
    return angle, 100 * (sa / sb - 1), np.linalg.norm(ta - tb)


def main():
    folder = sys.argv[1]
    truth = np.array(json.load(open(f"{folder}/truth.json"))["matrix"])
    scan = np.asarray(o3d.io.read_point_cloud(f"{folder}/scan.ply").points)
    mesh = o3d.io.read_triangle_mesh(f"{folder}/target.ply")
    target = np.asarray(mesh.vertices)

    start = time.perf_counter()
    cs, ct = scan.mean(0), target.mean(0)
    s = np.sqrt(((target - ct) ** 2).sum(1).mean() / ((scan - cs) ** 2).sum(1).mean())
    rescale = np.eye(4)
    rescale[:3, :3] *= s
    rescale[:3, 3] = ct - s * cs
    rescale_seconds = time.perf_counter() - start

    start = time.perf_counter()
    mesh.compute_vertex_normals()
    tpcd = o3d.geometry.PointCloud(mesh.vertices)
    tpcd.normals = mesh.vertex_normals
    spcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(scan))
    result = o3d.pipelines.registration.registration_icp(
        spcd, tpcd, 10.0, rescale,
        o3d.pipelines.registration.TransformationEstimationPointToPlane(o3d.pipelines.registration.TukeyLoss(k=2.0)),
        o3d.pipelines.registration.ICPConvergenceCriteria(max_iteration=60))
    o3d_seconds = time.perf_counter() - start + rescale_seconds
    angle, scale, t = errors(result.transformation, truth)
    print(f"  Open3D {o3d.__version__} point-to-plane: {o3d_seconds:.2f} s, rotation error {angle:.4f} deg, "
          f"scale error {scale:+.4f} %, translation error {t:.3f} mm")
    print(f"row\tOpen3D {o3d.__version__} point-to-plane ICP\t{o3d_seconds:.2f} s\t{angle:.4f} deg\t{scale:+.2f} %\t{t:.3f} mm")

    start = time.perf_counter()
    result = small_gicp.align(target, scan, init_T_target_source=rescale, registration_type="GICP",
                              max_correspondence_distance=10.0, num_threads=2, max_iterations=60)
    gicp_seconds = time.perf_counter() - start + rescale_seconds
    angle, scale, t = errors(result.T_target_source, truth)
    print(f"  small_gicp {small_gicp.__version__ if hasattr(small_gicp, '__version__') else ''} GICP: {gicp_seconds:.2f} s, "
          f"rotation error {angle:.4f} deg, scale error {scale:+.4f} %, translation error {t:.3f} mm")
    print(f"row\tsmall_gicp GICP\t{gicp_seconds:.2f} s\t{angle:.4f} deg\t{scale:+.2f} %\t{t:.3f} mm")
    print(f"open3d_seconds {o3d_seconds:.3f}")
    print(f"small_gicp_seconds {gicp_seconds:.3f}")


if __name__ == "__main__":
    main()
