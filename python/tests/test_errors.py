"""Broken and hostile files raise the exception of their kind, naming the file once."""

import hashlib
import os
import shutil

import numpy as np
import pytest
import rmvp


@pytest.fixture
def scene_copy(fixtures, tmp_path):
    folder = tmp_path / "spot"
    shutil.copytree(fixtures / "spot_nersp", folder)
    return folder


def test_a_missing_scene_or_frame_is_a_missing_file(tmp_path):
    with pytest.raises(rmvp.MissingFileError) as missing:
        rmvp.read_scene(tmp_path / "absent")
    assert isinstance(missing.value, FileNotFoundError) and missing.value.path == str(tmp_path / "absent")
    with pytest.raises(FileNotFoundError):
        rmvp.read_raw(tmp_path / "frame.raw", "BayerRGPolarized12p")


def test_a_truncated_array_names_its_file(scene_copy):
    broken = scene_copy / "s1" / "0003.npy"
    broken.write_bytes(broken.read_bytes()[:200])
    with pytest.raises(rmvp.InputError) as error:
        rmvp.read_scene(scene_copy)
    assert error.value.path == str(broken)
    assert str(error.value).count(str(broken)) == 1


def test_a_fifo_where_an_array_should_be_is_refused_without_hanging(scene_copy):
    fifo = scene_copy / "s0" / "0002.npy"
    fifo.unlink()
    os.mkfifo(fifo)
    with pytest.raises(rmvp.InputError, match="not a regular file") as error:
        rmvp.read_scene(scene_copy)
    assert error.value.path == str(fifo)


def test_an_array_of_the_wrong_shape_is_refused_before_writing(fixtures, tmp_path):
    scene = rmvp.read_scene(fixtures / "spot_nersp")
    scene.views[0].mask = scene.views[0].mask[:, :-1]
    with pytest.raises(rmvp.InputError):
        rmvp.write_scene(scene, tmp_path / "out", "rmvp")
    assert not (tmp_path / "out" / "scene.json").exists()
    with pytest.raises(rmvp.OptionError, match="layout"):
        rmvp.write_scene(fixtures / "spot_nersp", tmp_path / "other", "colmap")


def test_a_release_is_read_only_when_its_files_match_its_checksums(scene_copy, tmp_path):
    # A release of one object: its folder (build.json, rmvp/) listed in SHA256SUMS.
    release = tmp_path / "release"
    rmvp.convert(scene_copy, release / "spot" / "rmvp", "rmvp")
    (release / "spot" / "build.json").write_text("{}")
    listing = []
    for root, _dirs, files in os.walk(release):
        for name in files:
            path = os.path.join(root, name)
            with open(path, "rb") as f:
                digest = hashlib.sha256(f.read()).hexdigest()
            listing.append(f"{digest}  {os.path.relpath(path, release)}")
    (release / "SHA256SUMS").write_text("\n".join(sorted(listing)) + "\n")
    train = rmvp.read_release(release)
    held_out = rmvp.read_release(release, split="eval")
    assert list(train) == ["spot"] and all(v.split == "train" for v in train["spot"].views)
    assert len(train["spot"].views) + len(held_out["spot"].views) == len(rmvp.read_scene(scene_copy).views)
    with pytest.raises(rmvp.OptionError):
        rmvp.read_release(release, split="test")
    (release / "spot" / "stray.txt").write_text("not published")
    with pytest.raises(rmvp.InputError) as error:
        rmvp.read_release(release)
    assert "spot/stray.txt: not listed in SHA256SUMS" in str(error.value)
    with pytest.raises(rmvp.MissingFileError):
        rmvp.read_release(tmp_path / "absent")
