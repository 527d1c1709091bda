"""``python -m panomap`` and the ``panomap`` command: the command line."""

import os
import sys


def main() -> None:
    """Run the command line (:mod:`panomap.cli.app`)."""
    # Before NumPy loads: the commands do only small linear algebra, and OpenBLAS's idle
    # threads spin at start-up (CPU time taken from the video decoder's threads).
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    # And no transparent huge pages for NumPy's large arrays: where the kernel compacts memory for them on the
    # first touch (defrag "madvise", a common default), a fresh process stalls there. A 4K dual fisheye's video
    # (100 frames, 2 cores, load 3-10): 0.3-0.6 s less system CPU a run; its set-up's system time 0.23-0.29 s
    # steady, where it swung 0.12-1.02 s with them.
    os.environ.setdefault("NUMPY_MADVISE_HUGEPAGE", "0")
    from panomap.batch.forkserver import start_for_command

    # A batch's workers come from a fork server: its imports overlap the command line's own.
    start_for_command(sys.argv[1:])
    from panomap.cli.app import main as run_cli

    run_cli()


if __name__ == "__main__":
    main()
