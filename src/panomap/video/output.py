"""Each view's output: an encoder and a container, written under a temporary name and renamed when done."""

from __future__ import annotations

import contextlib
import queue
import threading
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import Any

import av

from .. import inputs
from ..errors import PanomapError
from .encoder_open import open_codec
from .handoff import END, QUEUE_FRAMES, reason


@dataclass(frozen=True)
class EncoderSettings:
    """How each view's video is encoded.

    Parameters
    ----------
    codec : str
        An FFmpeg encoder name (``libx264``, ``libx265``, ``ffv1``, ...).
    pix_fmt : str
        The encoded pixel format (``yuv420p`` plays everywhere).
    crf : int or None
        Constant rate factor for codecs that take one (x264/x265: 0 lossless,
        18 visually lossless, 23 their default); None leaves the codec's.
    preset : str or None
        Speed preset for codecs that take one (x264: ultrafast .. veryslow).
    bitrate : int or None
        Target bit rate (bit/s) instead of a constant quality.
    options : tuple of (key, value)
        Further encoder options, as FFmpeg's ``-KEY VALUE``: the encoder's own
        (``x264-params``, ``tune``) or any encoder's (``g``, ``bf``); a name the
        encoder does not know is refused by :meth:`check`.
    """

    codec: str = "libx264"
    pix_fmt: str = "yuv420p"
    crf: int | None = 20
    preset: str | None = "veryfast"
    bitrate: int | None = None
    options: tuple[tuple[str, str], ...] = ()

    def __post_init__(self) -> None:
        inputs.instance(self.codec, str, "the codec", " (an FFmpeg encoder name, such as 'libx264')")
        inputs.instance(self.pix_fmt, str, "the pixel format", " (such as 'yuv420p')")
        if self.crf is not None and inputs.whole_numbers((self.crf,), 1, "crf")[0] < 0:
            raise PanomapError(f"crf must be 0 or more (0 lossless, 23 x264's default), not {self.crf}")
        if self.bitrate is not None and inputs.whole_numbers((self.bitrate,), 1, "the bit rate (bit/s)")[0] <= 0:
            raise PanomapError(f"the bit rate must be more than 0 bit/s, not {self.bitrate}")

    def codec_options(self) -> dict[str, str]:
        """The options passed to the encoder."""
        takes_crf_preset = self.codec in ("libx264", "libx264rgb", "libx265")
        options: dict[str, str] = {}
        if takes_crf_preset and self.preset is not None:
            options["preset"] = self.preset
        if takes_crf_preset and self.crf is not None and self.bitrate is None:
            options["crf"] = str(self.crf)
        if self.codec == "libx265":
            # x265 prints its settings, statistics and the settings it changed ("Source height < 720p;
            # disabling lookahead-slices") straight to stderr, a dozen lines per output, unless told not to;
            # its errors still show. Given x265-params win (log-level=info brings them back).
            options["x265-params"] = "log-level=error"
        return options | dict(self.options)

    def check(self) -> None:
        """Refuse an unknown encoder, a pixel format it cannot take or an option it does not know, before any work."""
        try:
            codec = av.codec.Codec(self.codec, "w")
        except (av.error.FFmpegError, ValueError):
            raise PanomapError(f"unknown video encoder {self.codec!r} (try libx264)") from None
        if codec.type != "video":
            raise PanomapError(f"{self.codec!r} is not a video encoder")
        formats = [f.name for f in codec.video_formats or ()]
        if formats and self.pix_fmt not in formats:
            raise PanomapError(f"the encoder {self.codec} cannot take {self.pix_fmt} (it takes {', '.join(formats)})")
        supported = av.codec.CodecContext.create(codec).supported_options
        known = {option.name for option in (*supported.generic, *supported.private)}
        unknown = [key for key, _ in self.options if key not in known]
        if unknown:
            raise PanomapError(
                f"the video encoder {self.codec} has no option {', '.join(repr(k) for k in unknown)} "
                f"(--encoder-option; its options: ffmpeg -h encoder={self.codec})"
            )
        refused = probe_refusal(self)  # (a value it refuses: a preset it has not, a crf of text)
        if refused is not None:
            raise PanomapError(f"the video encoder {self.codec} refused its options ({self.described()}): {refused}")

    def described(self) -> str:
        """The options passed to the encoder, as ``key=value, ...`` (for messages)."""
        return ", ".join(f"{key}={value}" for key, value in self.codec_options().items()) or "none"


@dataclass
class Writer:
    """One view's output: its container (under a temporary name), streams and thread."""

    path: Path
    temporary: Path
    container: Any
    video: Any
    audio: Any | None
    inbox: queue.Queue[Any] = field(default_factory=lambda: queue.Queue(QUEUE_FRAMES))
    error: BaseException | None = None
    frames: int = 0
    thread: threading.Thread | None = None
    abandoned: threading.Event = field(default_factory=threading.Event)

    def run(self, stop: threading.Event) -> None:
        try:
            while True:
                item = self.inbox.get()
                if self.abandoned.is_set():
                    return
                if item is END:
                    break
                if isinstance(item, av.Packet):
                    item.stream = self.audio
                    self.container.mux(item)
                    continue
                for packet in self.video.encode(item):
                    self.container.mux(packet)
                self.frames += 1
            for packet in self.video.encode(None):
                self.container.mux(packet)
        except BaseException as exc:  # reported by the caller
            self.error = exc
            stop.set()
            with contextlib.suppress(queue.Empty):
                while True:  # unblock the producer
                    self.inbox.get_nowait()

    def abandon(self) -> None:
        """Make the thread end after the item it is on, without flushing the encoder (an abort: the file is
        discarded); join the thread before :meth:`close`."""
        self.abandoned.set()
        with contextlib.suppress(queue.Full):  # (a full inbox wakes the thread anyway)
            self.inbox.put_nowait(END)

    def close(self) -> None:
        """Finish the container (its index and trailer are written here: a full disk shows now).

        An error is kept in ``error`` (the first one the writer met wins), never
        raised: every writer is closed, then the caller reports.
        """
        try:
            self.container.close()
        except (av.error.FFmpegError, OSError) as exc:
            if self.error is None:
                self.error = exc


def open_writer(
    path: Path,
    temporary: Path,
    size: tuple[int, int],
    rate: Fraction | None,
    time_base: Fraction,
    encoder: EncoderSettings,
    audio_template: Any | None,
) -> Writer:
    try:
        container = av.open(str(temporary), "w", format=container_format(path))
    except (av.error.FFmpegError, OSError, ValueError) as exc:
        raise PanomapError(f"cannot write a video there ({reason(exc)})", path) from None
    try:
        video: Any = container.add_stream(encoder.codec, rate=rate or Fraction(25))
        video.width, video.height = size
        video.pix_fmt = encoder.pix_fmt
        # FFmpeg's own default (and its command line's): frame and slice threads. PyAV sets slice threads alone,
        # which libx264 takes as its sliced threads (one frame at a time, every core waiting on the slowest slice).
        video.codec_context.thread_type = ENCODER_THREAD_TYPE
        video.time_base = time_base
        video.codec_context.time_base = time_base
        if encoder.bitrate is not None:
            video.bit_rate = encoder.bitrate
        video.options = encoder.codec_options()
    except (av.error.FFmpegError, ValueError, TypeError) as exc:
        container.close()
        raise PanomapError(f"cannot encode {encoder.codec} {encoder.pix_fmt} into it: {reason(exc)}", path) from None
    # Opened on its own (start_encoding then skips it), so that a value it refuses is blamed on it.
    refused = open_codec(video.codec_context)
    if refused is not None:
        container.close()
        if probe_refusal(encoder, rate or Fraction(25), time_base) is None:
            raise PanomapError(
                f"the video encoder {encoder.codec} cannot encode frames of {size[0]} x {size[1]} ({refused}): "
                "give the view a smaller size",
                path,
            )
        raise PanomapError(
            f"the video encoder {encoder.codec} refused its options ({encoder.described()}): {refused}", path
        )
    if audio_template is not None and container.format.name == "mpegts":
        codec = audio_template.codec_context.name
        if codec not in MPEGTS_AUDIO:
            container.close()
            raise PanomapError(
                f"MPEG-TS cannot carry the input's {codec} audio (FFmpeg would write it as a data stream no player "
                "plays): write .mkv, .mov or .nut, or leave the audio out (--no-audio)",
                path,
            )
    try:
        audio: Any = container.add_stream_from_template(audio_template) if audio_template is not None else None
        container.start_encoding()
    except (av.error.FFmpegError, ValueError, TypeError) as exc:
        container.close()
        what = "with the input's audio " if audio_template is not None else ""
        hint = " (try --no-audio)" if audio_template is not None else ""
        raise PanomapError(
            f"cannot encode {encoder.codec} {encoder.pix_fmt} {what}into it: {reason(exc)}{hint}", path
        ) from None
    return Writer(path, temporary, container, video, audio)


def check_frame_size(encoder: EncoderSettings, size: tuple[int, int]) -> None:
    """Refuse, before any work, frames of ``size`` (width, height; px) that the encoder, opened with its
    options, does not take (x264 and SVT-AV1: over 16384 px a side; MPEG-4: over 8191), in its own words."""
    refused = probe_refusal(encoder, size=size)
    if refused is not None and probe_refusal(encoder) is None:
        raise PanomapError(
            f"the video encoder {encoder.codec} cannot encode frames of {size[0]} x {size[1]} ({refused}): "
            "give the view a smaller size"
        )


def probe_refusal(
    encoder: EncoderSettings,
    rate: Fraction = Fraction(25),
    time_base: Fraction = Fraction(1, 25),
    size: tuple[int, int] | None = None,
) -> str | None:
    """Why the encoder refuses to open with these options and pixel format for a small frame (or one of
    ``size``) (its own words), or None where it opens: its options checked before any work, and, where a frame
    of the view's size was refused, whether its size was the reason."""
    context: Any = av.codec.CodecContext.create(encoder.codec, "w")
    try:
        context.width, context.height = size or PROBE_SIZE
        context.pix_fmt = encoder.pix_fmt
        context.framerate = rate
        context.time_base = time_base
        if encoder.bitrate is not None:
            context.bit_rate = encoder.bitrate
        context.options = encoder.codec_options()
    except (av.error.FFmpegError, ValueError, TypeError, OverflowError) as exc:
        return reason(exc)
    return open_codec(context, echo=False)


# A frame every encoder takes (divisible by 16; above every encoder's least size).
PROBE_SIZE = (256, 144)

# The encoders' threading: libavcodec's default (frame and slice threads), as ffmpeg's command line encodes;
# the thread count stays PyAV's 0 (as many as there are cores), as ffmpeg's ``-threads auto``.
ENCODER_THREAD_TYPE = "AUTO"

# The audio codecs FFmpeg's MPEG-TS muxer gives a stream type (any other it writes as private data, silently).
MPEGTS_AUDIO = frozenset({"mp2", "mp3", "aac", "aac_latm", "ac3", "eac3", "dts", "truehd", "opus", "s302m"})


def container_format(path: Path) -> str | None:
    suffix = path.suffix.lower()
    known = {
        ".mp4": "mp4",
        ".m4v": "mp4",
        ".mov": "mov",
        ".mkv": "matroska",
        ".webm": "webm",
        ".avi": "avi",
        ".ts": "mpegts",
        ".nut": "nut",
    }
    if suffix not in known:
        raise PanomapError(
            f"unknown video file type {suffix or '(none)'!r}: use .mp4, .mkv, .mov, .webm, .avi, .ts", path
        )
    return known[suffix]
