"""Recordings written by another tool (the ``rosbags`` package, ``bag_fixtures.py``): a ROS 1
``.bag`` with lz4 chunks and a ROS 2 bag in SQLite, holding the bundled frames as
``16UC1`` depth and ``bgr8`` colour, run on the command line to the same trajectory as the
folder, byte for byte; ``wgslam.run`` reads them too. The MCAP form is tested in Rust
(``tests/it/bags.rs``), written by the ``mcap`` crate's writer."""

import pytest

pytest.importorskip("rosbags")

import wgslam  # noqa: E402
from bag_fixtures import bundled_frames, write_ros1, write_ros2_sqlite  # noqa: E402
from conftest import BUNDLED, run_cli  # noqa: E402

GT = BUNDLED / "livingRoom2.gt.freiburg"
#: Frame 0 has no ground truth: the runs start at 1, as the folder's does.
FRAMES = "1..2"


@pytest.fixture(scope="module")
def bags(tmp_path_factory):
    d = tmp_path_factory.mktemp("bags")
    frames = bundled_frames(BUNDLED, 3)
    write_ros1(d / "frames.bag", frames)
    write_ros2_sqlite(d / "ros2", frames)
    return d


def trajectory(out):
    return (out / "trajectory.tum").read_bytes()


@pytest.mark.parametrize("name", ["frames.bag", "ros2"])
def test_a_bag_runs_to_the_folders_trajectory(bags, tmp_path, name):
    # 16UC1 is millimetres unless told: the bundled frames are at 5000 units a metre.
    bag = run_cli("run", bags / name, "--frames", FRAMES, "--backend", "cpu", "--gt", GT,
                  "--depth-scale", "5000", "--out", tmp_path / "bag")
    assert bag.returncode == 0, bag.stderr
    assert "/camera/depth/image" in bag.stderr and "/camera/rgb/image_color" in bag.stderr
    folder = run_cli("run", BUNDLED, "--frames", FRAMES, "--backend", "cpu",
                     "--out", tmp_path / "folder")
    assert folder.returncode == 0, folder.stderr
    assert trajectory(tmp_path / "bag") == trajectory(tmp_path / "folder")


def test_python_run_reads_a_bag(bags):
    params = {"depth-scale": 5000.0, "gt": str(GT)}
    result = wgslam.run(bags / "frames.bag", backend="cpu", params=params)
    assert len(result.stamps) == 2


def test_a_bag_cut_short_is_refused(bags, tmp_path):
    data = (bags / "frames.bag").read_bytes()
    cut = tmp_path / "cut.bag"
    cut.write_bytes(data[: len(data) // 2])
    done = run_cli("run", cut, "--backend", "cpu", "--out", tmp_path / "o")
    assert done.returncode != 0
    assert "cut.bag" in done.stderr and "rosbag reindex" in done.stderr
