"""The fork server that the local cluster's workers are forked from (light: no NumPy, no Dask).

It imports what every task needs (Dask, NumPy, OpenCV, PyAV, panomap) once; each worker is
forked from it, ready, instead of being a fresh interpreter that imports them again. The
``panomap batch`` command starts it before it imports its own modules, so that the server's
imports (about 1.5 CPU-s) run on another core beside the command's (about 0.8 s) rather than
after them; :func:`panomap.batch.run.run_job` starts it otherwise.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

# The modules the fork server imports before it forks any worker.
PRELOAD = ["distributed", "panomap.batch.tasks"]
SCHEDULER_VARIABLE = "DASK_SCHEDULER_ADDRESS"


def can_fork_serve() -> bool:
    """The system has fork servers (not Windows): elsewhere each worker starts as a fresh interpreter."""
    import multiprocessing  # here, not at the top: every command imports this module, a batch alone needs it

    return "forkserver" in multiprocessing.get_all_start_methods()


def start_fork_server() -> None:
    """Start the fork server (where it already runs, as for a second job in one process, it keeps what it
    preloaded)."""
    if not can_fork_serve():
        return
    import multiprocessing.forkserver

    multiprocessing.get_context("forkserver").set_forkserver_preload(PRELOAD)
    multiprocessing.forkserver.ensure_running()


def start_for_command(argv: Sequence[str]) -> None:
    """Start the fork server now when ``argv`` (the command line's arguments) runs a batch on a local cluster.

    Not for another command, for help, or with a scheduler to use (``--scheduler`` or
    ``DASK_SCHEDULER_ADDRESS``): there the workers are not ours.
    """
    arguments = list(argv)
    if not arguments or arguments[0] != "batch" or os.environ.get(SCHEDULER_VARIABLE):
        return
    if any(arg in ("-h", "--help") or arg == "--scheduler" or arg.startswith("--scheduler=") for arg in arguments):
        return
    start_fork_server()
