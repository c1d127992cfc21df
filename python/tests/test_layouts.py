"""Every layout rmvp reads, read by rmvp and by numpy from the same files: equal where the
format stores the values exactly."""

import json

import numpy as np
import pytest
import rmvp
from conftest import read_png

SCENES = ["spot_nersp", "bunny_nersp"]


@pytest.mark.parametrize("name", SCENES)
def test_a_nersp_scene_is_what_its_files_hold(fixtures, name):
    folder = fixtures / name
    scene = rmvp.read_scene(folder)
    assert scene.layout == "nersp"
    cameras = np.load(folder / "cameras.npz")
    train = scene.train_views
    # The official loader counts the views by the files in image/.
    assert len(train) == len(list((folder / "image").glob("*.png"))) == 6
    np.testing.assert_array_equal(scene.normalization, cameras["scale_mat_0"])
    for i, view in enumerate(train):
        stem = f"{i:04d}"
        for component in ("s0", "s1", "s2"):
            stored = np.load(folder / component / f"{stem}.npy")
            assert getattr(view, component).dtype == np.float32
            np.testing.assert_array_equal(getattr(view, component), stored)
        world_mat = cameras[f"world_mat_{i}"]
        np.testing.assert_array_equal(view.projection, world_mat)
        krt = view.K @ np.hstack([view.R, view.t[:, None]])
        np.testing.assert_allclose(krt, world_mat[:3], rtol=0, atol=1e-9 * np.abs(world_mat).max())
        assert view.s0.shape == (view.height, view.width, 3)
        # The mask: mask/ and the alpha of input_azimuth_maps/ (the official loader's) agree.
        mask = read_png(folder / "mask" / f"{stem}.png")
        azimuth = read_png(folder / "input_azimuth_maps" / f"{stem}.png")
        np.testing.assert_array_equal(view.mask > 127, mask > 127)
        np.testing.assert_array_equal(view.mask > 127, azimuth[..., 3] > 0)
        # The AoP: the official loader's pi * count / 65535.
        official = (np.pi * azimuth[..., 0].astype(np.float64) / 65535).astype(np.float32)
        np.testing.assert_allclose(view.aop, official, rtol=0, atol=4e-7)
        for k, angle in enumerate((0, 45, 90, 135)):
            png = read_png(folder / "polarized" / f"{stem}_{angle:03d}.png")
            np.testing.assert_array_equal(view.polarized[k], png)
    # Held-out views: their cameras as gt/cameras.json gives them.
    described = {c["name"]: c for c in json.loads((folder / "gt" / "cameras.json").read_text())["cameras"]}
    for view in scene.views:
        if view.split == "eval":
            record = described[view.name]
            np.testing.assert_array_equal(view.K, np.array(record["K"]))
            np.testing.assert_array_equal(view.R, np.array(record["R"]))
            np.testing.assert_array_equal(view.t, np.array(record["t"]))
            assert view.normals.shape == (view.height, view.width, 3) and view.s0 is None
    assert scene.mesh is not None and scene.mesh.faces.dtype == np.uint32


@pytest.mark.parametrize("layout", ["rmvp", "rmvp3d", "pandora", "nersp"])
def test_every_layout_keeps_the_scene(fixtures, tmp_path, layout):
    source = fixtures / "spot_nersp"
    original = rmvp.read_scene(source)
    rmvp.convert(source, tmp_path / layout, layout)
    copy = rmvp.read_scene(tmp_path / layout)
    assert copy.layout == layout
    train = copy.train_views
    # PANDORA names views by two-digit stems from 01.
    assert len(train) == len(original.train_views)
    for before, after in zip(original.train_views, train):
        np.testing.assert_allclose(after.K, before.K, rtol=0, atol=1e-12 * np.abs(before.K).max())
        np.testing.assert_allclose(after.R, before.R, atol=1e-12)
        np.testing.assert_allclose(after.t, before.t, atol=1e-12)
        np.testing.assert_array_equal(after.mask > 127, before.mask > 127)
        for component in ("s0", "s1", "s2"):
            a, b = getattr(after, component), getattr(before, component)
            if layout == "pandora":
                # Radiance HDR: 8-bit mantissas under an exponent a pixel's channels share, of
                # the shifted values (up to twice S0); S1 and S2 the difference of two of them.
                np.testing.assert_allclose(a, b, rtol=0, atol=2 ** -6 * np.abs(before.s0).max())
            else:
                np.testing.assert_array_equal(a, b)
    if layout == "rmvp3d":
        # RMVP3D's archives, read by numpy as PolGS reads them.
        archive = np.load(tmp_path / layout / "images_stokes" / "0000.npz")
        for key in ("S0", "S1", "S2"):
            np.testing.assert_array_equal(archive[key], getattr(original.train_views[0], key.lower()))


def test_a_scene_built_in_python_is_written_and_read_back(fixtures, tmp_path):
    scene = rmvp.read_scene(fixtures / "spot_nersp")
    scene.views = scene.train_views[:2]
    view = scene.views[0]
    view.mask = np.where(view.mask > 127, 255, 0).astype(np.uint8)
    view.mask[:10] = 0
    view.s0 = view.s0.astype(np.float64)  # any float dtype; stored as float32
    rmvp.write_scene(scene, tmp_path / "scene", "rmvp")
    back = rmvp.read_scene(tmp_path / "scene")
    assert [v.name for v in back.views] == ["000", "001"]
    np.testing.assert_array_equal(back.views[0].mask, view.mask)
    np.testing.assert_array_equal(back.views[0].s0, view.s0.astype(np.float32))
    np.testing.assert_array_equal(back.views[1].aop, scene.views[1].aop)
