"""Finding the image centre, the cut-off radius and the image circle in an omni-image.

Convention: pixel (u, v), u the column, v the row, the centre of the top-left
pixel at (0, 0); radii in px; image angle ``atan2(v - v0, u - u0)``.

Method (paper 2.1 and 3 find these automatically; refs. [18, 19] use circle
transforms):

1. **Start.** The image circle is the bright disc inside a dark border: a
   threshold of the smoothed, downscaled image, its largest blob, and a circle
   fitted to its outline where it meets its convex hull, away from the frame's
   edges (the visible arcs of a circle the frame cuts, not the dents of dark
   scene). Where that does not convince, a
   gradient circle transform of the downscaled image gives candidates: strong
   edges vote along their gradient for a centre, then for a radius.
2. **Rim edge points.** Along 720 rays from that centre, the intensity profile
   across the rim is sampled at full resolution (bilinear) and smoothed along
   the ray; each ray's outermost clear bright-to-dark drop is located to a
   fraction of a pixel. Only drops whose neighbourhood lies in the frame count:
   the frame's border is no rim.
3. **Robust circle fit.** A consensus circle through three edge points (seeded
   RANSAC), then geometric least squares (Gauss-Newton) on the points near it,
   then on the inliers (within 3 robust sigmas); steps 2-3 repeat from the new
   centre. A rim must be seen on enough rays, all round, and the level must step
   across it on most rays in the frame; that count ranks candidates. An ellipse
   is fitted to the same inliers and reported when the rim is measurably
   elliptical (non-square pixels, a tilted mirror); its centre is then the image
   centre. A bright- or dark-inside rim chosen is measured again at each ray's half level (a
   lit ring or a glow on the rim's outer slope moves its steepest point, not its half level),
   kept where it fits clearly better. Only when no bright disc is found, a rim of either polarity (a mirror
   in a bright housing: darker inside on some arcs, a thin bright or dark line on
   others), started from the circle transform's centres with the radii where the
   edge strength most rays reach peaks, outermost first (a concentric search; the
   centre searched on grids where those centres are too far off): peaks of the
   gradient magnitude along the rays, located on the profile itself (a line at its
   extreme level, a step at its steepest slope), an edge or line standing out on
   the circle, running along it, on most rays (on fewer where it is the last edge,
   the image past it smooth); the outermost such circle. Then a rim darker inside than out, checked by its step alone.
4. **Cut-off disc.** The radius where the median over the rays of the radial
   gradient rises most (a dark self-reflection, textured or not, against the
   scene), then each ray's steepest rise near it, fitted the same way. A
   fisheye, whose centre sees the scene, has none.

Every failure is an error with a reason, never a guess; where no rim is visible
at all, the error (:class:`NoImageCircle`) carries the frame centre as a
starting value.

The package, one idea a file, in the order a call goes: :mod:`.types`, :mod:`.thresholds`,
:mod:`.sampling`, :mod:`.fitting`, :mod:`.frame`, :mod:`.evidence`, :mod:`.starts`, :mod:`.rim`,
:mod:`.cutoff`, :mod:`.find`. Drawing what was found is :mod:`panomap.io.overlay`'s.
"""

from __future__ import annotations

from .cutoff import find_cutoff_about, find_cutoff_without_rim
from .find import find_image_circles
from .sampling import to_grey
from .types import Circle, Ellipse, ImageCircles, NoImageCircle

__all__ = [
    "Circle",
    "Ellipse",
    "ImageCircles",
    "NoImageCircle",
    "find_cutoff_about",
    "find_cutoff_without_rim",
    "find_image_circles",
    "to_grey",
]
