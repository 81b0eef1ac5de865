"""Whole runs from Python (`wgslam.run`) against the command line on the same frames."""

import filecmp
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import wgslam
from conftest import BUNDLED, command_line, run_cli

# A short range of the bundled frames (first with ground truth is 1): enough for tracking,
# fusion and the robust profile's surfel removal to run, a few seconds on the CPU backend.
FRAMES = "1..12"


def test_run_writes_the_command_lines_files_byte_for_byte(tmp_path):
    cli_out = tmp_path / "cli"
    done = run_cli("run", BUNDLED, "--frames", FRAMES, "--backend", "cpu", "--out", cli_out)
    assert done.returncode == 0, done.stderr
    seen = []
    result = wgslam.run(BUNDLED, frames=FRAMES, backend="cpu", progress=lambda d, t: seen.append((d, t)))
    assert seen == [(k, 12) for k in range(1, 13)]
    py_out = tmp_path / "py"
    result.write(py_out)
    for name in ("trajectory.tum", "trajectory_odometry.tum", "map.ply"):
        assert filecmp.cmp(cli_out / name, py_out / name, shallow=False), name
    # The arrays are the file's poses: the TUM text holds them to its printed precision.
    tum = np.loadtxt(cli_out / "trajectory.tum")
    assert np.array_equal(result.stamps, tum[:, 0])
    assert np.allclose(result.poses[:, :3, 3], tum[:, 1:4], atol=1e-6)
    assert result.poses.shape == (12, 4, 4) and result.poses.dtype == np.float64
    m = result.map
    n = result.metrics["map_points"]
    assert m["positions"].shape == (n, 3) and m["positions"].dtype == np.float32
    assert m["colors"].shape == (n, 3) and m["colors"].dtype == np.uint8
    assert m["weights"].shape == (n,)
    assert len(result.frames) == 12 and result.frames[0]["index"] == 1
    assert result.metrics["accuracy"]["ate_rmse_aligned_m"] < 0.01


def test_params_dict_is_the_parameter_file(tmp_path):
    params = {"profile": "assignment", "icp": {"dist_m": 0.08}}
    result = wgslam.run(BUNDLED, frames=(1, 3), backend="cpu", params=params)
    assert result.metrics["params"]["icp"]["dist_m"] == pytest.approx(0.08)
    assert result.metrics["first_frame"] == 1 and result.metrics["last_frame"] == 3


def test_errors_carry_the_command_lines_message(tmp_path):
    missing = tmp_path / "no-such-sequence"
    done = run_cli("run", missing, "--backend", "cpu", "--out", tmp_path / "o")
    assert done.returncode == 1
    line = [l for l in done.stderr.splitlines() if l.startswith("error: ")][-1]
    with pytest.raises(wgslam.Error) as e:
        wgslam.run(missing, backend="cpu")
    assert "error: " + str(e.value) == line
    with pytest.raises(wgslam.Error, match="unknown key `no-such-key`"):
        wgslam.run(BUNDLED, frames="1..2", backend="cpu", params={"no-such-key": 1})
    with pytest.raises(ValueError, match="backend"):
        wgslam.run(BUNDLED, backend="tpu")


def test_progress_callback_exception_stops_the_run():
    def stop(done, total):
        if done == 2:
            raise KeyError("enough")

    with pytest.raises(KeyError, match="enough"):
        wgslam.run(BUNDLED, frames="1..10", backend="cpu", progress=stop)


def test_the_wheels_command_is_the_command_line(tmp_path):
    """The installed `wgslam` script (beside this interpreter) prints, exits and writes as
    the command line does."""
    script = Path(sys.executable).parent / "wgslam"
    assert script.is_file(), f"the wheel installs no {script}"
    for args in (["--version"], ["run", "--no-such-flag"]):
        ours = subprocess.run([script, *args], capture_output=True, text=True)
        theirs = run_cli(*args)
        assert (ours.returncode, ours.stdout, ours.stderr) == (
            theirs.returncode,
            theirs.stdout,
            # clap's usage line names the program as invoked.
            theirs.stderr.replace(Path(command_line()).name, "wgslam"),
        ), args
    done = subprocess.run(
        [script, "run", BUNDLED, "--frames", "1..3", "--backend", "cpu", "--out", tmp_path],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    poses = [l for l in (tmp_path / "trajectory.tum").read_text().splitlines() if not l.startswith("#")]
    assert len(poses) == 3
