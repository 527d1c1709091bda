"""``python -m panomap`` and the ``panomap`` command: the command line."""

import os


def main() -> None:
    """Run the command line (:mod:`panomap.cli.app`)."""
    # Before NumPy loads: the commands do only small linear algebra, and OpenBLAS's idle
    # threads spin at start-up (CPU time taken from the video decoder's threads).
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    from panomap.cli.app import main as run_cli

    run_cli()


if __name__ == "__main__":
    main()
