"""The circle finder's settings: its rays and profile sampling, and the thresholds every step applies,
each with the measurement that set it.
"""

from __future__ import annotations

RAYS = 720
COARSE_SIDE = 400
# A bright blob whose own floor (2nd percentile) lies this many grey levels over the frame's holds a dark surround
# of its own (the circle in a dark square inside a black frame: squares of 10-40 levels): the disc is looked for in it.
NESTED_FLOOR_LEVELS = 8.0
# ... and is flat: its robust sigma (grey levels, in the smoothed downscaled image) at most this.
NESTED_FLOOR_SPREAD = 6.0
STEP = 0.5  # px between profile samples
PROFILE_SIGMA_PX = 1.0  # smoothing of the profiles along their rays
# Samples either side of an edge (4 px) that must lie in the frame, and those whose levels are compared.
EDGE_HALF_WINDOW = 8
LEVEL_SAMPLES = 16
# Edge points further than this from the fitted circle (in robust sigmas) are outliers.
INLIER_SIGMAS = 3.0
# Rays (of RAYS) whose rim points must agree: a circle cut by the frame by 15% of its
# radius on two sides still shows 64% of its rim, but dark scene may hide much of that
# (a real fisheye cut at top and bottom shows a quarter of its rim).
MIN_RIM_FRACTION = 0.2
# A round image just larger than the frame (past a square frame's sides, or a 4:3 frame's four) shows its rim only
# about the corners, on fewer rays than that: there, this share of the rays on which the circle lies in the frame
# will do, and no fewer than MIN_RIM_RAYS (20 deg of rim, in the sectors asked for below).
MIN_RIM_SHARE_IN_FRAME = 0.6
MIN_RIM_RAYS = 40
# ... spread around the circle: in at least this many of 12 sectors of 30 deg, a third of the rays agree.
MIN_RIM_SECTORS = 4
# Rays (of those in the frame) stepping across a rim that needs no other candidate.
CONVINCING_RIM_FRACTION = 0.85
# Rays (of those in the frame) along which the level steps across the circle: 0.8-0.97 on
# real rims, 0.4-0.7 on circles through scene edges. A mirror's rim in a bright housing
# (darker inside than out) steps less clearly (0.5-0.8 on the real one), and circles
# through scene edges reach 0.53 there.
MIN_STEPPING_FRACTION = 0.75
MIN_STEPPING_FRACTION_DARK_INSIDE = 0.62
# A rim darker inside than out is a mirror's in a bright housing, which frames it: the frame shows at least this
# share of its circle (housed-mirror renders 75-100%, the real miniomni 59%). A fisheye's scene edge (a car park's
# painted kerb, round through the lens) passed as one, 34% of it in the frame, on a full-frame fisheye.
DARK_INSIDE_LEAST_IN_FRAME = 0.5
# A search stops after its first circle where the levels step across it on fewer than this
# share of the rays the final test asks for (a wrong start costs one search, not four).
EARLY_STEPPING_SHARE = 0.5
# A rim of either polarity (a mirror in a bright housing) is told from scene edges by an edge
# or line that stands out on it (FEATURE_MIN_STRENGTH grey levels per px, FEATURE_MIN_RATIO
# times the edges beside it) on this fraction of the rays in the frame, in this many sectors.
MIN_FEATURE_FRACTION = 0.6
# ... or this fraction, for a circle about the same centre past one that passed (the outermost is the rim).
MIN_FEATURE_FRACTION_OUTSIDE = 0.4
MIN_RIM_SECTORS_EITHER = 6
# ... or this fraction, in MIN_RIM_SECTORS, for such a circle where the image past it is smooth
# (the housing out of focus; a rim seen only where the housing's light differs from the mirror's:
# on 22-38% of the rays where it is as bright as the mirror on 62% of the rim).
MIN_FEATURE_FRACTION_LAST = 0.2
FEATURE_MIN_STRENGTH = 4.0
FEATURE_MIN_RATIO = 2.0
# Sharp real rims fit to 0.2-0.9 px RMS, a soft (vignetted) one to 1.5 px; a false circle
# through scene edges fits worse.
MAX_RIM_RMS_PX = 2.0
# A soft rim (a fisheye's field stop out of focus, blurred over several px) scatters its edge points: each
# ray's outermost clear drop falls anywhere on the long slope, outward on average (a stop blurred by 3-4 px:
# 0.5-1.7 px RMS, the centre up to 0.9 px off and the radius up to 1.5 px too large; the whole image blurred
# by 8 px: none passes). A bright- or dark-inside rim whose fit is worse than SOFT_RIM_RMS_PX is fitted again
# on the image smoothed by each of SOFT_RIM_SIGMAS_PX (the profiles then show one slope), kept where its RMS
# is under SOFT_RIM_GAIN of the first and it is the same edge (centre and radius each within twice the
# first's RMS: on one real fisheye image the smoothed fit took an edge 4 px further in).
SOFT_RIM_RMS_PX = 0.5
# A rim whose arcs fix its centre worse than this (px: the standard error along the worst direction, fitting's
# centre_uncertainty_px) is refused: twice it would exceed the 3 px a centre is promised to. Neighbouring rays'
# residuals count as one in RIM_CORRELATED_RAYS there. Measured: a real fisheye's one 60 deg arc (a car's
# surround camera, the circle cut by three edges) 3.4 px, its centre 42 px off; a real T265-like rim seen on a
# third of its circle, 120 deg, 0.3 px (1.5 px off its calibration); rims seen all round, under 0.1 px.
MAX_CENTRE_UNCERTAINTY_PX = 1.5
RIM_CORRELATED_RAYS = 10
SOFT_RIM_SIGMAS_PX = (2.0, 4.0)
SOFT_RIM_GAIN = 0.7
MIN_CUTOFF_FRACTION = 0.5
MAX_CUTOFF_RMS_PX = 1.5
# Median over the rays of the radial gradient (grey levels per px) at the cut-off disc's edge.
CUTOFF_MIN_MEDIAN_RISE = 3.0
# The cut-off disc's centre may lie this far (a fraction of the outer radius) from the rim's: on the
# miniomni camera the disc (about the calibrated axis) is 3-5 px off the rim's centre in most images.
CUTOFF_CENTRE_FRACTION = 0.03
# A cut-off disc is the camera's own reflection, so it is as large as the camera seen from its mirror: the
# simulated mirror cameras' discs are 7-16% of the outer radius (cut-off angles 12 deg and up), the real
# ones 9-26% (miniomni to kaidan). A dark thing straight ahead of a fisheye is any size: one smaller than
# CUTOFF_MIN_RATIO of the outer radius (a lens's 7.6 px dot, 1.5% of its 495 px circle; a dark blob of 3%
# in a render) is no camera's reflection and is not reported, so it cannot make a fisheye a mirror camera.
# (A larger dark disc straight ahead, concentric with the rim, looks as a reflection does: see docs/centre.md.)
CUTOFF_MIN_RATIO = 0.05
CUTOFF_ITERATIONS = 4
# A mirror image that overfills the frame shows no rim, only the camera's reflection: a dark disc
# near the frame's middle. It is looked for about a grid of centres this far (a fraction of the
# frame's short side, in steps of DISC_GRID_STEP) from the middle, and kept only where it is clear:
# a dark-to-bright edge on DISC_MIN_FRACTION of the rays, its centre within DISC_MAX_OFFSET and its
# radius within DISC_RADII of the short side (on 40 simulated full-frame fisheyes, none was found).
DISC_GRID_HALF = 0.03
DISC_GRID_STEP = 0.005
DISC_MIN_FRACTION = 0.7
DISC_MAX_OFFSET = 0.05
# Its smallest radius is CUTOFF_MIN_RATIO of the image circle's, which overfills the frame: at least half its
# short side.
DISC_RADII = (CUTOFF_MIN_RATIO / 2, 0.35)
DISC_CANDIDATES = 5
# An ellipse is reported when its axes differ by more than this fraction and it fits clearly better.
ELLIPSE_MIN_ECCENTRICITY = 0.003
# The circle transform: the strongest edge pixels that vote, and the weakest gradient (Sobel units) that may.
VOTING_EDGES = 6000
VOTING_MIN_GRADIENT = 20.0
# How far (a fraction of the radius) the rim is looked for from a start circle: a good one, a rough one.
NARROW_REACH = 0.06
WIDE_REACH = 0.15
# A drop of at least this fraction of the steepest on its ray is a clear one.
CLEAR_DROP = 0.3
# A drop with a slope the other way of at least this fraction of it within this many px inward is a thin line's far
# side (a lit barrel's ring past the rim), no rim (evidence._far_sides).
LINE_SLOPE_RATIO = 0.5
LINE_WIDTH_PX = 6.0
# ... or a drop within LINE_WIDTH_PX past a line of the rim's polarity that a grey opening as wide takes off this many
# grey levels high (evidence._without_lines: a lit ring on the rim's blurred outer slope, its rise too small beside
# its fall for a line by slopes). On a flat grey with noise of 2 and 5 levels, JPEG at 60, the opening takes off 1.4
# and 4.9 levels at the 99th percentile (2.1 and 6.9 at the 99.9th): a drop in the noisiest such picture is now and
# then left out, which the fit's consensus of rays absorbs (the unkind renders, noise 2-5, lost none).
LINE_LEAST_LEVELS = 5.0
# A rim's edge, re-measured where the search ended, is where the level crosses halfway between its highest this many
# px inside each ray's drop and its lowest as far outside (evidence._halfway).
HALFWAY_WINDOW_PX = 15.0
# ... on rays whose fall is at least FALL_WIDTH_SHARE as wide as the rim's median (evidence._as_wide_as_the_rim; each
# ray's step over its steepest drop within FALL_SLOPE_PX of the crossing), where that median is SOFT_FALL_PX or more
# (a stop blurred by a sigma of 2.4 px). Renders of rims fading over 20-30 px (bench_circles_unkind --faded): the
# rim's falls 14-18 px wide, a dark thing's edge at the rim 3-6 px; a sharp rim's falls are a few px, all alike.
FALL_WIDTH_SHARE = 0.5
FALL_SLOPE_PX = 2.0
SOFT_FALL_PX = 6.0
# ... fitted this many times about each fit's circle, kept where at least this share of the rim's inliers are found
# so and the fit's RMS is at most this fraction of the search's (rim._halfway_rim): the half levels lie on a circle
# clearly better than the steepest points (a sharp rim's steepest points are the finer measure: 0.03-0.06 px).
# Six fits: with lines opened away (evidence._without_lines), a start 3.7 px off a ring's pull came back over five
# (3.7, 2.6, 1.9, 1.3, 0.4, 0.2 px: an unkind render, seed 52); three left it 1.3 px off and not kept.
HALFWAY_ITERATIONS = 6
HALFWAY_LEAST_SHARE = 0.8
HALFWAY_GAIN = 0.8
# ... or, at most 1 / HALFWAY_GAIN of it, with this many times its inliers (a lit ring past the rim on one arc: the
# steepest points there off the circle, the half levels on it).
HALFWAY_MORE = 1.2
# Circles through three edge points tried by the consensus fit.
CONSENSUS_SAMPLES = 200
GAUSS_NEWTON_ITERATIONS = 50
# Edge points this close to a circle (px) measure its spread.
NEAR_PX = 3.0
# ... or this fraction of the radius, when more: a rim that is an ellipse strays that far from a circle.
NEAR_FRACTION = 0.015
# The concentric search for a faint rim of either polarity: the circle transform's centres it
# starts from, its rays, the fraction of them whose edge strength it takes at each radius, and
# what makes a peak of that profile clear (a fraction of the highest, a multiple of its median).
CONCENTRIC_SEEDS = 3
CONCENTRIC_RAYS = 72
# Where those centres give no rim, the grids (half-width, step; px) on which the centre is searched.
CONCENTRIC_GRIDS = ((40.0, 10.0), (10.0, 3.0), (3.0, 1.0))
# ... scored by its profile's highest peak, and again by how far a peak stands above the profile's
# running median over this many px of radius either side (in the shrunk image): a rim is narrow in radius.
CONCENTRIC_BACKGROUND_PX = 12.0
CONCENTRIC_SHARE = 0.4
# ... of the rays in the frame, at radii where at least this fraction of them are.
CONCENTRIC_LEAST_IN_FRAME = 0.2
CONCENTRIC_PEAK_RATIO = 0.3
CONCENTRIC_PROMINENCE = 3.0
# Two start circles whose centres and radii differ by less than this fraction of the radius
# (or 2 px) lead to the same rim: the second is not tried.
SAME_START_FRACTION = 0.01
FRAME_EDGES = ("left", "top", "right", "bottom")
# A picture whose bright end (this percentile of its levels) lies under DARK_LEVEL of 255 uses under 40% of its
# range: it is brightened so that its bright end reaches EXPOSED_LEVEL, by at most MAX_EXPOSURE_GAIN (find.exposed).
DARK_PERCENTILE = 99.0
DARK_LEVEL = 100.0
EXPOSED_LEVEL = 200.0
MAX_EXPOSURE_GAIN = 8.0
# ... and, where that gain exceeds EXPOSED_SMOOTHING_GAIN and no rim passed, searched again smoothed by a Gaussian of
# EXPOSED_SMOOTHING_PX times the square root of the gain over it (px: 1.4 at the largest gain). Dark tracking-camera
# frames (848 x 800, 10-35% brightness, the circle cut by the frame): 5 of 24 rims refused before, 3 after.
EXPOSED_SMOOTHING_GAIN = 2.0
EXPOSED_SMOOTHING_PX = 0.7
# Where no rim passed, the search runs again on the picture stretched over the range (find.above_floor) where that
# gains at least this much, or takes a dark surround's floor off.
STRETCH_LEAST_GAIN = 1.5
# ... and only where the frame has black in it (its 2nd percentile at most this): the real surround-view fisheyes
# whose circles hold the frame have corners at 30-45 grey levels, and one was taken for a rim when stretched.
STRETCH_BLACK_LEVEL = 12.0
# Where no rim passes, a frame whose four corners (patches this fraction of the shrunk picture's short side) are that
# dark, its middle half this many grey levels brighter, is said to hold a round image whose rim was not found, not to
# be a full-frame fisheye (whose corners show the scene; the car park's, at 30-45 grey levels, stay full-frame).
DARK_CORNER_FRACTION = 0.04
DARK_CORNER_CONTRAST = 20.0
# Where no rim passes at full resolution, a bright disc's rim is looked for in the picture shrunk by each of these
# factors (find.coarser_rim: a soft rim, sharp again when shrunk), down to pictures of this many px a side; kept
# where its edge points lie on a circle to this RMS (px of the shrunk picture). Rendered soft rims (stops blurred by
# 6 px, in dark squares) fit to 0.06-0.7 px there; a real full-frame fisheye's scene gave a circle of 1.95 px.
COARSER_FACTORS = (1, 2, 4)
COARSER_LEAST_SIDE_PX = 64
COARSER_MAX_RMS_PX = 1.0
# The level lines that may outline a disc (starts._level_circles): these fractions of the way from the picture's dark
# end to its bright one; a blob is round where its outline lies on a circle to this fraction of its radius RMS.
LEVEL_FRACTIONS = (0.1, 0.2, 0.35, 0.5)
LEVEL_ROUND_FRACTION = 0.02
