"""``panomap batch`` given a rig (issue 52): each input one frame holding the rig's pictures (a dual fisheye's
side-by-side still or video), or a folder of one picture per camera; every output equals the view command's or
``panomap video``'s own output on that input, bit for bit (decoded frame for frame for lossless video).

The rigs and pictures are ``tests/test_rig_video.py``'s (ideal equidistant lenses in closed form, 960 x 960).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from panomap.batch.job import find_inputs
from panomap.errors import PanomapError
from test_rig_video import LOSSLESS_BGR, dual, frames_of, noisy, surround, write_video  # noqa: F401  (its fixtures)

from helpers import assert_one_line_error, run

EQUIRECT = "equirect:size=256x128"
SIDE_VIEW = "perspective:yaw=90,pitch=0,fov=100,size=160x120,name=side"  # (across the dual fisheye's seam)
COMMANDS = {
    "equirect": ["equirect", "--size", "256x128"],
    "side": ["perspective", "--yaw", "90", "--pitch", "0", "--fov", "100", "--size", "160x120"],
}
FLOOR = "floor:z=0,x=-3:5,y=-4:4,size=120x120"
FLOOR_COMMAND = ["floor", "--z", "0", "--x", "-3", "5", "--y", "-4", "4", "--size", "120x120"]


@pytest.mark.slow
def test_a_dual_fisheyes_frames_and_video_equal_the_view_commands_and_panomap_video(
    request: pytest.FixtureRequest, tmp_path: Path
) -> None:
    """Two side-by-side stills (a folder) and a lossless video of three frames, two views (one across the seam):
    each still output is the view command's picture of that frame bit for bit, each video's frames
    ``panomap video``'s of that view. A rig's video read cubic is refused in one line."""
    _, rig_path, frame = request.getfixturevalue("dual")
    (tmp_path / "frames").mkdir()
    stills = [tmp_path / "frames" / f"f{k}.png" for k in range(2)]
    cv2.imwrite(str(stills[0]), frame)
    cv2.imwrite(str(stills[1]), noisy(frame, 5, 0.9))
    write_video(tmp_path / "clip.mkv", [frame, np.roll(frame, 3, axis=0), frame])
    result = run("batch", tmp_path / "frames", tmp_path / "clip.mkv", "--table", rig_path, "-o",
                 tmp_path / "out" / "{stem}_{name}.mkv", "--view", EQUIRECT, "--view", SIDE_VIEW, *LOSSLESS_BGR,
                 "--record", tmp_path / "rec.jsonl", "--workers", "1", "-q")  # fmt: skip
    assert result.exit_code == 0, result.output + result.stderr
    for still in stills:
        for name, command in COMMANDS.items():
            alone = tmp_path / f"alone_{still.stem}_{name}.png"
            single = run(command[0], rig_path, still, "-o", alone, *command[1:])
            assert single.exit_code == 0, single.stderr
            assert (tmp_path / "out" / f"{still.stem}_{name}.png").read_bytes() == alone.read_bytes(), name
    for spec, name in ((EQUIRECT, "equirect"), (SIDE_VIEW, "side")):
        alone = tmp_path / f"alone_{name}.mkv"
        single = run("video", rig_path, tmp_path / "clip.mkv", "-o", alone, "--view", spec, *LOSSLESS_BGR, "-q")
        assert single.exit_code == 0, single.stderr
        made, expected = frames_of(tmp_path / "out" / f"clip_{name}.mkv"), frames_of(alone)
        assert len(made) == len(expected) == 3
        assert all(np.array_equal(a, b) for a, b in zip(made, expected, strict=True)), name
    cubic = run("batch", tmp_path / "clip.mkv", "--table", rig_path, "-o", tmp_path / "c.mkv", "--view", EQUIRECT,
                "--interp", "cubic")  # fmt: skip
    assert_one_line_error(cubic, "linear or nearest", exit_code=2)  # (before any work, as panomap video)


@pytest.mark.slow
def test_folders_of_one_picture_per_camera_equal_the_floor_command(
    request: pytest.FixtureRequest, tmp_path: Path
) -> None:
    """A surround rig's shots, one folder each: one named after the cameras (written in another order), one
    named otherwise (taken by name); each floor map is ``panomap floor`` of its four pictures bit for bit, named
    after its folder. A folder of three pictures is refused, naming it."""
    _, rig_path, pictures = request.getfixturevalue("surround")
    shots = {"s0": [f"cam{k}.png" for k in (2, 0, 3, 1)], "s1": ["a.png", "b.png", "c.png", "d.png"]}
    ordered = {}
    for shot, names in shots.items():
        (tmp_path / "shots" / shot).mkdir(parents=True)
        order = sorted(names) if shot == "s1" else [f"cam{k}.png" for k in range(4)]
        for k, name in enumerate(order):
            cv2.imwrite(str(tmp_path / "shots" / shot / name), pictures[k] if shot == "s0" else pictures[k][::-1])
        ordered[shot] = [tmp_path / "shots" / shot / name for name in order]
    result = run("batch", tmp_path / "shots", "--table", rig_path, "-o", tmp_path / "out" / "{stem}_{name}.png",
                 "--view", FLOOR, "--record", tmp_path / "rec.jsonl", "--workers", "1", "-q")  # fmt: skip
    assert result.exit_code == 0, result.output + result.stderr
    for shot, files in ordered.items():
        alone = tmp_path / f"alone_{shot}.png"
        single = run(FLOOR_COMMAND[0], rig_path, *files, "-o", alone, *FLOOR_COMMAND[1:])
        assert single.exit_code == 0, single.stderr
        assert (tmp_path / "out" / f"{shot}_floor.png").read_bytes() == alone.read_bytes(), shot
    (tmp_path / "shots" / "s1" / "d.png").unlink()
    with pytest.raises(PanomapError, match=r"s1: a rig's folder holds one picture or video per camera .*not 3 files"):
        find_inputs([str(tmp_path / "shots")], rig_path)
