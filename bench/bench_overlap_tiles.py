"""How far apart a dual fisheye's two lenses draw their overlap (issue 52): the tiles of
:func:`panomap.rig.overlap.overlap_tiles` with the TRUE lenses, and with lens 1 wrong by a little.

Run: ``PYTHONPATH=src .venv/bin/python bench/bench_overlap_tiles.py [--photograph]``

The frames are ``bench_dual_learn``'s: two equidistant 190 deg lenses back to back but for a small turn,
rendered in closed form (3 x 3 samples a pixel), six frames of its room turned and pitched, and with
``--photograph`` three of a real 360 photograph (``../shared/data/panoramas``, skipped where absent). The rig is
built from the true lenses (a Kalibr camchain, equidistant, exactly back to back), lens 1's focal length scaled
or its centre moved; its turn is learned from the features (:func:`panomap.rig.learn.learn_rotations`, as
``rig learn --side-by-side`` does), then the overlap's 16 px tiles are measured three ways: phase correlation,
cross-correlation on every textured tile, and cross-correlation on the tiles textured both ways
(:data:`panomap.rig.overlap.MIN_CORNERNESS`, what ``rig learn`` uses). Printed per case: the tiles kept and
their shifts' p50 / p90 / max (px). Where the lenses are true, the spread is the measure's own; where one is
wrong, how much of it the measure shows (the side-by-side check refuses above the two lenses' bands plus 0.5 px).
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_dual_learn as dual
from panomap.interop.orient import turn_table
from panomap.interop.rig_of_camchain import rig_of_camchain
from panomap.rig import overlap
from panomap.rig.learn import learn_rotations

WRONG = (("true lenses", 1.0, (0.0, 0.0)), ("lens 1 scaled 1.005", 1.005, (0.0, 0.0)),
         ("lens 1 scaled 1.01", 1.01, (0.0, 0.0)), ("lens 1 scaled 1.02", 1.02, (0.0, 0.0)),
         ("lens 1 centre 4 px off", 1.0, (4.0, 0.0)), ("lens 1 centre 8 px off", 1.0, (8.0, 0.0)))  # fmt: skip


def camchain(path: Path, lenses: tuple[dual.Lens, dual.Lens], scale: float, shift: tuple[float, float]) -> Path:
    """The two lenses as a Kalibr camchain (lens 1 exactly back to back), lens 1's focal length times ``scale``
    and its centre moved by ``shift`` (px)."""
    lines = []
    for k, lens in enumerate(lenses):
        f = lens.f * (scale if k else 1.0)
        cx, cy = lens.cx + (shift[0] if k else 0.0), lens.cy + (shift[1] if k else 0.0)
        lines += [f"cam{k}:", "  camera_model: pinhole", f"  intrinsics: [{f}, {f}, {cx}, {cy}]",
                  "  distortion_model: equidistant", "  distortion_coeffs: [0.0, 0.0, 0.0, 0.0]",
                  f"  resolution: [{dual.SIDE}, {dual.SIDE}]"]  # fmt: skip
        if k:
            lines += ["  T_cn_cnm1:", "  - [-1, 0, 0, 0]", "  - [0, 1, 0, 0]", "  - [0, 0, -1, 0]", "  - [0, 0, 0, 1]"]
    path.write_text("\n".join(lines) + "\n")
    return path


def spread(tiles: overlap.OverlapTiles) -> str:
    """The tiles' count and their shifts' p50 / p90 / max (px)."""
    d = tiles.distances_px()
    if not d.size:
        return "no tiles"
    return f"{d.size:4d} tiles {np.percentile(d, 50):.2f} / {np.percentile(d, 90):.2f} / {d.max():.2f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--photograph", action="store_true", help="also three frames of the real photograph")
    args = parser.parse_args()
    cases = [dual.CASES[7]]
    if args.photograph:
        if Path(dual.CASES[11].scene).exists():
            cases.append(dual.CASES[11])
        else:
            print(f"photograph: skipped ({dual.CASES[11].scene} absent)")
    for case in cases:
        start = time.perf_counter()
        frames = [dual.render_frame(*dual.case_truth(case, pose), case.scene) for pose in case.poses_deg]
        lenses, _ = dual.case_truth(case, case.poses_deg[0])
        print(f"## {case.name} ({len(frames)} frames, rendered in {time.perf_counter() - start:.0f} s)")
        print("  (tiles kept, shifts p50 / p90 / max px) phase correlation | cross-correlation, every tile | "
              "cross-correlation, tiles textured both ways")  # fmt: skip
        with tempfile.TemporaryDirectory() as folder:
            for name, scale, shift in WRONG:
                chain = camchain(Path(folder) / "dual.yaml", lenses, scale, shift)
                rig = rig_of_camchain(chain, side_by_side=True, fov_rad=math.radians(dual.FOV_DEG))
                learned = learn_rotations(rig, list(frames), turn=turn_table, seed=0)
                measured = [spread(overlap.overlap_tiles(learned.rig, list(frames), tile_px=16, min_std=6.0))]
                for least in (0.0, overlap.MIN_CORNERNESS):
                    kept = overlap.MIN_CORNERNESS
                    overlap.MIN_CORNERNESS = least
                    try:
                        tiles = overlap.overlap_tiles(learned.rig, list(frames), tile_px=16, min_std=6.0,
                                                      search_px=overlap.SEARCH_PX)  # fmt: skip
                    finally:
                        overlap.MIN_CORNERNESS = kept
                    measured.append(spread(tiles))
                print(f"  {name:24s} " + " | ".join(measured), flush=True)


if __name__ == "__main__":
    main()
