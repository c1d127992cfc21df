"""Raw frames and polarization: a real IMX250MZR mosaic demosaiced by rmvp against numpy on
its cells; Stokes against the measurement model; the AoP tangents against the official NeRSP
loader's computation."""

import numpy as np
import pytest
import rmvp


def test_a_real_mono_mosaic_splits_into_the_sensors_angles(real_raw):
    raw = rmvp.read_raw(real_raw / "fruits_IMX250MZR.png", "Polarized8")
    assert raw.shape == (2048, 2448) and raw.dtype == np.uint16
    frame = rmvp.demosaic(raw, "Polarized8")
    # The cell's sites in the image frame (y down): [90 135; 45 0] (the vendor's names turn
    # towards image up).
    cells = raw.astype(np.float64)
    i90, i135, i45, i0 = cells[0::2, 0::2], cells[0::2, 1::2], cells[1::2, 0::2], cells[1::2, 1::2]
    for got, want in zip(frame.angles, (i0, i45, i90, i135)):
        np.testing.assert_array_equal(got, want)
    full = 255.0
    s0, s1, s2 = (i0 + i45 + i90 + i135) / 2 / full, (i0 - i90) / full, (i45 - i135) / full
    for got, want in zip((frame.s0, frame.s1, frame.s2), (s0, s1, s2)):
        assert got.shape == (1024, 1224) and got.dtype == np.float32
        np.testing.assert_allclose(got, want, rtol=0, atol=2e-7)
    aop = np.mod(0.5 * np.arctan2(s2, s1), np.pi)
    dop = np.hypot(s1, s2) / np.maximum(s0, 1e-12)
    polarized = dop > 0.05
    difference = np.abs(np.angle(np.exp(2j * (frame.aop[polarized] - aop[polarized])))) / 2
    assert difference.max() < 1e-5
    np.testing.assert_allclose(frame.dop[s0 > 0.02], dop[s0 > 0.02], rtol=1e-5, atol=1e-6)
    # Saturated angles: the samples at full scale (one in this frame).
    at_full_scale = sum((cell >= full).astype(np.uint8) for cell in (i0, i45, i90, i135))
    np.testing.assert_array_equal(frame.saturated, at_full_scale)


def test_the_pixel_format_bounds_the_samples():
    raw = np.full((8, 8), 300, np.uint16)
    with pytest.raises(rmvp.InputError, match="exceeds"):
        rmvp.demosaic(raw, "Polarized8")
    with pytest.raises(rmvp.OptionError, match="unsupported pixel format"):
        rmvp.demosaic(raw, "Mono9")


def test_stokes_inverts_the_measurement_model():
    rng = np.random.default_rng(3)
    s0 = rng.uniform(0.2, 1.0, (5, 7, 3))
    dop, aop = rng.uniform(0, 1, s0.shape), rng.uniform(0, np.pi, s0.shape)
    s1, s2 = s0 * dop * np.cos(2 * aop), s0 * dop * np.sin(2 * aop)
    images = [0.5 * (s0 + s1 * np.cos(2 * t) + s2 * np.sin(2 * t)) for t in np.radians([0, 45, 90, 135])]
    out = rmvp.stokes(*images)
    for got, want in zip((out.s0, out.s1, out.s2), (s0, s1, s2)):
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-6)
    assert out.aop.shape == (5, 7)


def test_the_aop_tangents_are_the_official_loaders_corrected_for_the_ray(fixtures):
    scene = rmvp.read_scene(fixtures / "spot_nersp")
    for view in scene.train_views:
        t, e = rmvp.aop_tangents(view)
        inside = view.mask > 127
        # The official NeRSP loader (models/dataio/ours_data.py): r1 sin(a) - r2 cos(a), with
        # r1 and r2 the camera's x and y axes in the world, for every pixel alike.
        a = view.aop.astype(np.float64)[..., None]
        official = view.R[0] * np.sin(a) - view.R[1] * np.cos(a)
        # Each pixel's ray, through its centre.
        jj, ii = np.mgrid[0 : view.height, 0 : view.width]
        pixels = np.stack([ii + 0.5, jj + 0.5, np.ones(ii.shape)], -1)
        d = pixels @ np.linalg.inv(view.K).T @ view.R
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        # rmvp's: perpendicular to the ray and to the polarization direction e, which lies
        # across the ray.
        assert np.abs(np.sum(t * d, -1)).max() < 1e-12 and np.abs(np.sum(e * d, -1)).max() < 1e-12
        # The same line as the official tangent (reversed) where the ray is the optical axis,
        # turned by at most the ray's angle to the axis elsewhere.
        cosine = -np.sum(official * t, -1) / np.linalg.norm(official, axis=-1) / np.linalg.norm(t, axis=-1)
        turned = np.degrees(np.arccos(np.clip(np.abs(cosine), 0, 1)))
        off_axis = np.degrees(np.arccos(np.clip(d @ view.R[2], -1, 1)))
        assert np.all(cosine[inside] > 0)
        assert np.all(turned[inside] <= 1.01 * off_axis[inside] + 1e-6), (turned - off_axis)[inside].max()
        assert np.median(turned[inside]) < 5
