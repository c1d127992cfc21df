"""Reconstruction from Python: a short run with its results and figures, options by the
command line's names, Ctrl-C leaving a run that resumes; evaluation and alignment."""

import json
import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import rmvp


def test_a_short_reconstruction_writes_its_results_and_reports_each_step(fixtures, tmp_path):
    steps = []
    result = rmvp.reconstruct(fixtures / "spot_nersp", tmp_path / "run", iters=20, mesh_res=48, progress=steps.append)
    assert result.finished and result.iteration == result.iterations == 20
    assert [s["iteration"] for s in steps] == list(range(20))
    assert all(np.isfinite(s["loss"]) and "eikonal" in s["losses"] for s in steps)
    assert os.path.getsize(result.mesh) > 0 and len(result.residuals) == 6
    figures = rmvp.evaluate(result.mesh, fixtures / "spot_nersp" / "gt" / "mesh.ply", fixtures / "spot_nersp")
    assert 0 < figures["chamfer"] < 1 and 0 <= figures["fscore"] <= 1
    assert len(figures["normal_views"]) == 8 and 0 < figures["normal_mae_deg"] < 90


def test_options_go_by_the_command_lines_names(fixtures, tmp_path):
    with pytest.raises(rmvp.OptionError, match="unknown field `iterations`"):
        rmvp.reconstruct(fixtures / "spot_nersp", tmp_path / "a", iterations=10)
    with pytest.raises(rmvp.OptionError, match="iterations must be at least 1"):
        rmvp.reconstruct(fixtures / "spot_nersp", tmp_path / "b", iters=0)
    with pytest.raises(rmvp.OptionError):
        rmvp.reconstruct(fixtures / "spot_nersp", tmp_path / "c", preset="slow")


def test_ctrl_c_stops_a_run_that_then_resumes(fixtures, tmp_path):
    out = tmp_path / "run"
    child = textwrap.dedent(
        f"""
        import signal, time, rmvp
        # As in a terminal's Python, whatever the test runner's parent ignores.
        signal.signal(signal.SIGINT, signal.default_int_handler)
        def progress(step):
            print(step["iteration"], flush=True)
            time.sleep(0.05)
        rmvp.reconstruct({str(fixtures / "spot_nersp")!r}, {str(out)!r}, iters=60, mesh_res=32, progress=progress)
        """
    )
    process = subprocess.Popen([sys.executable, "-c", child], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    for line in process.stdout:
        if int(line) >= 5:
            process.send_signal(signal.SIGINT)
            break
    _, stderr = process.communicate(timeout=120)
    assert process.returncode != 0 and "KeyboardInterrupt" in stderr, stderr
    stopped = len((out / "log.jsonl").read_text().splitlines())
    assert 5 < stopped < 60 and (out / "checkpoint.bin").is_file() and not (out / "mesh.ply").exists()
    steps = []
    result = rmvp.reconstruct(fixtures / "spot_nersp", out, iters=60, mesh_res=32, resume=True, progress=steps.append)
    assert result.finished and steps[0]["iteration"] == stopped and len(steps) == 60 - stopped
    # Resuming with other options is refused, naming the checkpoint.
    with pytest.raises(rmvp.OptionError) as refused:
        rmvp.reconstruct(fixtures / "spot_nersp", out, iters=80, resume=True)
    assert refused.value.path.endswith("checkpoint.bin")


def write_ply(path, vertices, faces):
    header = (
        f"ply\nformat ascii 1.0\nelement vertex {len(vertices)}\nproperty float x\nproperty float y\n"
        f"property float z\nelement face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    body = "".join(f"{x} {y} {z}\n" for x, y, z in vertices) + "".join(f"3 {a} {b} {c}\n" for a, b, c in faces)
    path.write_text(header + body)


def test_a_scan_is_aligned_by_the_similarity_it_was_moved_by(fixtures, tmp_path):
    scene = rmvp.read_scene(fixtures / "spot_nersp")
    target = tmp_path / "target.ply"
    write_ply(target, scene.mesh.vertices, scene.mesh.faces)
    angle = np.radians(25)
    rotation = np.array([[np.cos(angle), 0, np.sin(angle)], [0, 1, 0], [-np.sin(angle), 0, np.cos(angle)]])
    scale, shift = 30.0, np.array([5.0, -2.0, 1.0])
    scan = tmp_path / "scan.ply"
    # The scan in millimetres, turned and moved: x_scan = s R x + t.
    write_ply(scan, scale * scene.mesh.vertices @ rotation.T + shift, scene.mesh.faces)
    alignment = rmvp.align(scan, target, tmp_path / "aligned")
    # x = R^T (x_scan - t) / s
    found = alignment["scan_to_target"]
    assert found["s"] == pytest.approx(1 / scale, rel=1e-6)
    np.testing.assert_allclose(np.array(found["r"]), rotation.T, atol=1e-6)
    np.testing.assert_allclose(np.array(found["t"]), -rotation.T @ shift / scale, atol=1e-6)
    assert alignment["rms_point_to_plane"] < 1e-3 and alignment["inlier_ratio"] > 0.99
    assert json.loads((tmp_path / "aligned" / "alignment.json").read_text()) == alignment
