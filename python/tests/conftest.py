"""Shared fixtures of the Python package's tests: where the repository's frames are, and
the command line to compare with.

The command line is the native binary named by ``WGSLAM_BIN`` (``.ci/run`` sets it to the
one ``cargo test`` built), else the wheel's own ``wgslam`` command. The full data sets
(``../shared/data``) are optional here: a test that needs them is skipped with the reason,
and with ``WGSLAM_REQUIRE_DATA=1`` (``.ci/run``) fails instead.
"""

import os
import shutil
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
BUNDLED = REPO / "assets" / "icl_living_room_kt2"
SHARED_DATA = REPO.parent / "shared" / "data"


def command_line() -> str:
    """The ``wgslam`` command line to compare with (see the module's header)."""
    exe = os.environ.get("WGSLAM_BIN") or shutil.which("wgslam")
    if not exe:
        pytest.fail("no wgslam command: set WGSLAM_BIN or install the wheel")
    return exe


def run_cli(*args: str) -> subprocess.CompletedProcess:
    """Runs the command line with ``args``; its output is captured as text."""
    return subprocess.run(
        [command_line(), *map(str, args)], capture_output=True, text=True, check=False
    )


@pytest.fixture
def shared_data() -> Path:
    """``../shared/data``, or a skip with the reason (a failure under WGSLAM_REQUIRE_DATA=1)."""
    if not SHARED_DATA.is_dir():
        why = f"{SHARED_DATA} is not here (the full data sets)"
        if os.environ.get("WGSLAM_REQUIRE_DATA") == "1":
            pytest.fail(why + " and WGSLAM_REQUIRE_DATA=1")
        pytest.skip(why)
    return SHARED_DATA
