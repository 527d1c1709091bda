"""``panomap batch`` and :mod:`panomap.batch`: jobs on Dask, resumable, on a local cluster and a real one.

The inputs are made here: the bundled room rendered through a simulated equidistant fisheye
(320 x 320), still images turned by a few degrees each (so that every output differs), and
a 40-frame clip of the room turning 3 deg per frame. Outputs are checked against the view
commands' and ``panomap video``'s own outputs (bit for bit for images, decoded frame for
frame for lossless video), never against numbers the batch code produced.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import av
import cv2
import numpy as np
import pytest

import panomap
from panomap.batch.job import Job, Settings, excluded, find_inputs, make_job, output_pattern, without_outputs
from panomap.batch.leftovers import tidy
from panomap.batch.record import Done, Record
from panomap.batch.run import Progress, codec_threads, connect, run_job
from panomap.batch.tasks import parts_folder
from panomap.simulate import load_room, render, standard_cameras
from panomap.table.file import save_table
from panomap.video.output import EncoderSettings
from panomap.views.spec import name_views, parse_view_spec

from helpers import assert_one_line_error, learn_table, run, spread_landmarks

SIZE = (320, 320)
CAMERA = standard_cameras(SIZE, centre=(160.3, 159.6), s=-1, phi0=0.4)["equidistant"]
PANORAMA = "panorama:size=480x120"
DOOR = "perspective:yaw=30,pitch=-35,fov=90,size=160x120,name=door"
# The same views as the view commands take them (the commands make their one map the exact way).
COMMANDS = {
    "panorama": ["panorama", "--size", "480x120"],
    "door": ["perspective", "--yaw", "30", "--pitch", "-35", "--fov", "90", "--size", "160x120"],
}
VIEWS = name_views([parse_view_spec(PANORAMA), parse_view_spec(DOOR)])
LOSSLESS = Settings(EncoderSettings("libx264", "yuv420p", 0, "veryfast"))  # x264 crf 0: lossless, B-frames
RATE, FRAMES, IMAGES = 25, 40, 8
SRC = str(Path(panomap.__file__).resolve().parents[1])

room = load_room()
OMNI = render(room, CAMERA, supersample=1)


def turned(degrees: float) -> np.ndarray:
    return cv2.warpAffine(OMNI, cv2.getRotationMatrix2D(CAMERA.centre, degrees, 1.0), SIZE)


def write_clip(path: Path) -> None:
    """FRAMES frames of the turning room, H.264 yuv420p, RATE fps, no audio."""
    with av.open(str(path), "w") as container:
        video = container.add_stream("libx264", rate=RATE)
        video.width, video.height = SIZE
        video.pix_fmt = "yuv420p"
        video.options = {"preset": "ultrafast", "crf": "16"}
        for index in range(FRAMES):
            frame = av.VideoFrame.from_ndarray(turned(3.0 * index), format="bgr24")
            frame.pts = index
            for packet in video.encode(frame):
                container.mux(packet)
        for packet in video.encode(None):
            container.mux(packet)


def decoded(path: Path) -> list[tuple[float, np.ndarray]]:
    """(time in s, frame as yuv420p planes) of every frame: compared without any conversion."""
    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        return [(float(f.pts * stream.time_base), f.to_ndarray(format="yuv420p")) for f in container.decode(stream)]


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def record_lines(path: Path) -> list[dict[str, object]]:
    return [json.loads(line) for line in path.read_text().splitlines()]


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """cam.npz (the learned table), images/i0..i7.png (the room turned 0, 5, ... deg), clip.mp4."""
    folder = tmp_path_factory.mktemp("batch")
    landmarks = spread_landmarks(CAMERA, tuple(room.camera), 20, np.random.default_rng(3))
    table, _ = learn_table(CAMERA, tuple(room.camera), landmarks, SIZE)
    save_table(table, folder / "cam.npz")
    (folder / "images").mkdir()
    for index in range(IMAGES):
        cv2.imwrite(str(folder / "images" / f"i{index}.png"), turned(5.0 * index))
    write_clip(folder / "clip.mp4")
    return folder


@pytest.fixture(scope="module")
def cluster() -> Iterator[str]:
    """A local Dask cluster of two single-threaded worker processes, shared by the tests; its address."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as local:
        yield local.scheduler_address


def image_job(work: Path, out: Path, count: int = IMAGES) -> Job:
    inputs = find_inputs([str(work / "images" / f"i{k}.png") for k in range(count)], work / "cam.npz")
    return make_job(inputs, VIEWS, str(out / "{camera}" / "{stem}_{name}.png"))


# ----------------------------------------------------------------------------- the outputs


def test_a_two_camera_manifest_on_the_default_local_cluster_equals_the_view_commands_bit_for_bit(
    work: Path, tmp_path: Path
) -> None:
    shutil.copy(work / "cam.npz", tmp_path / "north.npz")
    shutil.copy(work / "cam.npz", tmp_path / "south.npz")
    rows = ["input,table,camera"]
    rows += [f"{work}/images/i{k}.png,north.npz,north" for k in range(3)]
    rows += [f"{work}/images/i{k}.png,south.npz," for k in range(3, 5)]  # camera: the table's stem
    (tmp_path / "job.csv").write_text("\n".join(rows) + "\n")
    result = run(
        "batch", tmp_path / "job.csv", "-o", tmp_path / "out/{camera}/{stem}_{name}.mp4",
        "--view", PANORAMA, "--view", DOOR, "--record", tmp_path / "rec.jsonl", "--workers", "2",
    )  # fmt: skip
    assert result.exit_code == 0, result.output + result.stderr
    assert "unwarped 5 of 5 inputs (10 outputs, 5 frames)" in result.output and "2 worker(s)" in result.output
    lines = record_lines(tmp_path / "rec.jsonl")
    assert len(lines) == 10 and all(line["status"] == "done" and line["frames"] == 1 for line in lines)
    by_output = {line["output"]: line for line in lines}
    for k in range(5):
        camera = "north" if k < 3 else "south"
        for name, command in COMMANDS.items():
            made = tmp_path / "out" / camera / f"i{k}_{name}.png"  # images keep their format
            alone = tmp_path / f"alone_{k}_{name}.png"
            single = run(
                command[0], tmp_path / f"{camera}.npz", work / "images" / f"i{k}.png", "-o", alone, *command[1:]
            )
            assert single.exit_code == 0, single.stderr
            assert made.read_bytes() == alone.read_bytes(), made
            line = by_output[str(made)]
            assert line["sha256"] == sha256(made) and line["bytes"] == made.stat().st_size
            assert line["input"] == str(work / "images" / f"i{k}.png") and line["view"] == name
    assert not list((tmp_path / "out").rglob(".*"))  # no temporary left


@pytest.mark.slow
def test_a_segmented_video_equals_the_unsegmented_one_frame_for_frame(work: Path, tmp_path: Path, cluster: str) -> None:
    """Lossless x264 (with B-frames): every frame and timestamp of the joined output as the whole run's."""
    inputs = find_inputs([str(work / "clip.mp4")], work / "cam.npz")
    outputs = {}
    for how, segment in (("whole", None), ("parts", 0.5)):
        job = make_job(inputs, VIEWS, str(tmp_path / how / "{stem}_{name}.mp4"), LOSSLESS)
        report = run_job(job, Record(tmp_path / f"{how}.jsonl"), scheduler=cluster, segment_s=segment)
        assert report.ok and report.done == 1 and report.frames == FRAMES, report
        outputs[how] = job.items[0].outputs
    for whole, parts in zip(outputs["whole"], outputs["parts"], strict=True):
        a, b = decoded(whole.path), decoded(parts.path)
        assert len(a) == len(b) == FRAMES
        assert [t for t, _ in b] == pytest.approx([k / RATE for k in range(FRAMES)], abs=1e-6)  # continuous
        assert [t for t, _ in a] == [t for t, _ in b]
        differ = [k for k, ((_, x), (_, y)) in enumerate(zip(a, b, strict=True)) if not np.array_equal(x, y)]
        assert differ == [], (
            whole.path.name,
            differ,
            [int(np.abs(a[k][1].astype(int) - b[k][1]).max()) for k in differ],
        )
    line = record_lines(tmp_path / "parts.jsonl")[0]
    assert line["frames"] == FRAMES and line["sha256"] == sha256(Path(str(line["output"])))
    assert not (tmp_path / "parts" / ".panomap-parts").exists()  # the segments are gone
    # And the whole run equals panomap video's own output.
    alone = tmp_path / "alone.mp4"
    single = run("video", work / "cam.npz", work / "clip.mp4", "-o", alone, "--view", PANORAMA, "--crf", "0")
    assert single.exit_code == 0, single.stderr
    pairs = zip(decoded(alone), decoded(outputs["whole"][0].path), strict=True)
    assert all(np.array_equal(x, y) for (_, x), (_, y) in pairs)


# ----------------------------------------------------------------------------- resuming


def test_an_interrupted_job_rerun_redoes_only_what_is_unfinished(work: Path, tmp_path: Path, cluster: str) -> None:
    job = image_job(work, tmp_path / "out")
    stop = threading.Event()

    def progress(state: Progress) -> None:
        if state.inputs_done >= 3:
            stop.set()

    first = run_job(job, Record(tmp_path / "rec.jsonl"), scheduler=cluster, chunk=1, progress=progress, stop=stop)
    assert first.interrupted and not first.ok and 3 <= first.done < IMAGES
    finished = {line["output"]: line for line in record_lines(tmp_path / "rec.jsonl")}
    assert len(finished) == 2 * first.done
    before = {path: Path(path).stat().st_mtime_ns for path in finished}
    # One finished output damaged since: it is redone too.
    damaged = Path(sorted(finished)[0])
    damaged.write_bytes(damaged.read_bytes()[:100])
    time.sleep(0.01)
    second = run_job(job, Record(tmp_path / "rec.jsonl"), scheduler=cluster)
    assert second.ok and second.skipped == first.done - 1 and second.done == IMAGES - first.done + 1
    for path, mtime in before.items():
        damaged_input = Path(path).name.split("_")[0] == damaged.name.split("_")[0]
        assert (Path(path).stat().st_mtime_ns == mtime) != damaged_input, path
    record = Record(tmp_path / "rec.jsonl")
    assert all(record.complete(item) for item in job.items)
    third = run_job(job, Record(tmp_path / "rec.jsonl"), scheduler=cluster, force=True)
    assert third.done == IMAGES and third.skipped == 0


def test_a_rerun_removes_what_killed_runs_left_and_never_a_live_runs_temporaries(
    work: Path, tmp_path: Path, cluster: str
) -> None:
    # A SIGKILLed batch left .part files beside outputs that its workers (outliving it) then finished: the
    # rerun found them complete, skipped them, and the temporaries stayed; a failed segmented video left an
    # empty .panomap-parts/<id>/.
    inputs = find_inputs([str(work / "images" / "i0.png"), str(work / "clip.mp4")], work / "cam.npz")
    job = make_job(inputs, VIEWS, str(tmp_path / "out" / "{stem}_{name}.mp4"))
    assert run_job(job, Record(tmp_path / "rec.jsonl"), scheduler=cluster).ok
    gone = subprocess.Popen(["true"])
    gone.wait()  # (its process id is now free: the temporary's owner is dead)
    alive = subprocess.Popen(["sleep", "120"])
    try:
        image_output, video_output = job.items[0].outputs[0].path, job.items[1].outputs[1].path
        dead = [image_output.parent / f".{image_output.name}.{gone.pid}-abc123.part.png",
                video_output.parent / f".{video_output.name}.{gone.pid}-def456.part.mp4"]  # fmt: skip
        live = image_output.parent / f".{image_output.name}.{alive.pid}-ghi789.part.png"
        parts = parts_folder(job.items[1])
        parts.mkdir(parents=True)
        (parts / "000000_panorama.mp4").write_bytes(b"a part of a killed run")
        (parts / f".000001_door.mp4.{gone.pid}-jkl012.part.mp4").write_bytes(b"half a part")
        for path in [*dead, live]:
            path.write_bytes(b"half an output")
        again = run_job(job, Record(tmp_path / "rec.jsonl"), scheduler=cluster)
        assert again.ok and again.skipped == 2 and again.done == 0
        assert not any(path.exists() for path in dead) and not parts.parent.exists()
        assert live.exists()  # (another run, alive, writes it: never touched)
        # An empty parts folder of an input that is not complete (a failed segmented run's) goes too.
        parts.mkdir(parents=True)
        assert tidy(job, lambda item: False) == [parts] and not parts.parent.exists()
    finally:
        alive.kill()
        alive.wait()


def test_images_a_viewer_would_turn_are_warned_of_once_a_camera(work: Path, tmp_path: Path, cluster: str) -> None:
    from PIL import Image

    folder = tmp_path / "in"
    folder.mkdir()
    exif = Image.Exif()
    exif[0x0112] = 6
    for path in sorted((work / "images").glob("*.png"))[:3]:
        with Image.open(path) as image:
            image.save(folder / path.name, exif=exif)
    os.environ["DASK_SCHEDULER_ADDRESS"] = cluster
    try:
        result = run(
            "batch", folder, "--table", work / "cam.npz", "-o", tmp_path / "out/{stem}_{name}.png",
            "--view", PANORAMA, "--record", tmp_path / "rec.jsonl", "-q",
        )  # fmt: skip
    finally:
        del os.environ["DASK_SCHEDULER_ADDRESS"]
    assert result.exit_code == 0, result.output + result.stderr
    warnings = [line for line in result.stderr.splitlines() if "EXIF orientation (6)" in line]
    assert len(warnings) == 1 and warnings[0].startswith("panomap: warning: "), result.stderr
    assert len(list((tmp_path / "out").glob("*.png"))) == 3


def test_a_failing_input_is_retried_recorded_and_the_rest_goes_on(work: Path, tmp_path: Path, cluster: str) -> None:
    folder = tmp_path / "in"
    shutil.copytree(work / "images", folder)
    (folder / "i2.png").write_bytes(b"not a png")
    (folder / "i5.png").unlink()
    cv2.imwrite(str(folder / "i5.png"), np.zeros((100, 100, 3), np.uint8))  # the wrong size
    os.environ["DASK_SCHEDULER_ADDRESS"] = cluster
    try:
        result = run(
            "batch", folder, "--table", work / "cam.npz", "-o", tmp_path / "out/{stem}_{name}.jpg",
            "--view", PANORAMA, "--view", DOOR, "--record", tmp_path / "rec.jsonl", "-q",
        )  # fmt: skip
    finally:
        del os.environ["DASK_SCHEDULER_ADDRESS"]
    assert result.exit_code == 1, result.output + result.stderr
    errors = result.stderr.splitlines()
    assert len(errors) == 3 and "Traceback" not in result.stderr
    assert "i2.png: cannot read it as an image" in result.stderr
    assert "i5.png: the image is 100 x 100, the table" in result.stderr
    assert errors[-1].startswith("panomap: error: 2 of 8 inputs failed")
    lines = record_lines(tmp_path / "rec.jsonl")
    assert sorted(Path(str(line["input"])).name for line in lines if line["status"] == "failed") == ["i2.png", "i5.png"]
    assert len([line for line in lines if line["status"] == "done"]) == 12
    assert not (tmp_path / "out" / "i2_panorama.png").exists()


def test_a_folder_made_for_outputs_that_never_came_is_removed(work: Path, tmp_path: Path, cluster: str) -> None:
    """Two cameras, one whose only input is broken: its {camera} folder was left behind, empty."""
    from panomap.batch.job import BatchInput

    (tmp_path / "broken.png").write_bytes(b"not a png")
    inputs = [
        BatchInput(work / "images" / "i0.png", work / "cam.npz", "north"),
        BatchInput(tmp_path / "broken.png", work / "cam.npz", "south"),
    ]
    job = make_job(inputs, VIEWS, str(tmp_path / "out" / "{camera}" / "deep" / "{stem}_{name}.png"))
    report = run_job(job, Record(tmp_path / "rec.jsonl"), scheduler=cluster, retries=0)
    assert report.done == 1 and len(report.failed) == 1
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["north"]
    assert len(list((tmp_path / "out" / "north" / "deep").iterdir())) == len(VIEWS)


def test_a_rerun_never_takes_the_jobs_own_outputs_as_inputs_and_exclude_leaves_out_what_it_matches(
    work: Path, tmp_path: Path, cluster: str
) -> None:
    # The outputs' folder inside the inputs' folder: the rerun found the 6 outputs of the first run as
    # inputs ("6 of 9 failed"). Now they are left out (with a note), and the rerun finds all complete.
    cams = tmp_path / "cams"
    cams.mkdir()
    for k in range(3):
        shutil.copy(work / "images" / f"i{k}.png", cams / f"i{k}.png")
    shutil.copy(work / "images" / "i3.png", cams / "skip_me.png")
    args = ["batch", cams, "--table", work / "cam.npz", "-o", cams / "out/{camera}/{stem}_{name}.png",
            "--view", PANORAMA, "--view", DOOR, "--record", cams / "rec.jsonl", "--scheduler", cluster,
            "--exclude", "skip_*"]  # fmt: skip
    first = run(*args)
    assert first.exit_code == 0, first.output + first.stderr
    assert "unwarped 3 of 3 inputs (6 outputs" in first.output
    assert len(list((cams / "out").rglob("*.png"))) == 6 and not any((cams / "out").rglob("skip_me*"))
    again = run(*args)
    assert again.exit_code == 0, again.output + again.stderr
    assert "6 of the files found are outputs of this job" in again.stderr
    assert "unwarped 0 of 3 inputs" in again.output and "3 already complete" in again.output
    assert len(list((cams / "out").rglob("*.png"))) == 6
    # Outputs of an input since removed are still outputs of the job; another stem is an input.
    kept, dropped = without_outputs(find_inputs([str(cams)], work / "cam.npz", None, ["skip_*"]), VIEWS,
                                    str(cams / "out/{camera}/{stem}_{name}.png"))  # fmt: skip
    assert sorted(item.path.name for item in kept) == ["i0.png", "i1.png", "i2.png"] and len(dropped) == 6
    pattern = output_pattern(str(cams / "out/{camera}/{stem}_{name}.mp4"), ["cam"], ["panorama", "door"])
    assert pattern.fullmatch((cams / "out/cam/gone_door.jpg").as_posix())
    assert not pattern.fullmatch((cams / "out/cam/gone_hall.jpg").as_posix())  # not a view of this job
    assert not pattern.fullmatch((cams / "out/other/gone_door.jpg").as_posix())  # not a camera of this job
    assert excluded(Path("a/old/x.mp4"), ["*/old/*"]) and excluded(Path("/v/x.avi"), ["*.avi"])
    assert not excluded(Path("a/new/x.mp4"), ["*/old/*", "*.avi"])


def test_bad_jobs_get_one_line_errors(work: Path, tmp_path: Path) -> None:
    images = work / "images"
    common = ["--view", PANORAMA, "--record", tmp_path / "rec.jsonl"]
    result = run("batch", images, "--table", tmp_path / "missing.npz", "-o", tmp_path / "{stem}.png", *common)
    assert_one_line_error(result, "missing.npz", "no such table file", exit_code=1)
    result = run("batch", images, "--table", work / "cam.npz", "-o", tmp_path / "{stem}_{view}.png", *common)
    # Usage errors (exit 2): the template, and inputs and --table that do not go together.
    assert_one_line_error(result, "unknown key {view}", "{camera}, {stem}, {name}, {ext}", exit_code=2)
    result = run("batch", images, "-o", tmp_path / "{stem}.png", *common)
    assert_one_line_error(result, "give the table with --table TABLE", exit_code=2)
    result = run("batch", images, "--table", work / "cam.npz", "-o", tmp_path / "same.png", *common)
    assert_one_line_error(result, "two outputs would be this file", exit_code=1)
    result = run(
        "batch", tmp_path / "nothing*.png", "--table", work / "cam.npz", "-o", tmp_path / "{stem}.png", *common
    )
    assert_one_line_error(result, "matches no image or video", exit_code=1)
    (tmp_path / "job.csv").write_text("input,table\nimages/i0.png,\n")
    result = run("batch", tmp_path / "job.csv", "-o", tmp_path / "{stem}.png", *common)
    assert_one_line_error(result, "job.csv: row 1 needs an input and a table", exit_code=1)
    result = run("batch", tmp_path / "job.csv", "--table", work / "cam.npz", "-o", tmp_path / "{stem}.png", *common)
    assert_one_line_error(result, "job.csv: the manifest names each input's table: give no --table", exit_code=2)
    result = run("batch", images, "--table", work / "cam.npz", "-o", tmp_path / "{stem}.png")
    assert_one_line_error(result, "give at least one --view", exit_code=2)
    assert not (tmp_path / "rec.jsonl").exists()
    # An output that is an input through a link to its folder (paths were compared as text).
    (tmp_path / "in").mkdir()
    for name in ("x.png", "x_panorama.png"):
        shutil.copy(images / "i0.png", tmp_path / "in" / name)
    (tmp_path / "link").symlink_to(tmp_path / "in")
    before = (tmp_path / "in" / "x_panorama.png").read_bytes()
    result = run("batch", tmp_path / "in", "--table", work / "cam.npz", "-o", tmp_path / "link/{stem}_{name}.png",
                 "--view", PANORAMA, "--record", tmp_path / "rec.jsonl")  # fmt: skip
    assert_one_line_error(result, "x_panorama.png", "is an input: refusing to overwrite it", exit_code=1)
    assert (tmp_path / "in" / "x_panorama.png").read_bytes() == before


def test_bad_manifests_templates_and_records_get_one_line_errors(work: Path, tmp_path: Path) -> None:
    """Found by trying broken jobs (each was a traceback, a file written outside the output folder, or a
    manifest with the record's lines appended to it): one line, exit 1 or 2, every file as it was."""
    shutil.copy(work / "images" / "i0.png", tmp_path / "i0.png")
    shutil.copy(work / "cam.npz", tmp_path / "cam.npz")
    out = ["-o", tmp_path / "out" / "{camera}" / "{stem}_{name}.png", "--view", PANORAMA, "-q"]
    record = ["--record", tmp_path / "rec.jsonl"]
    (tmp_path / "extra.csv").write_text("input,table\ni0.png,cam.npz,surplus\n")
    assert_one_line_error(run("batch", tmp_path / "extra.csv", *out, *record), "row 1 has more fields", exit_code=1)
    (tmp_path / "null.yaml").write_text("- {input: i0.png, table: cam.npz, null: x}\n")
    assert_one_line_error(run("batch", tmp_path / "null.yaml", *out, *record), "a key that is null", exit_code=1)
    (tmp_path / "escape.json").write_text('[{"input": "i0.png", "table": "cam.npz", "camera": "../../escape"}]')
    result = run("batch", tmp_path / "escape.json", *out, *record)
    assert_one_line_error(result, "the camera name '../../escape' must be a plain name", exit_code=1)
    for template, shown in [("{stem:d}.png", "{stem:d}"), ("{stem!x}.png", "{stem!x}")]:
        result = run("batch", tmp_path / "i0.png", "--table", tmp_path / "cam.npz", "-o", tmp_path / template,
                     "--view", PANORAMA, *record)  # fmt: skip
        assert_one_line_error(result, f"has {shown}: its keys take no format spec or conversion", exit_code=2)
    # The record must be a record: a manifest, the landmarks or any other text is refused, and left as it was.
    (tmp_path / "job.csv").write_text("input,table,camera\ni0.png,cam.npz,north\n")
    before = (tmp_path / "job.csv").read_bytes()
    result = run("batch", tmp_path / "job.csv", *out, "--record", tmp_path / "job.csv")
    assert_one_line_error(result, "job.csv: not a batch record: line 1 is not one of its entries", exit_code=1)
    assert (tmp_path / "job.csv").read_bytes() == before
    (tmp_path / "out" / "north").mkdir(parents=True)
    result = run("batch", tmp_path / "job.csv", *out, "--record", tmp_path / "out" / "north" / "i0_panorama.png")
    assert_one_line_error(result, "the record would be an output of the job", exit_code=1)
    assert not (tmp_path / "escape").exists() and not (tmp_path.parent / "escape").exists()
    assert not (tmp_path / "rec.jsonl").exists()


def test_segments_shorter_than_a_frame_hold_one_frame_each() -> None:
    """A 1.2 s clip at 10 fps cut every 0.03 s planned 40 segments, most of them between two frames (the
    batch failed: "no frame could be decoded"); each now holds a whole number of frames, one at least."""
    from fractions import Fraction

    from panomap.batch.segments import Probe, plan_segments

    clip = Probe(duration_s=1.2, frames=12, start_s=0.0, time_base=Fraction(1, 10240), rate=Fraction(10))
    segments = plan_segments(clip, 0.03)
    assert len(segments) == 11 and segments[-1].duration_s is None
    assert all(segment.duration_s == pytest.approx(0.1) for segment in segments[:-1])
    assert [round(segment.start_s * 10, 9) for segment in segments] == list(range(11))
    assert len(plan_segments(clip, 0.26)) == 4  # 0.26 s is 3 frames (0.3 s): frames 0-2, 3-5, 6-8, 9-11


def test_a_record_cut_by_a_kill_is_read_and_appended_to_on_a_line_of_its_own(tmp_path: Path) -> None:
    """The last line cut mid-entry (a kill while writing) is skipped when read; the next entry starts on a new
    line, so that the record reads back whole (before, it was glued to the cut line, and lost)."""
    done = Done("/o/a.png", "/i/a.png", "pano", "k", 1, 10, "s", 5, 0.1)
    first = Record(tmp_path / "rec.jsonl")
    first.add_done([done])
    text = (tmp_path / "rec.jsonl").read_text()
    (tmp_path / "rec.jsonl").write_text(text + text[:40])  # a second entry cut after 40 characters
    second = Record(tmp_path / "rec.jsonl")
    assert set(second.done) == {"/o/a.png"}
    second.add_done([replace(done, output="/o/b.png")])
    assert set(Record(tmp_path / "rec.jsonl").done) == {"/o/a.png", "/o/b.png"}


# ----------------------------------------------------------------------------- a real cluster, a worker killed


def scheduler_address(scheduler_file: Path, timeout_s: float = 60.0) -> str:
    """The address a ``dask scheduler`` started with ``--port 0`` wrote to its scheduler file.

    Its own free port, not one probed here first: a port free when probed could be taken
    (by any process's outgoing connection) before the scheduler bound it.
    """
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            return str(json.loads(scheduler_file.read_text())["address"])
        except (OSError, ValueError, KeyError):
            time.sleep(0.1)
    raise AssertionError(f"the scheduler wrote no address to {scheduler_file} in {timeout_s} s")


def start(*args: str) -> subprocess.Popen[bytes]:
    """A Dask process of its own session (so that killing its group takes its nanny and worker)."""
    env = os.environ | {"PYTHONPATH": SRC + os.pathsep + os.environ.get("PYTHONPATH", "")}
    return subprocess.Popen(
        [sys.executable, "-m", *args],
        env=env,
        start_new_session=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )


@pytest.mark.slow
def test_a_worker_killed_mid_job_on_a_real_cluster_loses_nothing(work: Path, tmp_path: Path, cluster: str) -> None:
    """``dask scheduler`` and two ``dask worker`` processes; one killed (SIGKILL, nanny and all)
    when the first result comes in: every output complete and equal to a run without the kill."""
    inputs = find_inputs([str(work / "images"), str(work / "clip.mp4")], work / "cam.npz")
    reference = make_job(inputs, VIEWS, str(tmp_path / "ref" / "{stem}_{name}.mp4"), LOSSLESS)
    assert run_job(reference, Record(tmp_path / "ref.jsonl"), scheduler=cluster, segment_s=0.4, chunk=1).ok
    scheduler_file = tmp_path / "scheduler.json"
    processes = [
        start(
            "distributed.cli.dask_scheduler",
            *("--host", "127.0.0.1", "--port", "0", "--scheduler-file", str(scheduler_file), "--no-dashboard"),
        )
    ]
    try:
        address = scheduler_address(scheduler_file)
        for name in ("w1", "w2"):
            processes.append(
                start("distributed.cli.dask_worker", address, "--nthreads", "1", "--name", name, "--no-dashboard")
            )
        from distributed import Client

        with Client(address, timeout=30) as client:
            client.wait_for_workers(2, timeout=60)
        killed: list[int] = []

        def progress(state: Progress) -> None:
            if not killed:
                os.killpg(processes[1].pid, signal.SIGKILL)
                killed.append(processes[1].pid)

        job = make_job(inputs, VIEWS, str(tmp_path / "out" / "{stem}_{name}.mp4"), LOSSLESS)
        report = run_job(
            job, Record(tmp_path / "rec.jsonl"), scheduler=address, segment_s=0.4, chunk=1, progress=progress
        )
        assert killed and processes[1].wait(timeout=10) != 0
        assert report.ok and report.done == IMAGES + 1 and report.workers == 2, report
        for made, ref in zip(job.items, reference.items, strict=True):
            for output, expected in zip(made.outputs, ref.outputs, strict=True):
                if output.path.suffix == ".png":
                    assert output.path.read_bytes() == expected.path.read_bytes(), output.path
                else:
                    a, b = decoded(output.path), decoded(expected.path)
                    assert len(a) == FRAMES and [t for t, _ in a] == [t for t, _ in b]
                    assert all(np.array_equal(x, y) for (_, x), (_, y) in zip(a, b, strict=True))
        lines = record_lines(tmp_path / "rec.jsonl")
        assert sorted(line["output"] for line in lines) == sorted(str(o.path) for i in job.items for o in i.outputs)
        assert all(line["sha256"] == sha256(Path(str(line["output"]))) for line in lines)
        assert {line["frames"] for line in lines} == {1, FRAMES}
        assert not list((tmp_path / "out").rglob(".*part*"))
    finally:
        for process in processes:
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGTERM)
        for process in processes:
            try:
                process.wait(timeout=15)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait()


@pytest.mark.parametrize(
    ("argv", "starts"),
    [
        (["batch", "in", "--table", "t.npz", "-o", "{stem}_{name}.jpg"], True),
        (["batch", "--help"], False),
        (["batch", "in", "--scheduler", "tcp://host:8786"], False),
        (["batch", "in", "--scheduler=tcp://host:8786"], False),
        (["video", "t.npz", "in.mp4"], False),
        ([], False),
    ],
)
def test_the_command_line_starts_the_fork_server_only_for_a_local_batch(
    argv: list[str], starts: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    from panomap.batch import forkserver

    started: list[bool] = []
    monkeypatch.setattr(forkserver, "start_fork_server", lambda: started.append(True))
    monkeypatch.delenv(forkserver.SCHEDULER_VARIABLE, raising=False)
    forkserver.start_for_command(argv)
    assert bool(started) == starts
    if starts:  # a scheduler in the environment: the workers are not ours
        started.clear()
        monkeypatch.setenv(forkserver.SCHEDULER_VARIABLE, "tcp://host:8786")
        forkserver.start_for_command(argv)
        assert not started


def test_video_tasks_share_the_cores_only_on_a_local_cluster_of_several_workers(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """One codec thread per worker where the local workers fill the machine; FFmpeg's choice on one worker or
    on someone else's cluster (whose workers' cores this process cannot know)."""
    monkeypatch.setattr(os, "cpu_count", lambda: 8)
    assert codec_threads(None, 8) == 1
    assert codec_threads(None, 2) == 4
    assert codec_threads(None, 1) is None
    assert codec_threads("tcp://127.0.0.1:8786", 8) is None
    monkeypatch.setattr(os, "cpu_count", lambda: None)
    assert codec_threads(None, 2) == 1


def test_a_local_cluster_starts_quietly_where_dasks_default_port_is_taken() -> None:
    """The local cluster's HTTP server takes a free port: on Dask's default, 8787, held by another Dask (a second
    batch, a notebook's cluster), it printed a three-line warning from distributed and left a socket open (an
    error under this suite's warnings, where two runs at once failed a documented batch command)."""
    import socket

    with socket.socket() as holder:
        holder.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            holder.bind(("0.0.0.0", 8787))
            holder.listen()
        except OSError:
            pass  # held by someone else already: the case itself
        with connect(None, workers=1) as client:
            assert client.submit(sum, [1, 2]).result() == 3
            assert not client.scheduler_info()["address"].endswith(":8787")
