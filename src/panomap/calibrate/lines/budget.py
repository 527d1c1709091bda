"""The memory of learning a camera from lines and checkerboards, estimated before any image is read.

Measured (peak RSS of ``panomap fit --image``, 2 cores): one image of one grey level, 2000 x 2000:
0.60 GB, 4000 x 4000: 0.68 GB, 6000 x 6000: 0.83 GB (7.3 bytes a pixel beyond about 0.57 GB: the
image held, its circles, the edges' working image, the checkerboard search at a fixed size); a rendered
room, 1920 x 1080: 0.43 GB, 3840 x 2160: 0.60 GB (its line fit, up to 38 bytes a pixel where the
working image is the image itself: radii under 1700 px, so at most about 0.5 GB). The estimate rounds
both up.
"""

from __future__ import annotations

from collections.abc import Sequence

from ...errors import PanomapError

# Bytes per pixel of every image (all are held while the edges of each are searched), and the rest.
BYTES_PER_IMAGE_PIXEL = 12
BASE_BYTES = 1_000_000_000


def line_search_memory(sizes: Sequence[tuple[int, int]]) -> int:
    """Estimated peak memory (bytes) of learning from images of ``sizes`` (width, height px)."""
    return BASE_BYTES + BYTES_PER_IMAGE_PIXEL * sum(width * height for width, height in sizes)


def check_line_search_memory(sizes: Sequence[tuple[int, int]], memory_limit: int | None) -> int:
    """The estimate of :func:`line_search_memory`; PanomapError beyond ``memory_limit`` bytes (the command
    line gives 3/4 of the machine's memory, as ``panomap video`` checks its views; None: no limit)."""
    needed = line_search_memory(sizes)
    if memory_limit is not None and needed > memory_limit:
        pixels = sum(width * height for width, height in sizes)
        raise PanomapError(
            f"learning from {len(sizes)} image(s) of {pixels:,} pixels in all needs about {needed / 1e9:.1f} GB "
            f"of memory, more than the {memory_limit / 1e9:.1f} GB available (3/4 of this machine's): "
            "give fewer or smaller images"
        )
    return needed
