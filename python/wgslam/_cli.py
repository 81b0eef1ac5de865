"""The ``wgslam`` command of the wheel: the native command line, run in this process.

The extension's ``main`` is the executable's own entry point (``wgslam::cli::embed::main``):
the same parser, commands, messages and exit statuses as the ``wgslam`` binary.
"""

import signal
import sys

from . import _native


def main() -> None:
    """Runs ``wgslam`` with ``sys.argv`` and exits with its status."""
    # Python's own SIGINT handler only sets a flag that no Python code would check while the
    # command runs: restore the default, so Ctrl-C stops the command as it stops the binary
    # (`wgslam batch` installs its own handler, as it does there).
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    sys.exit(_native.main(sys.argv))


if __name__ == "__main__":
    main()
