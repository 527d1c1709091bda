"""The memory a still view of each kind takes, against the figure its kind declares (``View.bytes_per_pixel``).

Run: ``.venv/bin/python bench/bench_view_memory.py [--quick]``

Writes the demo into a temporary folder, then renders each view kind of its table from its picture at two
sizes (1000 x 500 and 8000 x 4000 px; ``--quick``: 500 x 250 and 4000 x 2000), each in a fresh process
(``panomap KIND ... -q``) that reports its peak RSS. The slope between the two sizes is the view's own memory
per output pixel (the interpreter, the table and the picture cancel out); it is printed beside the declared
figure, whose ratio to it must be at least 1 (the check before the work refuses on the declared figure: it
errs high). Measured on a loaded 2-core machine (RSS does not depend on the load).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

from panomap.views import view_kinds

# Each kind's options beside its size (the demo's room: camera 2.45 m up).
OPTIONS = {
    "panorama": [],
    "cylinder": ["--distance", "2", "--band", "-2.45", "0.15"],
    "plane": ["--distance", "1.8", "--width", "2.4", "--band", "-2.45", "0.15", "--azimuth", "90"],
    "perspective": ["--yaw", "30", "--pitch", "-30", "--fov", "100"],
    "floor": ["--z", "0", "--x", "0", "6", "--y", "0", "5"],
    "equirect": [],
}
PEAK = (
    "import resource, runpy, sys\n"
    "sys.argv = ['panomap', *sys.argv[1:]]\n"
    "try:\n    runpy.run_module('panomap', run_name='__main__')\n"
    "except SystemExit as exc:\n    assert not exc.code, exc.code\n"
    "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024, file=sys.stderr)\n"
)


def peak_bytes(args: list[str]) -> int:
    """The peak RSS (bytes) of ``panomap ARGS`` run in a fresh process."""
    done = subprocess.run([sys.executable, "-c", PEAK, *args], capture_output=True, text=True, check=True)
    return int(done.stderr.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="smaller views (500 x 250 and 4000 x 2000 px)")
    sizes = ((500, 250), (4000, 2000)) if parser.parse_args().quick else ((1000, 500), (8000, 4000))
    with tempfile.TemporaryDirectory() as folder:
        demo = Path(folder) / "demo"
        subprocess.run([sys.executable, "-m", "panomap", "demo", "-o", str(demo), "-q"], check=True)
        print(f"{'view':<12} {'measured B/px':>14} {'declared':>9} {'declared / measured':>20}")
        worst = float("inf")
        for kind, options in OPTIONS.items():
            inputs = [str(demo / "table.npz"), str(demo / "omni.png"), "-o", str(Path(folder) / "v.png")]
            peaks = [peak_bytes([kind, *inputs, "--size", f"{w}x{h}", "-q", *options]) for w, h in sizes]
            measured = (peaks[1] - peaks[0]) / (sizes[1][0] * sizes[1][1] - sizes[0][0] * sizes[0][1])
            declared = view_kinds()[kind].bytes_per_pixel
            worst = min(worst, declared / measured)
            print(f"{kind:<12} {measured:>14.1f} {declared:>9} {declared / measured:>20.2f}")
        print(f"worst declared / measured: {worst:.2f} (at least 1: the check errs high)")


if __name__ == "__main__":
    main()
