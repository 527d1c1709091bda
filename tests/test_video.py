"""``panomap video`` and :mod:`panomap.video`: frames, timestamps, audio, damage, interruption, memory.

The clips are made here with PyAV: a simulated equidistant fisheye looking at
the bundled room, the scene turning 3 deg per frame (so that every frame differs
and frame order shows), 25 fps, with a 440 Hz tone as audio.
"""

from __future__ import annotations

import contextlib
import fcntl
import http.server
import json
import math
import os
import pty
import select
import signal
import struct
import subprocess
import sys
import termios
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from functools import partial
from pathlib import Path

import av
import cv2
import numpy as np
import pytest

from panomap.io.images import read_image
from panomap.remap import Remapper
from panomap.simulate import load_room, render, standard_cameras
from panomap.table.file import load_table, save_table
from panomap.video.frames import REMAP_THREADS, FrameRemapper, _chroma_map
from panomap.video.output import EncoderSettings
from panomap.video.source import Selection
from panomap.video.unwarp import ViewOutput, unwarp_video
from panomap.views import GenericPanorama, PerspectiveView, build_map

from helpers import assert_one_line_error, learn_table, run, spread_landmarks

SIZE = (320, 320)
RATE = 25
FRAMES = 40
CAMERA = standard_cameras(SIZE, centre=(160.3, 159.6), s=-1, phi0=0.4)["equidistant"]
PANORAMA = "panorama:size=480x120"
PERSPECTIVE = "perspective:yaw=30,pitch=-35,fov=90,size=160x120"
LOSSLESS_BGR = ["--codec", "ffv1", "--pix-fmt", "bgr0"]


def write_clip(
    path: Path, frames: int, audio: bool = True, container_format: str | None = None, audio_codec: str = "aac"
) -> None:
    """``frames`` frames of the turning room (yuv420p H.264), and a tone (``audio_codec``: aac or pcm_s16le)
    if ``audio``."""
    omni = OMNI
    with av.open(str(path), "w", format=container_format) as container:
        video = container.add_stream("libx264", rate=RATE)
        video.width, video.height = SIZE
        video.pix_fmt = "yuv420p"
        video.options = {"preset": "ultrafast", "crf": "16"}
        tone = container.add_stream(audio_codec, rate=48000) if audio else None
        for index in range(frames):
            turn = cv2.getRotationMatrix2D(CAMERA.centre, 3.0 * index, 1.0)
            frame = av.VideoFrame.from_ndarray(cv2.warpAffine(omni, turn, SIZE), format="bgr24")
            frame.pts = index
            for packet in video.encode(frame):
                container.mux(packet)
        for packet in video.encode(None):
            container.mux(packet)
        if tone is not None:
            samples = 48000 * frames // RATE
            for start in range(0, samples, 1024):
                wave = 0.2 * np.sin(2 * np.pi * 440 * np.arange(start, start + 1024) / 48000)
                if audio_codec == "pcm_s16le":
                    samples_s16 = np.rint(wave * 32767).astype(np.int16)[None]
                    chunk = av.AudioFrame.from_ndarray(samples_s16, format="s16", layout="mono")
                else:
                    chunk = av.AudioFrame.from_ndarray(wave.astype(np.float32)[None], format="fltp", layout="mono")
                chunk.sample_rate, chunk.pts = 48000, start
                for packet in tone.encode(chunk):
                    container.mux(packet)
            for packet in tone.encode(None):
                container.mux(packet)


def decoded(path: Path, fmt: str = "bgr24") -> list[tuple[float, np.ndarray]]:
    """(time in s, frame as ndarray in ``fmt``) of every frame of ``path``'s video."""
    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        return [(float(f.pts * stream.time_base), f.to_ndarray(format=fmt)) for f in container.decode(stream)]


def luma_planes(path: Path) -> list[np.ndarray]:
    """The Y plane of every frame of ``path`` (yuv420p video), as decoded, without conversion."""
    with av.open(str(path)) as container:
        frames = [f.to_ndarray(format="yuv420p") for f in container.decode(video=0)]
    return [frame[: frame.shape[0] * 2 // 3] for frame in frames]


def audio_packets(path: Path) -> list[float]:
    with av.open(str(path)) as container:
        if not container.streams.audio:
            return []
        stream = container.streams.audio[0]
        return [float(p.pts * stream.time_base) for p in container.demux(stream) if p.pts is not None]


room = load_room()
OMNI = render(room, CAMERA, supersample=1)
POSITION = tuple(room.camera)


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder with the camera's table (cam.npz) and a clip (clip.mp4, 40 frames, audio)."""
    folder = tmp_path_factory.mktemp("video")
    landmarks = spread_landmarks(CAMERA, POSITION, 20, np.random.default_rng(3))
    table, _ = learn_table(CAMERA, POSITION, landmarks, SIZE)
    save_table(table, folder / "cam.npz")
    write_clip(folder / "clip.mp4", FRAMES)
    return folder


def leftovers(folder: Path) -> list[str]:
    """Temporary files a run left behind."""
    return sorted(p.name for p in folder.iterdir() if ".part" in p.name)


# ----------------------------------------------------------------------------- frames, timestamps, audio


@pytest.mark.parametrize(("sub_x", "sub_y"), [(1, 1), (1, 0), (0, 0)])
def test_chroma_map_is_the_block_mean_in_chroma_plane_coordinates(sub_x: int, sub_y: int) -> None:
    """Odd sizes repeat the last row and column; a NaN anywhere in a block makes its entry NaN."""
    rng = np.random.default_rng(3)
    map_uv = rng.uniform(0, 500, (7, 9, 2)).astype(np.float32)
    map_uv[2, 3, 0] = np.nan
    sx, sy = 1 << sub_x, 1 << sub_y
    padded = np.pad(map_uv.astype(np.float64), ((0, -7 % sy), (0, -9 % sx), (0, 0)), mode="edge")
    mean = padded.reshape(padded.shape[0] // sy, sy, padded.shape[1] // sx, sx, 2).mean(axis=(1, 3))
    expected = (mean + 0.5) / np.array([sx, sy]) - 0.5
    chroma = _chroma_map(map_uv, sub_x, sub_y)
    assert chroma.dtype == np.float32 and chroma.shape == expected.shape
    np.testing.assert_allclose(chroma, expected, atol=1e-4)
    assert np.isnan(chroma[2 // sy, 3 // sx, 0]) and np.isfinite(chroma[2 // sy, 3 // sx, 1])
    # Bit for bit the float32 steps its docstring states (the seams' chroma weights are built on them): each block
    # summed from its first entry in row order, times 1 / (s sx sy), plus 0.5 / s - 0.5, per axis.
    edge = np.pad(map_uv, ((0, -7 % sy), (0, -9 % sx), (0, 0)), mode="edge")
    sums = edge[::sy, ::sx].copy()
    for dy, dx in [(dy, dx) for dy in range(sy) for dx in range(sx)][1:]:
        sums += edge[dy::sy, dx::sx]
    scale = np.array([1 / (sx * sx * sy), 1 / (sy * sx * sy)], dtype=np.float32)
    np.testing.assert_array_equal(chroma, sums * scale + np.array([0.5 / sx - 0.5, 0.5 / sy - 0.5], np.float32))


def test_every_frame_and_timestamp_is_kept_and_audio_is_copied_into_each_output(work: Path) -> None:
    out = work / "keep"
    out.mkdir()
    result = run(
        "video",
        work / "cam.npz",
        work / "clip.mp4",
        "-o",
        out / "{name}.mp4",
        "--view",
        PANORAMA,
        "--view",
        PERSPECTIVE + ",name=door",
    )
    assert result.exit_code == 0, result.output + result.stderr
    assert "unwarped 40 frames" in result.output and "audio copied" in result.output
    source_times = [t for t, _ in decoded(work / "clip.mp4")]
    source_audio = audio_packets(work / "clip.mp4")
    for name, size in (("panorama", (480, 120)), ("door", (160, 120))):
        frames = decoded(out / f"{name}.mp4")
        assert [t for t, _ in frames] == pytest.approx(source_times, abs=1e-6)
        assert frames[0][1].shape == (size[1], size[0], 3)
        with av.open(str(out / f"{name}.mp4")) as container:
            assert container.streams.video[0].average_rate == RATE
        assert audio_packets(out / f"{name}.mp4") == pytest.approx(source_audio, abs=1e-6)
    assert leftovers(out) == []


def test_without_audio_when_asked_or_when_the_input_has_none(work: Path, tmp_path: Path) -> None:
    result = run(
        "video", work / "cam.npz", work / "clip.mp4", "-o", tmp_path / "a.mp4", "--view", PANORAMA, "--no-audio"
    )
    assert result.exit_code == 0, result.stderr
    assert audio_packets(tmp_path / "a.mp4") == [] and "audio copied" not in result.output
    write_clip(tmp_path / "silent.mp4", 5, audio=False)
    result = run("video", work / "cam.npz", tmp_path / "silent.mp4", "-o", tmp_path / "b.mp4", "--view", PANORAMA)
    assert result.exit_code == 0, result.stderr
    assert len(decoded(tmp_path / "b.mp4")) == 5 and audio_packets(tmp_path / "b.mp4") == []


def test_audio_mpeg_ts_cannot_carry_is_refused_before_any_work(work: Path, tmp_path: Path) -> None:
    """PCM audio into .ts was written as a private data stream that no player plays, silently."""
    write_clip(tmp_path / "pcm.mkv", 5, audio_codec="pcm_s16le")
    result = run("video", work / "cam.npz", tmp_path / "pcm.mkv", "-o", tmp_path / "out.ts", "--view", PANORAMA)
    assert_one_line_error(result, "out.ts: MPEG-TS cannot carry the input's pcm_s16le audio", "--no-audio")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pcm.mkv"]  # nothing written
    result = run("video", work / "cam.npz", tmp_path / "pcm.mkv", "-o", tmp_path / "out.mkv", "--view", PANORAMA)
    assert result.exit_code == 0, result.stderr
    with av.open(str(tmp_path / "out.mkv")) as container:
        assert container.streams.audio[0].codec_context.name == "pcm_s16le"
    result = run(
        "video", work / "cam.npz", tmp_path / "pcm.mkv", "-o", tmp_path / "quiet.ts", "--view", PANORAMA, "--no-audio"
    )
    assert result.exit_code == 0, result.stderr
    assert len(decoded(tmp_path / "quiet.ts")) == 5 and audio_packets(tmp_path / "quiet.ts") == []
    # AAC goes into .ts as ever.
    result = run("video", work / "cam.npz", work / "clip.mp4", "-o", tmp_path / "aac.ts", "--view", PANORAMA)
    assert result.exit_code == 0, result.stderr
    with av.open(str(tmp_path / "aac.ts")) as container:
        assert container.streams.audio[0].codec_context.name == "aac"


def test_output_frames_equal_the_still_image_view_of_the_same_decoded_frame(work: Path, tmp_path: Path) -> None:
    """Lossless BGR output: each frame equals, bit for bit, ``panomap panorama`` of that frame as a PNG."""
    result = run(
        "video",
        work / "cam.npz",
        work / "clip.mp4",
        "-o",
        tmp_path / "v.mkv",
        "--view",
        PANORAMA,
        *LOSSLESS_BGR,
    )
    assert result.exit_code == 0, result.stderr
    inputs, outputs = decoded(work / "clip.mp4"), decoded(tmp_path / "v.mkv")
    assert len(outputs) == FRAMES
    for index in (0, 17, FRAMES - 1):
        cv2.imwrite(str(tmp_path / "frame.png"), inputs[index][1])
        still = run(
            "panorama", work / "cam.npz", tmp_path / "frame.png", "-o", tmp_path / "still.png", "--size", "480x120"
        )
        assert still.exit_code == 0, still.stderr
        np.testing.assert_array_equal(outputs[index][1], read_image(tmp_path / "still.png"))
    # Consecutive frames differ (the scene turns), so the equality above also pins the order.
    assert np.abs(outputs[1][1].astype(int) - outputs[0][1]).mean() > 5


def test_fixed_point_maps_when_asked(work: Path, tmp_path: Path) -> None:
    """--fixed-point: each frame equals the still view made with OpenCV's fixed-point maps, not the float one."""
    result = run(
        "video",
        work / "cam.npz",
        work / "clip.mp4",
        "-o",
        tmp_path / "f.mkv",
        "--view",
        PANORAMA,
        "--fixed-point",
        "--duration",
        "0.2",
        *LOSSLESS_BGR,
    )
    assert result.exit_code == 0, result.stderr
    table = load_table(work / "cam.npz")
    fixed = GenericPanorama((480, 120)).remapper(table, fixed_point=True)
    exact = GenericPanorama((480, 120)).remapper(table)
    source, out = decoded(work / "clip.mp4")[3][1], decoded(tmp_path / "f.mkv")[3][1]
    np.testing.assert_array_equal(out, fixed(source))
    assert np.any(out != exact(source))  # 1/32 px rounding shows somewhere


def test_yuv_planes_are_remapped_without_rgb_and_match_the_still_view(work: Path, tmp_path: Path) -> None:
    """yuv420p in and out: the luma plane is exactly the view's remap of the input's luma plane;
    in colour the frame stays within chroma-subsampling tolerance of the still view."""
    table = load_table(work / "cam.npz")
    view = PerspectiveView(math.radians(30), math.radians(-35), 0.0, math.radians(90), (160, 120))
    report = unwarp_video(
        table,
        str(work / "clip.mp4"),
        [ViewOutput(view, tmp_path / "y.mkv")],
        encoder=EncoderSettings("ffv1", "yuv420p"),
    )
    assert report.frames_written == FRAMES
    # The video's map was this table's first: the exact one (later maps read the direction lookup).
    map_uv = build_map(table, view, exact=True)
    luma = Remapper(map_uv, SIZE, "linear", 16.0, fixed_point=False)
    still = view.remapper(table, fixed_point=False)
    inputs_y, outputs_y = luma_planes(work / "clip.mp4"), luma_planes(tmp_path / "y.mkv")
    inputs, outputs = decoded(work / "clip.mp4"), decoded(tmp_path / "y.mkv")
    for index in (0, 21):
        np.testing.assert_array_equal(outputs_y[index], luma(inputs_y[index]))
        difference = np.abs(outputs[index][1].astype(int) - still(inputs[index][1]))
        valid = np.all(np.isfinite(map_uv), axis=2)
        # Colour differs from the RGB path only by where chroma is interpolated (at half resolution):
        # a few levels on average, more at sharp colour edges.
        assert difference[valid].mean() < 3.0
        assert np.percentile(difference[valid], 90) < 8


def test_frame_remapper_fills_planes_outside_the_view_with_black(work: Path) -> None:
    table = load_table(work / "cam.npz")
    map_uv = build_map(table, GenericPanorama((480, 120)))
    map_uv[:10] = np.nan  # no source in the top rows
    frame = av.VideoFrame.from_ndarray(np.full((SIZE[1], SIZE[0], 3), 200, np.uint8), format="bgr24")
    out = FrameRemapper(map_uv, SIZE, "yuv420p")(frame.reformat(format="yuv420p"))
    planes = [np.frombuffer(p, np.uint8).reshape(p.height, p.line_size)[:, : p.width] for p in out.planes]
    assert np.all(planes[0][:10] == 16) and np.all(planes[1][:5] == 128) and np.all(planes[2][:5] == 128)
    assert np.all(np.abs(planes[0][20:].astype(int) - planes[0][20, 0]) <= 1)  # the grey input, remapped


def test_start_duration_and_every_select_frames_and_shift_timestamps(work: Path, tmp_path: Path) -> None:
    result = run(
        "video",
        work / "cam.npz",
        work / "clip.mp4",
        "-o",
        tmp_path / "s.mkv",
        "--view",
        PANORAMA,
        "--start",
        "0.4",
        "--duration",
        "0.8",
        "--every",
        "3",
        *LOSSLESS_BGR,
    )
    assert result.exit_code == 0, result.stderr
    inputs = decoded(work / "clip.mp4")
    chosen = [frame for t, frame in inputs if 0.4 - 1e-9 <= t < 1.2 - 1e-9][::3]  # frames 10..29, every 3rd
    outputs = decoded(tmp_path / "s.mkv")
    assert [t for t, _ in outputs] == pytest.approx([3 * k / RATE for k in range(len(chosen))], abs=1e-3)
    still = GenericPanorama((480, 120)).remapper(load_table(work / "cam.npz"), fixed_point=False)
    for (_, out), source in zip(outputs, chosen, strict=True):
        np.testing.assert_array_equal(out, still(source))
    audio = audio_packets(tmp_path / "s.mkv")
    assert audio and min(audio) > -0.05 and max(audio) < 0.8  # the tone's 0.4..1.2 s, shifted to start at 0


def test_views_file_in_json_and_yaml(work: Path, tmp_path: Path) -> None:
    (tmp_path / "views.json").write_text('{"wide": {"kind": "panorama", "size": [480, 120]}}')
    (tmp_path / "views.yaml").write_text(
        "door:\n  kind: perspective\n  yaw: 30\n  pitch: -35\n  fov: 90\n  size: 160x120\n"
    )
    for name in ("views.json", "views.yaml"):
        result = run(
            "video",
            work / "cam.npz",
            work / "clip.mp4",
            "-o",
            tmp_path / "{name}.mkv",
            "--views",
            tmp_path / name,
            "--duration",
            "0.2",
            *LOSSLESS_BGR,
        )
        assert result.exit_code == 0, result.stderr
    # Every key reaches the view (a yaw, pitch or fov ignored or of the wrong sign fails): the frames
    # are those of the views the files describe, to the bit.
    source = decoded(work / "clip.mp4")[:5]
    table = load_table(work / "cam.npz")
    door = PerspectiveView(math.radians(30), math.radians(-35), 0.0, math.radians(90), (160, 120))
    for path, view in [(tmp_path / "wide.mkv", GenericPanorama((480, 120))), (tmp_path / "door.mkv", door)]:
        frames = decoded(path)
        assert len(frames) == 5
        still = view.remapper(table, fixed_point=False)
        for (_, got), (_, frame) in zip(frames, source, strict=True):
            np.testing.assert_array_equal(got, still(frame))


# ----------------------------------------------------------------------------- damage and bad input


def test_a_truncated_file_still_yields_the_frames_before_the_damage(work: Path, tmp_path: Path) -> None:
    write_clip(tmp_path / "whole.ts", FRAMES, container_format="mpegts")
    data = (tmp_path / "whole.ts").read_bytes()
    (tmp_path / "cut.ts").write_bytes(data[: len(data) * 6 // 10])
    readable = decoded(tmp_path / "cut.ts")  # what a plain decoder gets out of the damaged file
    assert 10 < len(readable) < FRAMES
    result = run(
        "video", work / "cam.npz", tmp_path / "cut.ts", "-o", tmp_path / "cut.mkv", "--view", PANORAMA, *LOSSLESS_BGR
    )
    assert result.exit_code == 0, result.stderr
    outputs = decoded(tmp_path / "cut.mkv")
    assert len(outputs) >= len(readable) - 1
    still = GenericPanorama((480, 120)).remapper(load_table(work / "cam.npz"), fixed_point=False)
    np.testing.assert_array_equal(outputs[5][1], still(readable[5][1]))


def garbled_mjpeg_clip(path: Path, garbled: set[int]) -> None:
    """FRAMES frames of the turning room as Motion JPEG (Matroska), the packets of the frames in
    ``garbled`` replaced by random bytes of the same length: the decoder refuses exactly those.
    (H.264's decoder hides such damage: it conceals or drops frames and reports nothing.)"""
    rng = np.random.default_rng(7)
    with av.open(str(path), "w") as container:
        stream = container.add_stream("mjpeg", rate=RATE)
        stream.width, stream.height = SIZE
        stream.pix_fmt = "yuvj420p"
        for index in range(FRAMES):
            turn = cv2.getRotationMatrix2D(CAMERA.centre, 3.0 * index, 1.0)
            frame = av.VideoFrame.from_ndarray(cv2.warpAffine(OMNI, turn, SIZE), format="bgr24")
            frame.pts = index
            for packet in stream.encode(frame):
                if index in garbled:
                    noise = av.Packet(rng.integers(0, 256, packet.size, dtype=np.uint8).tobytes())
                    noise.pts, noise.dts, noise.time_base = packet.pts, packet.dts, packet.time_base
                    noise.stream = stream
                    packet = noise
                container.mux(packet)
        for packet in stream.encode(None):
            container.mux(packet)


def test_corrupt_frames_are_reported_and_skipped(work: Path, tmp_path: Path) -> None:
    write_clip(tmp_path / "whole.ts", FRAMES, container_format="mpegts")
    data = bytearray((tmp_path / "whole.ts").read_bytes())
    rng = np.random.default_rng(7)
    middle = len(data) // 2
    for offset in rng.integers(middle, middle + 20000, 400):
        data[offset] ^= 0xFF
    (tmp_path / "bad.ts").write_bytes(bytes(data))
    # Two frames the decoder refuses (frames 10 and 11: at 0.400 and 0.440 s), each a line.
    garbled_mjpeg_clip(tmp_path / "bad.mkv", {10, 11})
    warnings: list[str] = []
    report = unwarp_video(
        load_table(work / "cam.npz"),
        str(tmp_path / "bad.mkv"),
        [ViewOutput(GenericPanorama((480, 120)), tmp_path / "bad.mp4")],
        warn=warnings.append,
    )
    assert (report.frames_written, report.frames_skipped, report.problems) == (FRAMES - 2, 2, [])
    assert len(decoded(tmp_path / "bad.mp4")) == FRAMES - 2
    assert [line.split(" (")[0] for line in warnings] == [
        f"{tmp_path / 'bad.mkv'}: skipped a frame that does not decode at {when} s" for when in ("0.400", "0.440")
    ]
    result = run("video", work / "cam.npz", tmp_path / "bad.mkv", "-o", tmp_path / "bad2.mp4", "--view", PANORAMA)
    assert result.exit_code == 0 and "Traceback" not in result.stderr
    # The command prints the same lines on stderr (no terminal: no bar), and counts the skips.
    assert result.stderr.splitlines() == warnings
    assert f"unwarped {FRAMES - 2} frames, 2 skipped in " in result.output
    # H.264 with flipped bits in the middle: the decoder conceals the damage; every frame comes out.
    result = run("video", work / "cam.npz", tmp_path / "bad.ts", "-o", tmp_path / "bad3.mp4", "--view", PANORAMA)
    assert result.exit_code == 0 and "Traceback" not in result.stderr
    assert len(decoded(tmp_path / "bad3.mp4")) == FRAMES


def test_bad_input_gets_one_line_before_any_work(work: Path, tmp_path: Path) -> None:
    table, clip = work / "cam.npz", work / "clip.mp4"
    (tmp_path / "text.mp4").write_text("not a video")
    cases = [
        ((table, tmp_path / "none.mp4", "-o", tmp_path / "o.mp4", "--view", PANORAMA), ("none.mp4", "no such file")),
        ((table, tmp_path / "text.mp4", "-o", tmp_path / "o.mp4", "--view", PANORAMA), ("text.mp4", "cannot open")),
        ((table, clip, "-o", tmp_path / "no" / "o.mp4", "--view", PANORAMA), ("o.mp4", "folder does not exist")),
        ((table, clip, "-o", tmp_path / "o.xyz", "--view", PANORAMA), ("o.xyz", "unknown video file type")),
        ((table, clip, "-o", tmp_path / "o.mp4", "--view", "panorama:size=481x120"), ("size such as size=480x120",)),
    ]
    # Usage errors (exit 2): a --view SPEC, an encoder or its options, a selection the command line gets wrong.
    usages = [
        (("--view", "perspective:yaw=3,fov=200"), ("'--view'", "field of view must be more than 0 and less than 180")),
        (("--view", "sphere:size=2x2"), ("unknown view kind 'sphere'",)),
        (("--view", "panorama:fov=3"), ("no key fov",)),
        (("--view", "perspective:yaw=nan,pitch=0,fov=90,size=160x120"), ("not a finite number",)),
        (("--view", PANORAMA, "--codec", "nope"), ("unknown video encoder",)),
        (("--view", PANORAMA, "--pix-fmt", "rgb24"), ("cannot take rgb24",)),
        (
            ("--view", PANORAMA, "--encoder-option", "foo=bar"),
            ("the video encoder libx264 has no option 'foo'", "ffmpeg -h encoder=libx264"),
        ),
        (("--view", PANORAMA, "--duration", "0"), ("the duration must be more than 0 s, not 0",)),
        (
            ("--view", PANORAMA, "--encoder-option", "crf=abc"),
            ("the video encoder libx264 refused its options (preset=veryfast, crf=abc)", 'parse "crf" option'),
        ),
    ]
    for args, fragments, code in [
        *((args, fragments, 1) for args, fragments in cases),
        *(((table, clip, "-o", tmp_path / "o.mp4", *args), fragments, 2) for args, fragments in usages),
    ]:
        result = run("video", *args)
        assert_one_line_error(result, *fragments, exit_code=code)
        assert "audio" not in result.stderr  # (the clip has audio: no error may blame it wrongly)
    # A table of another camera size.
    write_clip(tmp_path / "small.mp4", 2, audio=False)
    with av.open(str(tmp_path / "other.mp4"), "w") as container:
        stream = container.add_stream("libx264", rate=RATE)
        stream.width, stream.height, stream.pix_fmt = 160, 160, "yuv420p"
        for packet in stream.encode(av.VideoFrame.from_ndarray(np.zeros((160, 160, 3), np.uint8), format="bgr24")):
            container.mux(packet)
        for packet in stream.encode(None):
            container.mux(packet)
    assert_one_line_error(
        run("video", table, tmp_path / "other.mp4", "-o", tmp_path / "o.mp4", "--view", PANORAMA),
        "other.mp4",
        "160 x 160",
        "320 x 320",
        exit_code=1,
    )
    usage = run("video", table, clip, "-o", tmp_path / "o.mp4", "--view", PANORAMA, "--view", PERSPECTIVE)
    assert usage.exit_code == 2 and "{name}" in usage.stderr
    assert not (tmp_path / "o.mp4").exists() and leftovers(tmp_path) == []


# ----------------------------------------------------------------------------- interruption, live input, progress


def test_a_stop_mid_run_finishes_every_output_playable(work: Path, tmp_path: Path) -> None:
    stop = threading.Event()

    def progress(done: int, expected: int | None) -> None:
        assert expected == FRAMES
        if done == 12:
            stop.set()

    outputs = [
        ViewOutput(GenericPanorama((480, 120)), tmp_path / "a.mp4"),
        ViewOutput(PerspectiveView(0.0, -0.6, 0.0, 1.5, (160, 120)), tmp_path / "b.mp4"),
    ]
    report = unwarp_video(load_table(work / "cam.npz"), str(work / "clip.mp4"), outputs, stop=stop, progress=progress)
    # The main loop looks at ``stop`` before each frame: no frame after the one that set it.
    assert report.interrupted and report.frames_written == 12
    for item in outputs:
        assert len(decoded(item.path)) == report.frames_written
    assert leftovers(tmp_path) == []


# A system call number of read(2), by machine, to see from /proc that a process waits on a pipe.
READ_SYSCALL = {"x86_64": 0, "aarch64": 63}.get(os.uname().machine)


@dataclass
class LiveRun:
    """``panomap video`` reading a clip through a FIFO given as a file:// URL: a live input, with no
    length, whose data this test controls. The clip is written whole, then the FIFO is held open (the
    input neither ends nor moves on) until ``release`` is set. The progress bar goes to a terminal."""

    process: subprocess.Popen[str]
    terminal: int
    fifo: Path
    release: threading.Event = field(default_factory=threading.Event)
    seen: bytes = b""

    def wait_for(self, text: bytes, timeout: float = 60.0) -> None:
        """Read the terminal until ``text`` shows (the test fails after ``timeout`` s)."""
        deadline = time.monotonic() + timeout
        while text not in self.seen:
            left = deadline - time.monotonic()
            assert left > 0 and self.process.poll() is None, self.seen.decode(errors="replace")
            ready, _, _ = select.select([self.terminal], [], [], min(left, 1.0))
            if ready:
                self.seen += os.read(self.terminal, 4096)

    def saw(self, text: bytes, within: float) -> bool:
        """Whether ``text`` shows on the terminal within ``within`` s (or has shown)."""
        deadline = time.monotonic() + within
        while text not in self.seen and (left := deadline - time.monotonic()) > 0:
            with contextlib.suppress(OSError):  # (EIO once the process has exited)
                if select.select([self.terminal], [], [], left)[0]:
                    self.seen += os.read(self.terminal, 4096)
        return text in self.seen

    def waits_on_its_input(self) -> bool:
        """Whether one of the process's threads is blocked reading the FIFO (from /proc)."""
        fds = set()
        for fd in os.listdir(f"/proc/{self.process.pid}/fd"):
            with contextlib.suppress(OSError):
                if os.readlink(f"/proc/{self.process.pid}/fd/{fd}") == str(self.fifo):
                    fds.add(int(fd))
        for task in os.listdir(f"/proc/{self.process.pid}/task"):
            with contextlib.suppress(OSError), open(f"/proc/{self.process.pid}/task/{task}/syscall") as file:
                fields = file.read().split()
                if fields[0] == str(READ_SYSCALL) and int(fields[1], 16) in fds:
                    return True
        return False

    def finish(self, timeout: float = 60.0) -> tuple[int, str, str]:
        """Release the input; the exit code, stdout and everything the terminal showed."""
        self.release.set()
        out, _ = self.process.communicate(timeout=timeout)
        with contextlib.suppress(OSError):
            while select.select([self.terminal], [], [], 0)[0]:
                chunk = os.read(self.terminal, 4096)
                if not chunk:
                    break
                self.seen += chunk
        os.close(self.terminal)
        return self.process.returncode, out, self.seen.decode(errors="replace")


def start_live_run(work: Path, tmp_path: Path, frames: int) -> LiveRun:
    write_clip(tmp_path / "source.ts", frames, audio=False, container_format="mpegts")
    data = (tmp_path / "source.ts").read_bytes()
    fifo = tmp_path / "live.ts"
    os.mkfifo(fifo)
    leader, follower = pty.openpty()
    fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # (tqdm draws nothing in 0 columns)
    command = [sys.executable, "-m", "panomap", "video", str(work / "cam.npz"), fifo.as_uri()]
    command += ["-o", str(tmp_path / "{name}.mp4"), "--view", PANORAMA, "--view", PERSPECTIVE]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=follower, text=True)
    os.close(follower)
    run = LiveRun(process, leader, fifo)

    def feed() -> None:
        with open(fifo, "wb") as pipe:  # (waits for the process to open its input)
            with contextlib.suppress(BrokenPipeError):
                pipe.write(data)
                pipe.flush()
            run.release.wait(120)

    threading.Thread(target=feed, daemon=True).start()
    return run


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_finishes_cleanly_with_playable_files(work: Path, tmp_path: Path, signum: int) -> None:
    """The signal goes after the first frame is written (the progress bar shows), before the
    input ends (it never does until released): every output holds the same frames, playable."""
    live = start_live_run(work, tmp_path, FRAMES)
    live.wait_for(b"frame [")  # the bar appears with the first frame written
    live.process.send_signal(signum)
    code, out, terminal = live.finish()
    assert code == 0, terminal
    assert "Traceback" not in terminal
    written = int(out.split("stopped by a signal after ")[1].split()[0])
    assert 1 <= written <= FRAMES
    counts = [len(decoded(tmp_path / f"{name}.mp4")) for name in ("panorama", "perspective")]
    assert counts == [written, written]
    assert leftovers(tmp_path) == []


@pytest.mark.skipif(READ_SYSCALL is None, reason="the read system call's number on this machine is not known here")
@pytest.mark.slow
def test_a_second_sigint_aborts_and_leaves_no_output(work: Path, tmp_path: Path) -> None:
    """The first SIGINT asks for a clean finish, which waits for the input's reader; while the
    reader waits on a silent input, a second SIGINT aborts: exit 130, one line, no output."""
    live = start_live_run(work, tmp_path, FRAMES)
    live.wait_for(b"frame [")
    deadline = time.monotonic() + 60
    while not live.waits_on_its_input():  # every byte of the clip read: the reader waits for more
        assert time.monotonic() < deadline and live.process.poll() is None
        time.sleep(0.05)
    # The first SIGINT is handled within 0.1 s (the main thread waits on its queue 0.1 s at a time)
    # and the run then waits for the reader for ever: the next SIGINT, whenever it comes, aborts. One
    # more goes each second until the abort shows, and none after it (a third would kill the process).
    live.process.send_signal(signal.SIGINT)
    while not live.saw(b"interrupted", within=1.0):
        assert time.monotonic() < deadline, live.seen
        live.process.send_signal(signal.SIGINT)
    code, out, terminal = live.finish()
    assert "panomap: error: interrupted" in terminal and "Traceback" not in terminal
    assert "stopped by a signal" not in out
    assert not (tmp_path / "panorama.mp4").exists() and not (tmp_path / "perspective.mp4").exists()
    assert leftovers(tmp_path) == []
    # (Was a segmentation fault, every run: the abort closed the input while the reader waited in
    # FFmpeg's read on it; the input is now closed only once no thread reads it.)
    assert code == 130, terminal


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, format: str, *args: object) -> None:
        pass


@pytest.fixture
def http_server(work: Path) -> Iterator[str]:
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), partial(_QuietHandler, directory=str(work)))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()


def test_a_stream_over_http_is_read_like_a_live_input(work: Path, tmp_path: Path, http_server: str) -> None:
    """An MPEG-TS stream over HTTP (the server is this test's, on the loopback address)."""
    write_clip(work / "live.ts", FRAMES, container_format="mpegts")
    seen: list[int | None] = []
    report = unwarp_video(
        load_table(work / "cam.npz"),
        f"{http_server}/live.ts",
        [ViewOutput(GenericPanorama((480, 120)), tmp_path / "h.mp4")],
        progress=lambda done, expected: seen.append(expected),
    )
    assert report.frames_written == FRAMES and set(seen) == {None}  # a live input has no known length
    # MPEG-TS starts its clock at 1.4 s; MP4 starts at 0: the frames keep their spacing.
    source = np.array([t for t, _ in decoded(work / "live.ts")])
    times = np.array([t for t, _ in decoded(tmp_path / "h.mp4")])
    np.testing.assert_allclose(times - times[0], source - source[0], atol=1e-6)


@pytest.mark.slow
def test_progress_bar_on_a_terminal_only(work: Path, tmp_path: Path) -> None:
    command = [
        sys.executable,
        "-m",
        "panomap",
        "video",
        str(work / "cam.npz"),
        str(work / "clip.mp4"),
        "-o",
        str(tmp_path / "p.mp4"),
        "--view",
        PANORAMA,
    ]
    leader, follower = pty.openpty()
    fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # a 100-column terminal
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=follower)
    os.close(follower)
    chunks = []
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:  # (a read with no end would hang the test: select first)
        if not select.select([leader], [], [], 1.0)[0]:
            continue
        try:
            chunk = os.read(leader, 4096)
        except OSError:  # EIO: the process has exited and the terminal is closed
            break
        if not chunk:
            break
        chunks.append(chunk)
    process.wait(timeout=60)
    assert process.stdout is not None
    process.stdout.close()
    os.close(leader)
    terminal = b"".join(chunks).decode(errors="replace")
    assert f"{FRAMES}/{FRAMES}" in terminal and "frame/s" in terminal
    piped = subprocess.run(command, capture_output=True, text=True, check=True)
    assert piped.stderr == "" and "unwarped 40 frames" in piped.stdout
    quiet = subprocess.run([*command, "-q"], capture_output=True, text=True, check=True)
    assert quiet.stdout == quiet.stderr == ""
    # x265 prints its settings and statistics straight to the stderr descriptor unless told not to (it was
    # a dozen "x265 [info]: ..." lines per output, -q or not).
    x265 = subprocess.run([*command, "--codec", "libx265", "-q"], capture_output=True, text=True, check=True)
    assert x265.stdout == x265.stderr == ""
    with av.open(str(tmp_path / "p.mp4")) as container:
        assert container.streams.video[0].codec_context.name == "hevc"
        assert sum(1 for _ in container.decode(video=0)) == FRAMES


MEMORY_RUN = """
import json, os, sys
from pathlib import Path
from panomap.table.file import load_table
from panomap.video.unwarp import ViewOutput, unwarp_video
from panomap.views import GenericPanorama, PerspectiveView

folder = Path(sys.argv[1])
page = os.sysconf("SC_PAGE_SIZE")
samples = {}

def progress(done, expected):
    if done % 25 == 0:
        with open("/proc/self/statm") as statm:
            samples[done] = int(statm.read().split()[1]) * page / 2**20

outputs = [
    ViewOutput(GenericPanorama((480, 120)), folder / "a.mp4"),
    ViewOutput(PerspectiveView(0.0, -0.6, 0.0, 1.5, (160, 120)), folder / "b.mp4"),
]
report = unwarp_video(load_table(sys.argv[2]), str(folder / "long.mp4"), outputs, progress=progress)
print(json.dumps({"frames": report.frames_written, "samples": samples}))
"""


@pytest.mark.slow
def test_memory_stays_flat_over_a_long_stream(work: Path, tmp_path: Path) -> None:
    """600 frames through two views, in a process of their own (nothing else allocates there):
    resident memory after warm-up grows by less than 0.02 MB per frame, the least-squares slope over
    frames 150..600 (a leak of one decoded frame per frame is 0.15 MB per frame, 90 MB in all), and
    by less than 8 MB in all. Measured: 0.0024 MB per frame, 1.1 MB."""
    write_clip(tmp_path / "long.mp4", 600, audio=True)
    done = subprocess.run(
        [sys.executable, "-c", MEMORY_RUN, str(tmp_path), str(work / "cam.npz")],
        capture_output=True,
        text=True,
        timeout=240,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    assert result["frames"] == 600
    samples = {int(k): v for k, v in result["samples"].items() if int(k) >= 150}
    frames, rss = np.array(list(samples)), np.array(list(samples.values()))
    slope = np.polyfit(frames, rss, 1)[0]
    assert slope < 0.02, samples
    assert rss.max() - rss[0] < 8.0, samples


def x264_settings(path: Path) -> tuple[str, str, dict[str, str]]:
    """The codec, pixel format and the settings libx264 wrote into its first packet (an SEI
    message: "x264 - core ... options: cabac=1 ... crf=20.0 ...") of ``path``'s video."""
    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        packet = next(p for p in container.demux(stream) if p.size)
        text = bytes(packet).split(b"options: ", 1)[1].split(b"\0", 1)[0].decode()
        return stream.codec_context.name, stream.codec_context.pix_fmt, dict(o.split("=", 1) for o in text.split())


def test_encoder_defaults_and_options_through_the_command(work: Path, tmp_path: Path) -> None:
    """The README's defaults (H.264 by libx264, crf 20, preset veryfast, yuv420p) and what --crf,
    --preset and --encoder-option change, read back from the files."""
    base = ["video", work / "cam.npz", work / "clip.mp4", "--view", PANORAMA, "-q"]
    assert run(*base, "-o", tmp_path / "default.mp4").exit_code == 0
    result = run(*base, "-o", tmp_path / "set.mp4", "--crf", 35, "--preset", "slow", "--encoder-option", "g=7")
    assert result.exit_code == 0, result.stderr
    codec, pix_fmt, default = x264_settings(tmp_path / "default.mp4")
    assert (codec, pix_fmt) == ("h264", "yuv420p")
    # veryfast: subpixel refinement 2; slow: 8 (x264's presets).
    assert (default["crf"], default["subme"], default["keyint"]) == ("20.0", "2", "250")
    _, _, chosen = x264_settings(tmp_path / "set.mp4")
    assert (chosen["crf"], chosen["subme"], chosen["keyint"]) == ("35.0", "8", "7")
    # A higher crf is a coarser quantiser: a smaller file (measured 70 kB against 29 kB).
    assert (tmp_path / "set.mp4").stat().st_size < 0.7 * (tmp_path / "default.mp4").stat().st_size
    assert len(decoded(tmp_path / "set.mp4")) == len(decoded(tmp_path / "default.mp4")) == FRAMES


def test_opencv_thread_count_is_restored(work: Path, tmp_path: Path) -> None:
    """unwarp_video runs OpenCV on REMAP_THREADS threads (process-wide) and gives the caller's
    setting back after the run, and after a run that fails midway."""
    before = cv2.getNumThreads()
    during: list[int] = []

    def progress(done: int, expected: int | None) -> None:
        during.append(cv2.getNumThreads())
        if done == 3:
            raise RuntimeError("the caller's callback fails")

    try:
        cv2.setNumThreads(3)
        assert cv2.getNumThreads() == 3
        table = load_table(work / "cam.npz")
        outputs = [ViewOutput(GenericPanorama((480, 120)), tmp_path / "a.mp4")]
        unwarp_video(
            table, str(work / "clip.mp4"), outputs, progress=lambda done, _: during.append(cv2.getNumThreads())
        )
        assert during == [REMAP_THREADS] * FRAMES
        assert cv2.getNumThreads() == 3
        during.clear()
        with pytest.raises(RuntimeError, match="callback fails"):
            unwarp_video(
                table, str(work / "clip.mp4"), [ViewOutput(outputs[0].view, tmp_path / "b.mp4")], progress=progress
            )
        assert during == [REMAP_THREADS] * 3
        assert cv2.getNumThreads() == 3
        assert not (tmp_path / "b.mp4").exists() and leftovers(tmp_path) == []
    finally:
        cv2.setNumThreads(before)


def test_an_encoder_option_it_knows_is_passed_on(work: Path, tmp_path: Path) -> None:
    """A generic option (g: the keyframe interval) and one of x264's own (tune) are taken, not refused."""
    args = ["--encoder-option", "g=5", "--encoder-option", "tune=zerolatency", "--no-audio"]
    result = run("video", work / "cam.npz", work / "clip.mp4", "-o", tmp_path / "a.mp4", "--view", PANORAMA, *args)
    assert result.exit_code == 0, result.stderr
    with av.open(str(tmp_path / "a.mp4")) as container:
        keys = [packet.is_keyframe for packet in container.demux(video=0) if packet.size]
    assert len(keys) == FRAMES and keys[::5] == [True] * (FRAMES // 5)


def test_the_help_points_at_what_it_prints(work: Path) -> None:
    text = " ".join(run("video", "--help").output.split())  # (click wraps the option help)
    assert "see below" not in text
    # What the options point at is printed before them, under the description.
    assert text.index("View SPECs") < text.index("see the View SPECs above")
    assert text.index("A --views file") < text.index("see the --views file above")


def test_selection_start_is_the_old_spelling_of_start_s() -> None:
    """``Selection(start=...)`` and ``.start`` still work, each with a DeprecationWarning naming ``start_s``."""
    with pytest.warns(DeprecationWarning, match="start_s"):
        old = Selection(start=2.5, duration=1.0)
    assert old == Selection(2.5, 1.0) == Selection(start_s=2.5, duration=1.0)
    with pytest.warns(DeprecationWarning, match="start_s"):
        assert old.start == 2.5
    assert replace(old, every=2) == Selection(2.5, 1.0, 2)


def test_selection_and_encoder_settings_refuse_nonsense() -> None:
    from panomap.errors import PanomapError

    for kwargs in ({"start_s": -1.0}, {"duration": 0.0}, {"every": 0}, {"start_s": math.inf}):
        with pytest.raises(PanomapError):
            Selection(**kwargs)  # type: ignore[arg-type]
    assert EncoderSettings().codec_options() == {"preset": "veryfast", "crf": "20"}
    assert EncoderSettings(bitrate=8_000_000).codec_options() == {"preset": "veryfast"}
    assert EncoderSettings("ffv1", "yuv420p", options=(("level", "3"),)).codec_options() == {"level": "3"}


def test_writer_threads_x264_as_ffmpeg_does(tmp_path: Path) -> None:
    """The encoder gets libavcodec's default threading, as ffmpeg's command line: x264 writes frame threads, not
    sliced threads (PyAV's own default, slice threads alone, makes libx264 slice each frame)."""
    from fractions import Fraction

    from panomap.video.output import open_writer

    path = tmp_path / "out.mp4"
    writer = open_writer(path, path, (320, 240), Fraction(25), Fraction(1, 25), EncoderSettings(), None)
    for index in range(3):
        frame = av.VideoFrame.from_ndarray(np.full((240, 320, 3), 40 * index, dtype=np.uint8), format="bgr24")
        frame.pts = index
        for packet in writer.video.encode(frame.reformat(format="yuv420p")):
            writer.container.mux(packet)
    for packet in writer.video.encode(None):
        writer.container.mux(packet)
    writer.close()
    assert writer.error is None
    assert b"sliced_threads=0" in path.read_bytes()


def test_a_text_file_named_like_a_picture_is_not_a_video(work: Path, tmp_path: Path) -> None:
    """FFmpeg opens a text file named .jpg as an image sequence with frames of 0 x 0: that is no video (before:
    "its frames are 0 x 0, the table is for ..."), and nothing is written."""
    (tmp_path / "notes.jpg").write_text("not a picture\n")
    result = run("video", work / "cam.npz", tmp_path / "notes.jpg", "-o", tmp_path / "v.mkv", "--view", PANORAMA)
    assert_one_line_error(result, "notes.jpg: cannot read it as a video (its header gives no frame size")
    assert not (tmp_path / "v.mkv").exists()
