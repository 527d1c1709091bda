"""Lenses a little apart in a near room: the learned turn's error against what `rig learn` states (issue 52, 4a).

Run: ``PYTHONPATH=src .venv/bin/python bench/bench_rig_parallax.py [--quick]``

The demo's dual fisheye (two 210 deg equidistant lenses back to back, 640 x 640 px each, its camchain's ``t`` 0)
renders the bundled room (walls 1-3 m away) in closed form (:mod:`panomap.simulate.lens_scenes`, not the code
under test), camera 1 ``BASE`` behind camera 0 along their axes and turned about 1 deg off the camchain, at
several places and headings in the room. For each: the least squares' error and its stated 1-sigma (the features'
fit, :func:`panomap.rig.learn._refine` and ``_uncertainty``, as before parallax was accounted for), and the answer's
error, its stated 1-sigma and its bound (:class:`panomap.rig.parallax.ParallaxFit`), and whether the tilt was
pinned. Then, per baseline: how often each statement held the error (coverage) and the worst cases.
"""

from __future__ import annotations

import argparse
import math
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

import panomap.rig.learn as learn
from panomap.camera.orientation import rotation_from_vector
from panomap.cli.demo_inputs import BACK, LENS, camchain_text
from panomap.interop.rig_of_camchain import rig_of_camchain
from panomap.simulate import load_room
from panomap.simulate.lens_scenes import camera_axes, render_lens

# Places (m) and headings (deg) in the room: off its centre, whose floor looks the same half a turn about it.
PLACES = [
    ((2.7, 2.15, 1.5), 0.0),
    ((1.5, 1.5, 1.2), 30.0),
    ((4.2, 3.3, 1.6), -60.0),
    ((3.4, 1.2, 1.0), 90.0),
    ((2.0, 3.6, 1.4), 150.0),
    ((1.2, 3.8, 1.7), -20.0),
    ((4.8, 1.3, 1.3), 120.0),
    ((3.6, 3.9, 1.1), 200.0),
    ((2.3, 1.0, 1.6), 60.0),
    ((4.5, 2.6, 1.5), -100.0),
]
# Camera 1's turn off the camchain (rotation vectors, deg), taken in turn.
OFFS = [(0.5, -0.6, 0.4), (-0.8, 0.3, 0.5), (0.2, 0.9, -0.6)]
BASES_M = (0.0, 0.005, 0.01, 0.02)


def angle_deg(rotation: Any) -> float:
    return math.degrees(math.acos(min(1.0, (float(np.trace(rotation)) - 1) / 2)))


def trial(path: Path, at: tuple[float, float, float], yaw: float, base: float, off_deg: Any) -> tuple[float, ...]:
    """(least squares' error, its 1-sigma, the answer's error, its 1-sigma, its bound, pinned), deg."""
    room = load_room()
    axes = camera_axes(yaw, 0.0, 0.0)
    off = rotation_from_vector(np.radians(off_deg))
    centre = np.asarray(at)
    frame = np.concatenate(
        [
            render_lens(room, LENS, centre, axes),
            render_lens(room, LENS, centre - base * axes[:, 2], off @ axes @ BACK.T),
        ],
        axis=1,
    )
    rig = rig_of_camchain(
        path, side_by_side=True, fov_rad=2 * LENS.half_fov_rad, orientation_rad=(math.radians(yaw), 0, 0)
    )
    seen: dict[str, Any] = {}
    settle = learn._settle_parallax

    def spy(rig_: Any, m: Any, rotations: Any) -> Any:
        seen["ls"] = rotations[1].copy()
        seen["sigma"] = learn._uncertainty(2, [m], [rotations[0], rotations[1].copy()])[1]
        return settle(rig_, m, rotations)

    learn._settle_parallax = spy  # type: ignore[assignment]
    try:
        learned = learn.learn_rotations(rig, frame)
    finally:
        learn._settle_parallax = settle  # type: ignore[assignment]
    truth = off @ learn.rotation_of(rig.tables[1])
    fit = learned.parallax
    assert fit is not None
    return (
        angle_deg(seen["ls"] @ truth.T),
        seen["sigma"],
        angle_deg(learned.rotations[1] @ truth.T),
        learned.uncertainty_deg[1],
        fit.bound_deg,
        float(fit.pinned),
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="three places, baselines 0 and 2 cm")
    args = parser.parse_args()
    places = PLACES[:3] if args.quick else PLACES
    bases = (0.0, 0.02) if args.quick else BASES_M
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "dual.yaml"
        path.write_text(camchain_text(LENS))
        for k, (at, yaw) in enumerate(places):
            for base in bases:
                row = trial(path, at, yaw, base, OFFS[k % len(OFFS)])
                rows.append((base, *row))
                print(
                    f"at {at} heading {yaw:+5.0f} deg, lenses {base * 1000:2.0f} mm apart: least squares {row[0]:.3f} "
                    f"deg off (stated {row[1]:.3f}); now {row[2]:.3f} off, stated {row[3]:.3f} (1 sigma), bound "
                    f"{row[4]:.3f}, {'pinned' if row[5] else 'not pinned'}",
                    flush=True,
                )
    table = np.array(rows)
    print(
        "baseline | trials | least squares: error p50 / max, covered by its 1-sigma | now: error p50 / max, "
        "covered by 1-sigma / by bound, bound p50 / max, pinned"
    )
    for base in bases:
        x = table[table[:, 0] == base]
        print(
            f"{base * 1000:2.0f} mm | {len(x)} | {np.median(x[:, 1]):.3f} / {x[:, 1].max():.3f}, "
            f"{np.mean(x[:, 1] <= x[:, 2]):.0%} | {np.median(x[:, 3]):.3f} / {x[:, 3].max():.3f}, "
            f"{np.mean(x[:, 3] <= x[:, 4]):.0%} / {np.mean(x[:, 3] <= x[:, 5]):.0%}, "
            f"{np.median(x[:, 5]):.3f} / {x[:, 5].max():.3f}, {int(x[:, 6].sum())}"
        )


if __name__ == "__main__":
    main()
