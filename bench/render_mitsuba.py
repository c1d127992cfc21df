"""Mitsuba 3 on the render benchmark's views: the same mesh, environment and cameras that
`cargo bench -p rmvp-render --bench render` exported, the same material (pplastic, eta 1.5,
alpha 0.1) and the same sampling budget (per sample one emitter and one BSDF sample of the
`direct` integrator inside `stokes`). Prints seconds per view; the first view includes Mitsuba's
JIT compilation and is reported apart.

usage: python bench/render_mitsuba.py EXPORT_DIR [VARIANT]
"""
import json
import sys
import time

import mitsuba as mi
import numpy as np


def to_world(R, t):
    """OpenCV world-to-camera (x right, y down, z forward) to Mitsuba camera-to-world (x left, y up)."""
    R = np.array(R)
    C = -R.T @ np.array(t)
    M = np.eye(4)
    M[:3, 0] = -R[0]
    M[:3, 1] = -R[1]
    M[:3, 2] = R[2]
    M[:3, 3] = C
    return mi.ScalarTransform4f(M.tolist())


def main():
    folder = sys.argv[1]
    variant = sys.argv[2] if len(sys.argv) > 2 else "llvm_ad_mono_polarized"
    mi.set_variant(variant)
    mi.set_log_level(mi.LogLevel.Error)
    spec = json.load(open(f"{folder}/cameras.json"))
    spp = spec["spp"]
    scene = mi.load_dict({
        "type": "scene",
        "integrator": {"type": "stokes", "integrator": {"type": "direct", "emitter_samples": 1, "bsdf_samples": 1}},
        "env": {"type": "envmap", "filename": f"{folder}/env.exr"},
        "object": {
            "type": "ply",
            "filename": f"{folder}/mesh.ply",
            "bsdf": {"type": "pplastic", "diffuse_reflectance": {"type": "rgb", "value": [0.75, 0.45, 0.3]},
                     "alpha": 0.1, "int_ior": 1.5, "ext_ior": 1.0},
        },
    })
    times = []
    for cam in spec["cameras"]:
        K = cam["K"]
        fov = 2 * np.degrees(np.arctan(cam["height"] / 2 / K[1][1]))
        sensor = mi.load_dict({
            "type": "perspective",
            "fov": fov,
            "fov_axis": "y",
            "to_world": to_world(cam["R"], cam["t"]),
            "film": {"type": "hdrfilm", "width": cam["width"], "height": cam["height"]},
            "sampler": {"type": "independent", "sample_count": spp},
        })
        start = time.perf_counter()
        image = mi.render(scene, sensor=sensor, spp=spp)
        np.array(image)  # force evaluation
        times.append(time.perf_counter() - start)
    steady = sum(times[1:]) / (len(times) - 1)
    print(f"mitsuba {mi.__version__} {variant}: first view {times[0]:.3f} s (with JIT), then {steady:.3f} s per view")
    print(f"mitsuba_s_per_view {steady:.4f}")


if __name__ == "__main__":
    main()
