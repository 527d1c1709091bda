"""``python -m panomap`` and the ``panomap`` command: the command line."""

import os
import sys


def main() -> None:
    """Run the command line (:mod:`panomap.cli.app`)."""
    # Before NumPy loads: the commands do only small linear algebra, and OpenBLAS's idle
    # threads spin at start-up (CPU time taken from the video decoder's threads).
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    from panomap.batch.forkserver import start_for_command

    # A batch's workers come from a fork server: its imports overlap the command line's own.
    start_for_command(sys.argv[1:])
    from panomap.cli.app import main as run_cli

    run_cli()


if __name__ == "__main__":
    main()
