"""What killed or failed runs of a job leave beside its outputs, removed by the next run.

A run killed outright (SIGKILL, a power cut) leaves each output it was writing as a temporary
(``.NAME.PID-XXXX.partSUFFIX``, :mod:`panomap.files`) and a segmented video's parts in
``.panomap-parts/KEY/``. The workers of a killed local cluster can outlive it for a while and
finish outputs that the next run then finds complete and skips, so their temporaries were never
written again, and never removed. A run sweeps the job's own outputs' folders when it starts and
when it ends: a temporary of one of the job's outputs whose process is gone, and the parts folder
of an input that is complete (or empty), go. A temporary whose process is alive, another live
run's, is never touched, nor is anything that is not the job's own.
"""

from __future__ import annotations

import contextlib
import shutil
from collections.abc import Callable
from pathlib import Path

from ..files import remove_stale_temporaries, temporaries_alive
from .job import Item, Job
from .tasks import parts_folder


def tidy(job: Job, complete: Callable[[Item], bool]) -> list[Path]:
    """Remove the leftovers of earlier runs of ``job`` (``complete(item)``: the record holds the item as
    done); returns what was removed (temporaries and parts folders)."""
    removed: list[Path] = []
    for item in job.items:
        for output in item.outputs:
            removed += remove_stale_temporaries(output.path)
        if not item.input.is_video:
            continue
        folder = parts_folder(item)
        if not folder.is_dir():
            continue
        for part in folder.iterdir():
            if not part.name.startswith("."):
                removed += remove_stale_temporaries(part)
        if temporaries_alive(folder):
            continue  # (a live run writes its parts)
        if complete(item) or not any(folder.iterdir()):
            shutil.rmtree(folder, ignore_errors=True)
            removed.append(folder)
        with contextlib.suppress(OSError):
            folder.parent.rmdir()  # (only where no other video's parts wait there)
    return removed
