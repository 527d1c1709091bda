"""Nothing lost, memory bounded, exit codes honest: every output all or none, inputs never
overwritten, faults (a full disk, a failing close, a signal) reported with the user's path,
tables checked as a whole, and sizes checked before the memory is taken.

Faults are injected through two seams: ``panomap.files._open_temporary`` (every output's
temporary file) and ``av.open`` for the video containers.
"""

from __future__ import annotations

import errno
import json
import os
import pty
import stat
import struct
import subprocess
import sys
import threading
import tracemalloc
import zipfile
import zlib
from pathlib import Path
from typing import Any

import av
import cv2
import numpy as np
import pytest

import panomap.files
from panomap.cli.video import summary
from panomap.errors import PanomapError
from panomap.io.images import read_image
from panomap.simulate import standard_cameras
from panomap.table.file import load_table, metadata_digest
from panomap.video.unwarp import ViewOutput, unwarp_video
from panomap.views import GenericPanorama

from helpers import assert_one_line_error, run, write_cli_inputs

SIZE = (320, 300)
CAMERA = standard_cameras(SIZE, centre=(160.4, 149.7), s=1, phi0=0.3)["parabolic"]
POSITION = (3.0, 2.0, 2.5)
PANORAMA = ("--size", "256x64")


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder with a fitted table (cam.npz), an omni-image (omni.png) and a 6-frame clip of it."""
    folder = tmp_path_factory.mktemp("reliability")
    write_cli_inputs(folder, CAMERA, POSITION)
    fitted = run("fit", folder / "lm.csv", "-o", folder / "cam.npz", "--camera", *POSITION, "--centre", *CAMERA.centre,
                 "--image-size", f"{SIZE[0]}x{SIZE[1]}", "--cutoff-radius", CAMERA.cutoff_radius, "--outer-radius",
                 CAMERA.outer_radius)  # fmt: skip
    assert fitted.exit_code == 0, fitted.output + fitted.stderr
    omni = cv2.imread(str(folder / "omni.png"))
    with av.open(str(folder / "clip.mp4"), "w") as container:
        stream = container.add_stream("libx264", rate=25)
        stream.width, stream.height, stream.pix_fmt = SIZE[0], SIZE[1], "yuv420p"
        for index in range(6):
            frame = av.VideoFrame.from_ndarray(np.roll(omni, index, axis=1), format="bgr24")
            frame.pts = index
            container.mux(stream.encode(frame))
        container.mux(stream.encode(None))
    return folder


def files_in(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def panorama(work: Path, *args: object) -> Any:
    return run("panorama", work / "cam.npz", work / "omni.png", *PANORAMA, *args)


# ----------------------------------------------------------------------------- inputs never overwritten


@pytest.mark.parametrize("link", ["same", "symlink", "hardlink", "spelling"])
def test_an_output_that_is_the_input_image_is_refused(work: Path, tmp_path: Path, link: str) -> None:
    image = tmp_path / "a.png"
    image.write_bytes((work / "omni.png").read_bytes())
    output = {"same": image, "symlink": tmp_path / "s.png", "hardlink": tmp_path / "h.png"}.get(
        link, tmp_path / "." / "sub" / ".." / "a.png"
    )
    (tmp_path / "sub").mkdir()
    if link == "symlink":
        output.symlink_to(image)
    elif link == "hardlink":
        os.link(image, output)
    before = image.read_bytes()
    result = run("panorama", work / "cam.npz", image, "-o", output, *PANORAMA)
    assert_one_line_error(result, "is the input image", "refusing to overwrite an input", exit_code=1)
    assert image.read_bytes() == before


def test_video_output_that_is_its_input_or_its_table_is_refused(work: Path, tmp_path: Path) -> None:
    clip = tmp_path / "v.mp4"
    clip.write_bytes((work / "clip.mp4").read_bytes())
    before = clip.read_bytes()
    result = run("video", work / "cam.npz", clip, "-o", clip, "--view", "panorama:size=128x32", "-q")
    assert_one_line_error(result, "v.mp4", "is the input", exit_code=1)
    assert clip.read_bytes() == before
    table = tmp_path / "cam.mp4"  # a table file may have any name
    table.write_bytes((work / "cam.npz").read_bytes())
    result = run("video", table, work / "clip.mp4", "-o", table, "--view", "panorama:size=128x32", "-q")
    assert_one_line_error(result, "is the table", exit_code=1)


@pytest.mark.parametrize("spelling", ["file://{abs}", "file:{abs}", "file://localhost{abs}", "file:{rel}"])
def test_a_video_input_given_as_a_file_url_is_never_overwritten(
    work: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, spelling: str
) -> None:
    # FFmpeg opens a file: URL as the file it names; the guard compared the URL's text with the output's
    # path, and `video T file:///abs/in.mp4 -o in.mp4` replaced its input (exit 0).
    clip = tmp_path / "in.mp4"
    clip.write_bytes((work / "clip.mp4").read_bytes())
    before = clip.read_bytes()
    monkeypatch.chdir(tmp_path)
    source = spelling.format(abs=clip.as_posix(), rel="in.mp4")
    result = run("video", work / "cam.npz", source, "-o", "in.mp4", "--view", "panorama:size=128x32", "-q")
    assert_one_line_error(result, "in.mp4", "is the input", exit_code=1)
    assert clip.read_bytes() == before
    assert files_in(tmp_path) == ["in.mp4"]


@pytest.mark.parametrize(
    ("command", "inputs", "output"),
    [("fit", ["lm.csv"], "lm.csv"), ("project", ["cam.npz", "lm.csv"], "lm.csv"), ("centre", ["omni.png"], None)],
)
def test_every_command_refuses_to_overwrite_its_inputs(
    work: Path, tmp_path: Path, command: str, inputs: list[str], output: str | None
) -> None:
    for name in {*inputs, "omni.png"}:
        (tmp_path / name).write_bytes((work / name).read_bytes())
    before = {name: (tmp_path / name).read_bytes() for name in inputs}
    where = ["-o", tmp_path / output] if output else ["--overlay", tmp_path / "omni.png"]
    extra = ["--camera", *POSITION, "--centre", *CAMERA.centre] if command == "fit" else []
    result = run(command, *(tmp_path / name for name in inputs), *where, *extra)
    assert_one_line_error(result, "refusing to overwrite an input", exit_code=1)
    assert {name: (tmp_path / name).read_bytes() for name in inputs} == before


def test_save_map_needs_npy_and_outputs_of_a_run_may_not_collide(work: Path, tmp_path: Path) -> None:
    result = panorama(work, "-o", tmp_path / "p.png", "--save-map", tmp_path / "map.png")
    assert_one_line_error(result, "--save-map", "not a .npy file name", exit_code=2)
    result = panorama(work, "-o", tmp_path / "m_x.pgm", "--save-map-pgm", tmp_path / "m")
    assert_one_line_error(result, "m_x.pgm", "are the same file", exit_code=1)
    assert files_in(tmp_path) == []


def test_save_map_pgm_into_a_folder_quiet_still_views_and_unknown_placeholders(work: Path, tmp_path: Path) -> None:
    # `--save-map-pgm a/` wrote ./a_x.pgm beside the working folder; now the folder's map_x.pgm, map_y.pgm.
    (tmp_path / "maps").mkdir()
    result = panorama(work, "-o", tmp_path / "p.png", "--save-map-pgm", f"{tmp_path / 'maps'}/", "-q")
    assert result.exit_code == 0, result.output + result.stderr
    assert result.output == ""  # -q: nothing but errors and warnings
    assert files_in(tmp_path / "maps") == ["map_x.pgm", "map_y.pgm"]
    assert not any(tmp_path.glob("maps_*.pgm")) and not any(Path.cwd().glob("*_x.pgm"))
    loud = panorama(work, "-o", tmp_path / "p.png")
    assert loud.output.startswith(f"wrote {tmp_path / 'p.png'} (")
    # An unknown {placeholder} in video's -o was taken literally: one file 'out_{view}.mp4' for every view.
    result = run("video", work / "cam.npz", work / "clip.mp4", "-o", tmp_path / "out_{view}.mp4", "--view",
                 "panorama:size=128x32", "-q")  # fmt: skip
    assert_one_line_error(result, "unknown placeholder {view}", "the only one is {name}", exit_code=2)
    assert not any(tmp_path.glob("out_*"))


def _long_clip(work: Path, path: Path, frames: int, options: dict[str, str] | None = None) -> None:
    omni = cv2.imread(str(work / "omni.png"))
    with av.open(str(path), "w", options=options or {}) as container:
        stream = container.add_stream("libx264", rate=25)
        stream.width, stream.height, stream.pix_fmt = SIZE[0], SIZE[1], "yuv420p"
        stream.options = {"preset": "ultrafast"}
        for index in range(frames):
            frame = av.VideoFrame.from_ndarray(np.roll(omni, 3 * index, axis=1), format="bgr24")
            frame.pts = index
            container.mux(stream.encode(frame))
        container.mux(stream.encode(None))


@pytest.mark.parametrize(("name", "options"), [("cut.mkv", None), ("cut.mp4", {"movflags": "faststart"})])
def test_a_video_cut_short_says_so_in_one_line(work: Path, tmp_path: Path, name: str, options: Any) -> None:
    # A truncated file gave "unwarped N frames", exit 0, with no word that the input ended early.
    whole = tmp_path / f"whole{Path(name).suffix}"
    _long_clip(work, whole, 100, options)  # 4 s at 25 fps
    data = whole.read_bytes()
    (tmp_path / name).write_bytes(data[: int(len(data) * 0.6)])
    view = ("--view", "panorama:size=128x32")
    result = run("video", work / "cam.npz", tmp_path / name, "-o", tmp_path / "out.mp4", *view)
    assert result.exit_code == 0, result.output + result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and "the input ended early" in lines[0] and "its header says 4.00 s" in lines[0], lines
    assert name in lines[0]
    complete = run("video", work / "cam.npz", whole, "-o", tmp_path / "out.mp4", *view)
    assert complete.exit_code == 0 and complete.stderr == "", complete.stderr
    assert "unwarped 100 frames" in complete.output


def test_a_start_past_the_end_and_a_stop_before_the_first_frame_say_what_happened(work: Path, tmp_path: Path) -> None:
    # Both said "no frame could be decoded", blaming a good input.
    result = run("video", work / "cam.npz", work / "clip.mp4", "-o", tmp_path / "o.mp4", "--view",
                 "panorama:size=128x32", "--start", 10)  # fmt: skip
    assert_one_line_error(result, "--start 10 s is past the end of the input: the clip lasts 0.24 s", exit_code=1)
    stop = threading.Event()
    stop.set()  # (as the first SIGINT or SIGTERM sets it, here before a frame is read)
    report = unwarp_video(load_table(work / "cam.npz"), str(work / "clip.mp4"),
                          [ViewOutput(GenericPanorama(size=(128, 32)), tmp_path / "o.mp4")], stop=stop)  # fmt: skip
    assert report.interrupted and report.frames_written == 0 and report.outputs == []
    assert files_in(tmp_path) == []
    assert summary(report).startswith("stopped by a signal before the first frame")


# ----------------------------------------------------------------------------- all outputs or none


def test_a_run_writes_all_of_its_outputs_or_none(work: Path, tmp_path: Path) -> None:
    (tmp_path / "m_y.pgm").mkdir()  # the last output cannot be written
    result = panorama(
        work, "-o", tmp_path / "p.png", "--save-map", tmp_path / "map.npy", "--save-map-pgm", tmp_path / "m"
    )
    assert_one_line_error(result, "m_y.pgm", "folder", exit_code=1)
    assert ".part" not in result.stderr
    assert files_in(tmp_path) == ["m_y.pgm"]


class _FullDisk:
    """A temporary file whose writes fail as on a full disk, from the ``fail_from``-th one opened."""

    opened = 0

    def __init__(self, real: Any, fail: bool) -> None:
        self._real, self._fail = real, fail

    def write(self, data: Any) -> int:
        if self._fail:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return int(self._real.write(data))

    def __getattr__(self, name: str) -> Any:
        return getattr(self._real, name)

    def __enter__(self) -> _FullDisk:
        return self

    def __exit__(self, *exc: object) -> None:
        self._real.close()


def full_disk_from(monkeypatch: pytest.MonkeyPatch, fail_from: int) -> None:
    real_open = panomap.files._open_temporary
    count = [0]

    def opening(directory: Path, path: Path) -> Any:
        count[0] += 1
        return _FullDisk(real_open(directory, path), count[0] >= fail_from)

    monkeypatch.setattr(panomap.files, "_open_temporary", opening)


@pytest.mark.parametrize("fail_from", [1, 2])
def test_a_full_disk_names_the_file_and_leaves_no_output(
    work: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, fail_from: int
) -> None:
    full_disk_from(monkeypatch, fail_from)
    result = panorama(work, "-o", tmp_path / "p.png", "--save-map", tmp_path / "map.npy")
    failed = ["p.png", "map.npy"][fail_from - 1]
    assert_one_line_error(result, f"{failed}: cannot write it (No space left on device)", exit_code=1)
    assert files_in(tmp_path) == []


@pytest.mark.parametrize("fail_from", [1, 2])
def test_a_failed_write_leaves_the_existing_outputs_as_they_were(
    work: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, fail_from: int
) -> None:
    """Outputs that exist already keep their bytes and their mode when the disk fills up while
    writing the first of them or the second (all or none of a run's outputs are replaced)."""
    old = {"p.png": (b"the previous image", 0o640), "map.npy": (b"the previous map", 0o604)}
    for name, (content, mode) in old.items():
        (tmp_path / name).write_bytes(content)
        (tmp_path / name).chmod(mode)
    full_disk_from(monkeypatch, fail_from)
    result = panorama(work, "-o", tmp_path / "p.png", "--save-map", tmp_path / "map.npy")
    failed = ["p.png", "map.npy"][fail_from - 1]
    assert_one_line_error(result, f"{failed}: cannot write it (No space left on device)", exit_code=1)
    assert files_in(tmp_path) == sorted(old)
    for name, (content, mode) in old.items():
        assert (tmp_path / name).read_bytes() == content
        assert stat.S_IMODE((tmp_path / name).stat().st_mode) == mode


def test_fit_on_a_full_disk_names_the_table_and_writes_neither_output(
    work: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    full_disk_from(monkeypatch, 2)  # the table is written, the plot is not
    result = run("fit", work / "lm.csv", "-o", tmp_path / "t.npz", "--camera", *POSITION, "--centre", *CAMERA.centre,
                 "--plot", tmp_path / "fit.png")  # fmt: skip
    assert_one_line_error(result, "fit.png: cannot write it (No space left on device)", exit_code=1)
    assert files_in(tmp_path) == []


def test_a_read_only_output_is_refused_and_a_writable_one_keeps_its_mode(work: Path, tmp_path: Path) -> None:
    output = tmp_path / "p.png"
    output.write_bytes(b"old")
    output.chmod(0o444)
    assert_one_line_error(panorama(work, "-o", output), "p.png", "read-only", exit_code=1)
    assert output.read_bytes() == b"old" and stat.S_IMODE(output.stat().st_mode) == 0o444
    output.chmod(0o640)
    assert panorama(work, "-o", output).exit_code == 0
    assert output.read_bytes() != b"old" and stat.S_IMODE(output.stat().st_mode) == 0o640


def test_temporaries_of_a_killed_run_are_removed_by_the_next(work: Path, tmp_path: Path) -> None:
    gone = subprocess.Popen([sys.executable, "-c", ""])
    gone.wait()
    stale = tmp_path / f".p.png.{gone.pid}-k2j4h6g8.part.png"
    running = tmp_path / f".p.png.{os.getppid()}-a1b2c3d4.part.png"  # a live process's: left alone
    other = tmp_path / f".q.png.{gone.pid}-k2j4h6g8.part.png"  # another output's: left alone
    # Its PID now a process's that started after the file was last written (a reboot, PIDs that wrapped):
    # not the process that wrote it, which is gone. (It stayed for good.)
    reused = tmp_path / f".p.png.{os.getppid()}-r3u5s7e9.part.png"
    for path in (stale, running, other, reused):
        path.write_bytes(b"half")
    os.utime(reused, (946684800, 946684800))  # written in 2000
    assert panorama(work, "-o", tmp_path / "p.png").exit_code == 0
    assert files_in(tmp_path) == sorted([running.name, other.name, "p.png"])


# ----------------------------------------------------------------------------- video: close, signals, memory


def test_a_failing_close_fails_the_video_keeps_the_old_file_and_names_it(
    work: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A full disk shows when the container writes its index at close: the run must fail."""
    real_open = av.open

    class FailingClose:
        def __init__(self, container: Any) -> None:
            self._container = container

        def __getattr__(self, name: str) -> Any:
            return getattr(self._container, name)

        def close(self) -> None:
            self._container.close()
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    def opening(file: Any, mode: str = "r", **options: Any) -> Any:
        container = real_open(file, mode, **options)
        return FailingClose(container) if mode == "w" else container

    monkeypatch.setattr(av, "open", opening)
    (tmp_path / "pano.mp4").write_bytes(b"the previous good file")
    (tmp_path / "pano.mp4").chmod(0o640)
    result = run("video", work / "cam.npz", work / "clip.mp4", "-o", tmp_path / "pano.mp4",
                 "--view", "panorama:size=128x32", "-q")  # fmt: skip
    assert_one_line_error(result, "pano.mp4: writing failed (No space left on device)", exit_code=1)
    assert files_in(tmp_path) == ["pano.mp4"]
    assert (tmp_path / "pano.mp4").read_bytes() == b"the previous good file"
    assert stat.S_IMODE((tmp_path / "pano.mp4").stat().st_mode) == 0o640


def test_sighup_stops_a_video_cleanly_as_sigterm_does() -> None:
    """Closing the terminal sends SIGHUP: it must finish the outputs, not kill the run."""
    code = (
        "import os, signal, threading, time\n"
        "from panomap.cli.video import stop_on_signals\n"
        "stop = threading.Event()\n"
        "with stop_on_signals(stop):\n"
        "    os.kill(os.getpid(), signal.SIGHUP)\n"
        "    stop.wait(5)\n"
        "print('stopped' if stop.is_set() else 'running')\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert (done.returncode, done.stdout.strip()) == (0, "stopped"), done.stderr


def test_views_beyond_the_memory_limit_are_refused_before_any_work(work: Path, tmp_path: Path) -> None:
    outputs = [ViewOutput(GenericPanorama((512, 128)), tmp_path / f"{k}.mp4") for k in range(3)]
    # 3 x 512 x 128 pixels at 100 bytes each: 19.7 MB.
    with pytest.raises(PanomapError, match=r"need about 19\.7 MB .*3 view\(s\), 196,608 pixels.* 19\.0 MB available"):
        unwarp_video(load_table(work / "cam.npz"), str(work / "clip.mp4"), outputs, memory_limit=19_000_000)
    assert files_in(tmp_path) == []
    unwarp_video(load_table(work / "cam.npz"), str(work / "clip.mp4"), outputs, memory_limit=20_000_000)
    assert files_in(tmp_path) == ["0.mp4", "1.mp4", "2.mp4"]


# ----------------------------------------------------------------------------- tables checked as a whole


def edit_table(source: Path, target: Path, change: dict[str, Any], seal: bool = True, version: int = 2) -> None:
    """A copy of a table file with ``change`` merged into its metadata (``info.KEY`` into info);
    ``seal``: with a metadata checksum that matches (an editor who knows the format);
    ``version=1``: as version 1 wrote it (no metadata checksum)."""
    with np.load(source) as archive:
        meta = json.loads(str(archive["meta"][()]))
        entries = archive["entries"]
    for key, value in change.items():
        if key.startswith("info."):
            meta["info"][key[5:]] = value
        else:
            meta[key] = value
    if version == 1:
        meta["version"] = 1
        del meta["metadata_sha256"]
    elif seal:
        meta["metadata_sha256"] = metadata_digest(meta)
    np.savez(target, entries=entries, meta=np.array(json.dumps(meta)))


@pytest.mark.parametrize("version", [1, 2])
@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"info.fit": "fast"}, 'info.fit is "fast", not an object'),
        ({"info.sources": 3}, "info.sources is 3, not an object of texts"),
        ({"camera_position": [1.0, 2.0]}, "camera_position is [1.0, 2.0], not a list of 3 finite numbers"),
        ({"outer_radius_px": -5}, "0 <= cutoff_radius_px < outer_radius_px, not"),
        ({"cutoff_radius_px": 1e6, "outer_radius_px": 2e6}, "leaves no pixel of a 320 x 300 image visible"),
        ({"image_size": [320]}, "image_size is [320], not a list of 2 integers"),
        ({"size": [64.5, 16]}, "size is [64.5, 16], not a list of 2 integers"),
        ({"colour": "red"}, "unknown field colour"),
    ],
)
def test_tampered_metadata_is_refused_with_one_line(
    work: Path, tmp_path: Path, change: dict[str, Any], message: str, version: int
) -> None:
    edit_table(work / "cam.npz", tmp_path / "t.npz", change, version=version)
    for command in (["info", tmp_path / "t.npz"], ["floor", tmp_path / "t.npz", work / "omni.png", "-o",
                    tmp_path / "f.png", "--z", 0, "--x", 0, 6, "--y", 0, 5, "--resolution", 0.05]):  # fmt: skip
        assert_one_line_error(run(*command), "t.npz: the table's metadata is malformed", message, exit_code=1)


def test_info_escapes_control_characters_from_a_table_and_names_it_when_its_report_is_malformed(
    work: Path, tmp_path: Path
) -> None:
    # A table from someone else: a landmark named with terminal escapes (retitle the window, clear the
    # screen) and a bidirectional override; info printed them raw.
    meta = json.loads(str(np.load(work / "cam.npz")["meta"]))
    rows = meta["info"]["fit"]["landmarks"]
    rows[0]["name"] = "a\x1b]0;owned\x07b\x1b[2Jc\u202ed\x9be"
    edit_table(work / "cam.npz", tmp_path / "t.npz", {"info.fit": meta["info"]["fit"]})
    result = run("info", tmp_path / "t.npz")
    assert result.exit_code == 0, result.output + result.stderr
    assert "a\\x1b]0;owned\\x07b\\x1b[2Jc\\u202ed\\x9be" in result.output
    assert not any(ch in result.output for ch in "\x1b\x07\u202e\x9b")
    rows[0]["name"] = 7  # a malformed report: the error names the table's file
    edit_table(work / "cam.npz", tmp_path / "m.npz", {"info.fit": meta["info"]["fit"]})
    assert_one_line_error(run("info", tmp_path / "m.npz"), "m.npz: the fit report is malformed", exit_code=1)
    # An error that quotes a name from a file is escaped too.
    assert "\x1b" not in run("info", tmp_path / "no\x1b[2Jsuch.npz").stderr


def test_project_to_a_terminal_escapes_names_and_to_a_pipe_passes_them_through(work: Path, tmp_path: Path) -> None:
    # project -o - printed a points file's names raw to the terminal, escape sequences and all.
    (tmp_path / "pts.csv").write_text("name,X,Y,Z\nx\x1b]0;owned\x07y,3.5,2.0,0.0\n")
    command = [sys.executable, "-m", "panomap", "project", str(work / "cam.npz"), str(tmp_path / "pts.csv"), "-o", "-"]
    leader, follower = pty.openpty()
    process = subprocess.Popen(command, stdout=follower, stderr=subprocess.PIPE)
    os.close(follower)
    shown = b""
    while True:
        try:
            chunk = os.read(leader, 65536)
        except OSError:  # (EIO: the process ended and all was read)
            break
        if not chunk:
            break
        shown += chunk
    os.close(leader)
    assert process.wait(60) == 0
    process.stderr.close()  # type: ignore[union-attr]
    assert b"x\\x1b]0;owned\\x07y" in shown and b"\x1b" not in shown
    piped = subprocess.run(command, capture_output=True, check=True)
    assert b"x\x1b]0;owned\x07y" in piped.stdout  # (a pipe gets the CSV as it is)


def test_an_edit_behind_the_checksum_is_caught_and_version_1_files_still_load(work: Path, tmp_path: Path) -> None:
    # image_size null would apply the table to images of any size; a radius a pixel further is
    # well-formed: only the metadata's checksum tells either from what fit wrote.
    for change in ({"image_size": None}, {"cutoff_radius_px": CAMERA.cutoff_radius + 1}):
        edit_table(work / "cam.npz", tmp_path / "t.npz", change, seal=False)
        assert_one_line_error(run("info", tmp_path / "t.npz"), "metadata does not match its checksum", exit_code=1)
    edit_table(work / "cam.npz", tmp_path / "old.npz", {}, version=1)
    old, new = load_table(tmp_path / "old.npz"), load_table(work / "cam.npz")
    assert (old.image_size, old.cutoff_radius, old.info) == (new.image_size, new.cutoff_radius, new.info)
    np.testing.assert_array_equal(old.entries, new.entries)


# ----------------------------------------------------------------------------- sizes checked before memory is taken


def test_a_table_that_declares_a_huge_array_is_refused_before_reading_it(work: Path, tmp_path: Path) -> None:
    """A 25000 x 20000 table declared in a few bytes: refused from the header, no 4 GB taken."""
    with np.load(work / "cam.npz") as archive:
        meta = archive["meta"]
    path = tmp_path / "huge.npz"
    np.savez(path, meta=meta)
    header = {"descr": "<f4", "fortran_order": False, "shape": (25000, 20000, 2)}
    with zipfile.ZipFile(path, "a") as archive:
        archive.writestr("entries.npy", _npy_header(header) + b"\0" * 1024)
    tracemalloc.start()
    try:
        with pytest.raises(PanomapError, match="declares a 25000 x 20000 table: more than the limits"):
            load_table(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 20_000_000  # bytes: the metadata and the zip's buffers, not the table


def _npy_header(header: dict[str, Any]) -> bytes:
    text = repr(header).encode("latin1")
    text += b" " * (-(len(text) + 11) % 64) + b"\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(text)) + text


def _png_header_only(width: int, height: int) -> bytes:
    """A PNG that declares width x height 8-bit grey pixels and holds almost none of them."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 64)) + chunk(b"IEND", b"")


def test_an_image_is_refused_from_its_header_before_it_is_decoded(
    work: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "big.png").write_bytes(_png_header_only(30000, 30000))

    def no_decoding(*args: Any) -> None:
        raise AssertionError("decoded")

    monkeypatch.setattr(cv2, "imdecode", no_decoding)
    result = run("panorama", work / "cam.npz", tmp_path / "big.png", "-o", tmp_path / "p.png")
    expected = f"big.png: the image is 30000 x 30000, the table {work / 'cam.npz'} is for 320 x 300 images"
    assert_one_line_error(result, expected, exit_code=1)
    with pytest.raises(PanomapError, match="30000 x 30000: more than the 268 megapixels panomap reads"):
        read_image(tmp_path / "big.png")


@pytest.mark.parametrize(("suffix", "kind"), [(".hdr", "a Radiance HDR image"), (".pfm", "a PFM image")])
def test_a_float_image_pillow_cannot_read_is_refused_before_it_is_decoded(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, suffix: str, kind: str
) -> None:
    """Radiance HDR and PFM (OpenCV reads them, Pillow does not tell their size) are 32-bit float: refused from
    their first bytes. Before, each was decoded first (a 16400 x 16400 HDR took 6.4 GB), then refused."""
    path = tmp_path / f"float{suffix}"
    assert cv2.imwrite(str(path), np.random.default_rng(0).random((48, 64, 3)).astype(np.float32))

    def no_decoding(*args: Any) -> None:
        raise AssertionError("decoded")

    monkeypatch.setattr(cv2, "imdecode", no_decoding)
    with pytest.raises(PanomapError, match=f"images must be 8- or 16-bit, this one is {kind} \\(32-bit float\\)"):
        read_image(path)


# ----------------------------------------------------------------------------- broken inputs found by trying them


def test_broken_landmark_files_and_a_wrong_axis_get_one_line_and_no_numpy_noise(work: Path, tmp_path: Path) -> None:
    """Each was a traceback (a RecursionError; NumPy's "SVD did not converge" after its RuntimeWarnings), or
    accepted: JSON true as the number 1."""
    fixed = ["--centre", *CAMERA.centre, "--image-size", f"{SIZE[0]}x{SIZE[1]}", "--cutoff-radius",
             CAMERA.cutoff_radius, "--outer-radius", CAMERA.outer_radius]  # fmt: skip
    (tmp_path / "deep.json").write_text("[" * 100000 + "]" * 100000)
    result = run("fit", tmp_path / "deep.json", "-o", tmp_path / "t.npz", "--camera", *POSITION, *fixed)
    assert_one_line_error(result, "deep.json: not valid landmarks JSON (nested too deeply)", exit_code=1)
    point = {"name": "a", "u": 10.0, "v": 20.0, "X": 1.0, "Y": 2.0, "Z": True}
    (tmp_path / "bool.json").write_text(json.dumps({"landmarks": [point] * 6}))
    result = run("fit", tmp_path / "bool.json", "-o", tmp_path / "t.npz", "--camera", *POSITION, *fixed)
    assert_one_line_error(result, "bool.json: landmark 1, Z is not a number: true", exit_code=1)
    named = [{"name": n, "u": 10.0 + k, "v": 20.0, "X": 1.0 + k, "Y": 2.0, "Z": 0.0} for k, n in enumerate("abcdb")]
    (tmp_path / "twice.json").write_text(json.dumps({"landmarks": named}))
    result = run("fit", tmp_path / "twice.json", "-o", tmp_path / "t.npz", "--camera", *POSITION, *fixed)
    expected = "twice.json: landmarks 2 and 5 are both named 'b': give each landmark a name of its own"
    assert_one_line_error(result, expected, exit_code=1)
    # The camera looks down; told that its centre sees the zenith, no model can place the landmarks.
    for model in ("auto", "fisheye"):
        result = run("fit", work / "lm.csv", "-o", tmp_path / "t.npz", "--camera", *POSITION, *fixed, "--axis", "up",
                     "--model", model)  # fmt: skip
        assert result.exit_code == 1 and "Traceback" not in result.stderr and "Warning" not in result.stderr
        assert result.stderr.startswith("panomap: error:") and result.stderr.count("\n") == 1, result.stderr
    assert not (tmp_path / "t.npz").exists()


def test_video_errors_name_the_file_they_are_about(work: Path, tmp_path: Path) -> None:
    """A frame of another size partway through a video names the video; a view the camera cannot see names
    its output; the size suggested for a chroma-subsampled output is a size (before: "size=0x0")."""
    half = cv2.resize(cv2.imread(str(work / "omni.png")), (SIZE[0] // 2, SIZE[1] // 2))
    with av.open(str(tmp_path / "switch.ts"), "w") as container:  # 3 frames at the table's size, then 3 at half
        stream = container.add_stream("mpeg2video", rate=25)
        stream.width, stream.height, stream.pix_fmt = SIZE[0], SIZE[1], "yuv420p"
        omni = cv2.imread(str(work / "omni.png"))
        for index in range(3):
            frame = av.VideoFrame.from_ndarray(omni, format="bgr24")
            frame.pts = index
            container.mux(stream.encode(frame))
        container.mux(stream.encode(None))
    with av.open(str(tmp_path / "small.ts"), "w") as container:
        stream = container.add_stream("mpeg2video", rate=25)
        stream.width, stream.height, stream.pix_fmt = SIZE[0] // 2, SIZE[1] // 2, "yuv420p"
        for index in range(3):
            frame = av.VideoFrame.from_ndarray(half, format="bgr24")
            frame.pts = index
            container.mux(stream.encode(frame))
        container.mux(stream.encode(None))
    (tmp_path / "both.ts").write_bytes((tmp_path / "switch.ts").read_bytes() + (tmp_path / "small.ts").read_bytes())
    views = ["--view", "panorama:size=64x32"]
    result = run("video", work / "cam.npz", tmp_path / "both.ts", "-o", tmp_path / "o_{name}.mp4", *views)
    assert_one_line_error(result, f"{tmp_path / 'both.ts'}: the image is 160 x 150, the table is for", exit_code=1)
    floor = ["--view", "floor:z=10,x=0:6,y=0:5,size=64x64,name=up"]
    result = run("video", work / "cam.npz", work / "clip.mp4", "-o", tmp_path / "o_{name}.mp4", *floor)
    assert_one_line_error(result, f"{tmp_path / 'o_up.mp4'}: the plane Z = 10 is at or above the camera", exit_code=1)
    result = run("video", work / "cam.npz", work / "clip.mp4", "-o", tmp_path / "o.mp4", "--view", "panorama:size=1x1")
    assert_one_line_error(result, "give the view a size such as size=2x2", exit_code=1)
    assert not [p for p in tmp_path.iterdir() if p.suffix == ".mp4"]


def test_a_fifo_is_not_read_and_an_image_size_that_is_not_the_images_is_refused(work: Path, tmp_path: Path) -> None:
    """A landmark file or a table that is a FIFO with no writer blocked the command for ever (an image was
    refused as "not a file"); --image-size beside an --image of another size was ignored."""
    os.mkfifo(tmp_path / "lm.fifo")
    result = run("fit", tmp_path / "lm.fifo", "-o", tmp_path / "t.npz", "--camera", *POSITION, "--centre", 1, 1)
    assert_one_line_error(result, "lm.fifo: not a file", exit_code=1)
    result = run("panorama", tmp_path / "lm.fifo", work / "omni.png", "-o", tmp_path / "p.png")
    assert_one_line_error(result, "lm.fifo: not a file", exit_code=1)
    result = run("fit", work / "lm.csv", "-o", tmp_path / "t.npz", "--camera", *POSITION, "--image", work / "omni.png",
                 "--image-size", "10x10")  # fmt: skip
    assert_one_line_error(result, f"10x10, but {work / 'omni.png'} is {SIZE[0]} x {SIZE[1]}", exit_code=2)
    assert not (tmp_path / "t.npz").exists() and not (tmp_path / "p.png").exists()
