"""find_boards on rendered scenes against their truth: boards found, corners on the truth, rows past a board's edge,
false boards (issue 54: the detector's row of a board's outer squares' vertices, a checkered floor read as boards).

Run: ``.venv/bin/python bench/bench_board_rows.py [--seeds 8] [--first 60]``

Scenes (:mod:`panomap.simulate.board_scenes`): three cameras (an 800 x 800 equidistant fisheye, outer radius 400;
the 190-degree fisheye and the hyperbolic mirror of ``line_camera`` at two thirds of their size), each seed one 9 x 6
board and two boards of mixed sizes (squares 12 px or more; a seed with no such pose left out), in the dark room and
in the room with its lines and checkered floor. Each found corner is matched to the nearest true inner corner of any
board (``camera.project`` of its 3-D point); a board whose median corner is over ``FALSE_PX`` from every true corner
is a false board; a true board's corners over 1 px off are an extra row's. Printed: per camera and room the counts,
then every fault.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from panomap.calibrate.boards.detect import find_boards
from panomap.errors import PanomapError
from panomap.simulate.board_scenes import board_poses, render_board_scene
from panomap.simulate.cameras import standard_cameras
from panomap.simulate.line_scenes import line_camera

FALSE_PX = 3.0
SIZES = ((9, 6), (8, 5), (7, 6), (10, 7))


def cameras():  # type: ignore[no-untyped-def]
    return {
        "equidistant 800": standard_cameras((800, 800), outer_radius=400)["equidistant"],
        "fisheye190": line_camera("fisheye190", 2.0 / 3.0),
        "hyperbolic": line_camera("hyperbolic", 0.64),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=8, help="poses per camera and count of boards (default 8)")
    parser.add_argument("--first", type=int, default=60, help="the first seed (default 60)")
    args = parser.parse_args()
    faults: list[str] = []
    for name, camera in cameras().items():
        for background in ("dark", "lines"):
            true_boards = found = false = rows = corners = within = 0
            worst, seconds = 0.0, 0.0
            for seed in range(args.first, args.first + args.seeds):
                for count in (1, 2):
                    try:
                        boards = board_poses(
                            camera, count, seed, sizes=SIZES[:1] if count == 1 else SIZES, min_square_px=12
                        )
                    except PanomapError:  # no pose of the boards' sizes fits the camera's view: a scene less
                        continue
                    scene = render_board_scene(camera, boards, seed, supersample=2, background=background)
                    truth = np.concatenate([t.pixels for t in scene.truth])
                    true_boards += count
                    start = time.perf_counter()
                    result = find_boards(scene.image)
                    seconds += time.perf_counter() - start
                    for board in result:
                        distance = np.linalg.norm(board.pixels[:, None, :] - truth[None, :, :], axis=2)
                        error = np.nan_to_num(distance, nan=np.inf).min(axis=1)
                        where = (
                            f"{name}, {background}, seed {seed}, {count} board(s): {board.shape[0]} x {board.shape[1]}"
                        )
                        if np.median(error) > FALSE_PX:
                            false += 1
                            faults.append(f"{where}, a false board")
                            continue
                        found += 1
                        corners += len(error)
                        within += int((error < 1.0).sum())
                        worst = max(worst, float(error.max()))
                        if error.max() > 1.0:
                            rows += 1
                            faults.append(f"{where}, {int((error > 1.0).sum())} corners up to {error.max():.1f} px off")
            print(
                f"{name}, {background} room: {found} of {true_boards} boards found, {false} false boards, {rows} with "
                f"corners over 1 px off; corners within 1 px {within} of {corners}, worst {worst:.2f} px; "
                f"find_boards {seconds:.1f} s"
            )
    for fault in faults:
        print("  " + fault)


if __name__ == "__main__":
    main()
