"""Finding the image centre, the cut-off radius and the image circle.

Issue's bar: rendered images of every simulated camera, centre at random
sub-pixel places up to 40 px from the middle, Gaussian noise of 5 grey levels
and JPEG at quality 75: centre error <= 0.5 px and radii <= 1 px over 20 seeded
trials each; the tests hold the centre to 0.06 px and the radii to 0.03 and 0.15 px.
The same for circles cut by one or two frame edges by up to 15% of their radius (4:3 and
16:9 sensors), and with dark vignetting and a dim side; the tolerances below are a few times
the worst error measured (docs/centre.md). Ground truth comes from panomap.simulate, which
imports nothing under test.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from panomap.calibrate.circles import NoImageCircle, find_image_circles
from panomap.calibrate.landmarks.pairs import landmarks_to_csv
from panomap.cli.app import main
from panomap.errors import PanomapError
from panomap.simulate import (
    dark_square,
    field_stop,
    housed_mirror,
    load_room,
    noisy_jpeg,
    render,
    standard_cameras,
    vignette,
)
from panomap.table.file import load_table

from helpers import spread_landmarks

SIZE = (640, 600)
ROOM = load_room()
TRIALS = 20


def degrade(image: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Gaussian noise of 5 grey levels, then JPEG at quality 75."""
    return noisy_jpeg(image, rng, noise=5.0, quality=75)


def random_centre(rng: np.random.Generator) -> tuple[float, float]:
    """Uniform in a disc of radius 40 px about the middle: the rim may leave the frame."""
    radius = 40.0 * math.sqrt(rng.uniform())
    angle = rng.uniform(0, 2 * math.pi)
    middle = ((SIZE[0] - 1) / 2, (SIZE[1] - 1) / 2)
    return middle[0] + radius * math.cos(angle), middle[1] + radius * math.sin(angle)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["equidistant", "equisolid", "parabolic", "hyperbolic", "spherical"])
def test_centre_and_radii_on_degraded_renders(name: str) -> None:
    rng = np.random.default_rng(100 + len(name))
    worst = {"centre": 0.0, "outer": 0.0, "cutoff": 0.0}
    for _ in range(TRIALS):
        camera = standard_cameras(SIZE, centre=random_centre(rng), phi0=rng.uniform(0, 2 * math.pi))[name]
        found = find_image_circles(degrade(render(ROOM, camera, supersample=2), rng))
        worst["centre"] = max(worst["centre"], math.dist(found.centre, camera.centre))
        worst["outer"] = max(worst["outer"], abs(found.outer_radius - camera.outer_radius))
        if camera.cutoff_radius == 0:
            assert found.cutoff is None, "a fisheye sees no self-occlusion disc"
        else:
            assert found.cutoff is not None
            worst["cutoff"] = max(worst["cutoff"], abs(found.cutoff.radius - camera.cutoff_radius))
        assert found.ellipse is None
    print(name, {k: round(v, 3) for k, v in worst.items()})
    # About 3x the worst measured over the 5 cameras (docs/centre.md): centre 0.021 px, outer
    # radius 0.010 px, cut-off radius 0.043 px (the bars, 0.5 and 1 px, were 25-100x).
    assert worst["centre"] <= 0.06
    assert worst["outer"] <= 0.03
    assert worst["cutoff"] <= 0.15


# Sub-pixel centres (four phases of the pixel grid) for the fast test below.
SUBPIXEL_CENTRES = [(160.37, 149.61), (158.83, 151.29), (161.12, 148.04), (159.55, 150.86)]


@pytest.mark.slow
def test_the_centre_of_noise_free_renders_at_sub_pixel_places_is_unbiased() -> None:
    """Every camera kind, noise-free (320 x 300, 2.5 s): a 0.05 px bias of the found centre fails here.

    Measured (OpenCV 5.1): worst error 0.026 px (equisolid), the mean error vector over the 20 renders
    (0.002, -0.007) px. A bias b of the found centre moves that mean by b: 0.05 px in any direction puts
    it at 0.043 px or more, over the 0.02 px bar; the worst error's bar, 0.035 px, is 1.35x the measured.
    """
    errors = []
    for name in ["equidistant", "equisolid", "parabolic", "hyperbolic", "spherical"]:
        for centre in SUBPIXEL_CENTRES:
            camera = standard_cameras((320, 300), centre=centre, phi0=0.7)[name]
            found = find_image_circles(render(ROOM, camera, supersample=2))
            errors.append(np.subtract(found.centre, camera.centre))
    errors_px = np.asarray(errors)
    assert float(np.max(np.linalg.norm(errors_px, axis=1))) <= 0.035
    assert float(np.linalg.norm(errors_px.mean(axis=0))) <= 0.02


def test_an_elliptical_rim_is_reported_as_one() -> None:
    camera = standard_cameras((600, 600))["parabolic"]
    image = render(ROOM, camera, supersample=2)
    # Non-square pixels: 3% wider than tall. Pixel centres scale about -0.5.
    stretched = cv2.resize(image, (618, 600), interpolation=cv2.INTER_AREA)
    found = find_image_circles(stretched)
    assert found.ellipse is not None
    semi = sorted(found.ellipse.semi_axes)
    assert semi[1] / semi[0] == pytest.approx(1.03, abs=0.003)
    expected = ((camera.centre[0] + 0.5) * 1.03 - 0.5, camera.centre[1])
    assert math.dist(found.centre, expected) < 0.5


@pytest.mark.parametrize("kind", ["photo", "blank", "noise"])
def test_no_circle_is_an_error_not_a_guess(kind: str) -> None:
    rng = np.random.default_rng(3)
    if kind == "photo":
        # A plain perspective-like picture: the room's wall and floor filling the frame.
        image = np.full((480, 640, 3), (150, 200, 150), np.uint8)
        image[300:] = (60, 80, 110)
        cv2.rectangle(image, (80, 60), (260, 200), (240, 210, 160), -1)
        cv2.putText(image, "N12", (380, 180), cv2.FONT_HERSHEY_SIMPLEX, 3, (30, 30, 30), 8)
    elif kind == "blank":
        image = np.full((480, 640), 128, np.uint8)
    else:
        image = rng.integers(0, 256, (480, 640), dtype=np.uint8)
    with pytest.raises(NoImageCircle, match="no image circle found") as raised:
        find_image_circles(image)
    assert raised.value.frame_centre == (319.5, 239.5)


def test_cli_centre_on_an_ordinary_photo_says_so_in_one_short_line(tmp_path: Path) -> None:
    """A picture that is no omni-image: one line naming it (<= 160 characters with the path, "rim" once), the frame
    centre as only a start; ``--verbose`` adds what the search found instead (before: ~190 characters and the path,
    "rim" twice, the rays' count in the line)."""
    image = np.full((480, 640, 3), (150, 200, 150), np.uint8)
    image[300:] = (60, 80, 110)
    cv2.rectangle(image, (80, 60), (260, 200), (240, 210, 160), -1)
    path = tmp_path / "holiday.jpg"
    cv2.imwrite(str(path), image)
    runner = CliRunner()
    failed = runner.invoke(main, ["centre", str(path)])
    assert failed.exit_code == 1 and failed.stdout == ""
    lines = failed.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"panomap: error: {path}: no image circle found: no rim is visible")
    message = lines[0].removeprefix("panomap: error: ")
    assert len(message.replace(str(path), "holiday.jpg")) <= 160 and message.count("rim") == 1, message
    assert "the frame centre (319.5, 239.5) is only a start" in message and "rays" not in message
    verbose = runner.invoke(main, ["centre", str(path), "--verbose"])
    more = verbose.stderr.splitlines()
    assert verbose.exit_code == 1 and more[0] == lines[0] and len(more) == 2
    assert re.fullmatch(r"only \d+ of \d+ rays cross a (bright-to-dark|dark-to-bright) rim", more[1]), more[1]


def test_sixteen_bit_and_grey_images_work() -> None:
    camera = standard_cameras((500, 500))["hyperbolic"]
    image = render(ROOM, camera, supersample=2)
    grey16 = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY).astype(np.uint16) * 257
    found = find_image_circles(grey16)
    assert math.dist(found.centre, camera.centre) < 0.2


def test_cli_centre_prints_and_draws(tmp_path: Path) -> None:
    camera = standard_cameras((500, 480), centre=(251.3, 238.6))["parabolic"]
    cv2.imwrite(str(tmp_path / "omni.png"), render(ROOM, camera, supersample=2))
    runner = CliRunner()
    result = runner.invoke(main, ["centre", str(tmp_path / "omni.png"), "--json", "--overlay", str(tmp_path / "o.png")])
    assert result.exit_code == 0, result.stderr
    data = json.loads(result.output)
    assert math.dist(data["centre"], camera.centre) < 0.2
    assert data["cutoff_radius"] == pytest.approx(camera.cutoff_radius, abs=0.5)
    overlay = cv2.imread(str(tmp_path / "o.png")).astype(int)
    assert overlay.shape == (480, 500, 3)
    # The overlay draws the image circle in green and the cut-off disc in red, around the true
    # centre at the true radii: every drawn pixel within the line's half-width (1.5 px for the thick
    # arcs, plus 1 px of anti-aliasing) of its circle, the median within 0.3 px (measured 0.11 and
    # 0.18 px), and the image circle all round (36 sectors of 10 deg).
    drawn = np.any(overlay != cv2.imread(str(tmp_path / "omni.png")).astype(int), axis=-1)
    blue, green, red = np.moveaxis(overlay, -1, 0)
    for colour, radius, sectors in [
        (drawn & (green > 150) & (red < 100) & (blue < 100), camera.outer_radius, 36),
        (drawn & (red > 150) & (green < 100) & (blue < 100), camera.cutoff_radius, 30),
    ]:
        v, u = np.nonzero(colour)
        distance = np.hypot(u - camera.centre[0], v - camera.centre[1])
        assert len(distance) > 2 * math.pi * radius, len(distance)
        assert np.max(np.abs(distance - radius)) < 3.0
        assert abs(np.median(distance) - radius) < 0.3
        angle = np.degrees(np.arctan2(v - camera.centre[1], u - camera.centre[0])) % 360
        assert len(np.unique((angle // 10).astype(int))) >= sectors

    text = runner.invoke(main, ["centre", str(tmp_path / "omni.png")]).output
    u0, v0 = map(float, text.splitlines()[0].removeprefix("centre: ").split())
    assert math.dist((u0, v0), camera.centre) < 0.05
    assert "frame cuts" not in text and "rim seen on 100% of the rays, bright inside" in text
    plain = tmp_path / "photo.png"
    cv2.imwrite(str(plain), np.full((100, 120), 90, np.uint8))
    failed = runner.invoke(main, ["centre", str(plain)])
    assert failed.exit_code == 1
    assert failed.stderr.strip().startswith(f"panomap: error: {plain}: no image circle found")


@pytest.mark.slow
def test_fit_finds_the_centre_and_radii_when_not_given(tmp_path: Path) -> None:
    camera = standard_cameras((640, 640), centre=(331.7, 309.2), s=-1, phi0=1.0)["hyperbolic"]
    cv2.imwrite(str(tmp_path / "omni.png"), render(ROOM, camera, supersample=2))
    landmarks = spread_landmarks(camera, ROOM.camera, 12, np.random.default_rng(0))
    (tmp_path / "lm.csv").write_text(landmarks_to_csv(landmarks))
    result = CliRunner().invoke(
        main,
        [
            "fit",
            str(tmp_path / "lm.csv"),
            "-o",
            str(tmp_path / "t.npz"),
            "--camera",
            *map(str, ROOM.camera),
            "--image",
            str(tmp_path / "omni.png"),
            "--outer-radius",
            "298",
        ],
    )
    assert result.exit_code == 0, result.stderr
    table = load_table(tmp_path / "t.npz")
    sources = table.info["sources"]
    # The detected centre starts the fit and the landmarks refine it (the default when it is not given).
    assert sources["centre"] == "detected, refined with the landmarks" and sources["cutoff_radius"] == "detected"
    assert sources["outer_radius"] == "given" and table.outer_radius == 298
    assert math.dist(table.model.centre, camera.centre) < 0.2
    assert table.cutoff_radius == pytest.approx(camera.cutoff_radius, abs=0.5)
    assert "image_circles" in table.info


# Frames that cut the circle: (width, height), which edges, and how the centre is drawn.
CROPPED_FRAMES = {
    "4:3, top and bottom": (640, 480),
    "16:9, top and bottom": (800, 450),
    "top only": (600, 600),
    "left and top": (600, 600),
}


def cropped_camera(frame: str, name: str, rng: np.random.Generator) -> object:
    """A camera whose circle the frame cuts by 0.5-15% of its radius on the edges named by ``frame``."""
    width, height = CROPPED_FRAMES[frame]
    cut = rng.uniform(0.005, 0.15)
    jitter = rng.uniform(-2.0, 2.0, 2)
    if frame == "top only":
        radius = 250.0 + jitter[0]
        centre = ((width - 1) / 2 + 10 * jitter[1], radius * (1 - cut) - 0.5)
    elif frame == "left and top":
        radius = 260.0 + jitter[0]
        centre = (radius * (1 - cut) - 0.5, radius * (1 - rng.uniform(0.005, 0.15)) - 0.5)
    else:
        radius = (height / 2) / (1 - cut)
        centre = ((width - 1) / 2 + jitter[0], (height - 1) / 2 + jitter[1] / 4)
    return standard_cameras((width, height), centre=centre, phi0=rng.uniform(0, 2 * math.pi), outer_radius=radius)[name]


@pytest.mark.slow
@pytest.mark.parametrize("frame", list(CROPPED_FRAMES))
def test_circles_cut_by_the_frame(frame: str) -> None:
    """Measured worst over these trials: centre 0.015 px, outer radius 0.015 px, cut-off radius 0.04 px."""
    rng = np.random.default_rng(200 + len(frame))
    worst = {"centre": 0.0, "outer": 0.0, "cutoff": 0.0}
    expected_edges = {
        "4:3, top and bottom": ("top", "bottom"),
        "16:9, top and bottom": ("top", "bottom"),
        "top only": ("top",),
        "left and top": ("left", "top"),
    }[frame]
    for name in ["equidistant", "equisolid", "parabolic", "hyperbolic", "spherical"]:
        for _ in range(2):
            camera = cropped_camera(frame, name, rng)
            found = find_image_circles(degrade(render(ROOM, camera, supersample=2), rng))
            worst["centre"] = max(worst["centre"], math.dist(found.centre, camera.centre))
            worst["outer"] = max(worst["outer"], abs(found.outer_radius - camera.outer_radius))
            assert found.cropped_by == expected_edges
            assert 0.5 < found.rim_in_frame < 1.0
            assert found.rim_seen <= found.rim_in_frame + 0.01
            if camera.cutoff_radius == 0:
                assert found.cutoff is None
            else:
                assert found.cutoff is not None
                worst["cutoff"] = max(worst["cutoff"], abs(found.cutoff.radius - camera.cutoff_radius))
    print(frame, {k: round(v, 3) for k, v in worst.items()})
    # About 3 times the worst measured; the bar is 0.5 px and 1 px.
    assert worst["centre"] <= 0.05
    assert worst["outer"] <= 0.05
    assert worst["cutoff"] <= 0.15


@pytest.mark.slow
@pytest.mark.parametrize("frame", ["uncropped", "4:3, top and bottom"])
def test_vignetting_and_a_dim_side(frame: str) -> None:
    """Rim at half brightness all round and a sixth on one side. Measured worst: centre 0.053 px, radius 0.046 px."""
    rng = np.random.default_rng(300 + len(frame))
    worst = {"centre": 0.0, "outer": 0.0}
    for name in ["equidistant", "equisolid", "parabolic", "hyperbolic", "spherical"]:
        for _ in range(2):
            if frame == "uncropped":
                camera = standard_cameras(SIZE, centre=random_centre(rng), phi0=rng.uniform(0, 2 * math.pi))[name]
            else:
                camera = cropped_camera(frame, name, rng)
            image = render(ROOM, camera, supersample=2)
            dimmed = vignette(
                image, camera.centre, camera.outer_radius, falloff=0.5, dim=0.35, dim_angle=rng.uniform(0, 2 * math.pi)
            )
            found = find_image_circles(degrade(dimmed, rng))
            worst["centre"] = max(worst["centre"], math.dist(found.centre, camera.centre))
            worst["outer"] = max(worst["outer"], abs(found.outer_radius - camera.outer_radius))
            assert (found.cutoff is None) == (camera.cutoff_radius == 0)
    print(frame, {k: round(v, 3) for k, v in worst.items()})
    assert worst["centre"] <= 0.15
    assert worst["outer"] <= 0.15


@pytest.mark.slow
@pytest.mark.parametrize(("size", "cuts"), [((600, 600), (0.17, 0.21)), ((640, 480), (0.28, 0.33))])
def test_a_circle_seen_only_about_the_corners(size: tuple[int, int], cuts: tuple[float, float]) -> None:
    """A round image just past the frame's sides (a square frame cut by 17-21% of the radius, a 4:3 one by 28-33%):
    its rim shows only about the four corners, on 14-34% of the rays; it is found all the same, not taken for a
    full-frame fisheye. Measured worst: centre 0.03 px, radius 0.03 px (the code before found none in the square
    frame: "the bright region fills the frame"). About 10 deg of rim a corner is the least that is found."""
    rng = np.random.default_rng(size[0] + size[1])
    worst = {"centre": 0.0, "outer": 0.0}
    for name in ["equidistant", "equisolid", "parabolic", "hyperbolic", "spherical"]:
        for cut in cuts:
            radius = (min(size) / 2) / (1 - cut) + rng.uniform(-1, 1)
            centre = ((size[0] - 1) / 2 + rng.uniform(-3, 3), (size[1] - 1) / 2 + rng.uniform(-3, 3))
            camera = standard_cameras(size, centre=centre, phi0=rng.uniform(0, 2 * math.pi), outer_radius=radius)[name]
            found = find_image_circles(degrade(render(ROOM, camera, supersample=2), rng))
            worst["centre"] = max(worst["centre"], math.dist(found.centre, camera.centre))
            worst["outer"] = max(worst["outer"], abs(found.outer_radius - camera.outer_radius))
            assert set(found.cropped_by) == {"left", "top", "right", "bottom"}
            assert found.rim_in_frame < 0.35
    print(size, {k: round(v, 3) for k, v in worst.items()})
    assert worst["centre"] <= 0.1
    assert worst["outer"] <= 0.1


SOFT_RIM_CASES = [
    ((1280, 960), 560.0, "equidistant"),
    ((1280, 960), 700.0, "equisolid"),
    ((1920, 1080), 640.0, "equidistant"),
    ((1024, 768), 420.0, "equisolid"),
    ((1920, 1920), 1100.0, "equisolid"),
]


@pytest.mark.slow
def test_a_soft_rim_out_of_focus() -> None:
    """A fisheye's field stop out of focus: its edge blurred by a Gaussian of 3, 4 and 6 px (its half level on the
    circle), vignetted, the rim off the axis. Measured worst, blurred by 3-4 px: centre 0.11 px, radius 0.26 px
    (the code before, each ray's outermost clear drop anywhere on the long slope: 0.32 and 0.63 px); by 6 px,
    every rim found, the centre within 0.48 px (before, one of the five not found)."""
    rng = np.random.default_rng(5)
    worst = {"centre": 0.0, "outer": 0.0}
    for softness in (3.0, 4.0, 6.0):
        for size, radius, name in SOFT_RIM_CASES:
            axis = (size[0] / 2 + rng.uniform(-10, 10), size[1] / 2 + rng.uniform(-10, 10))
            rim = (axis[0] + 1.5, axis[1] - 1.0)
            turn = rng.uniform(0, 2 * math.pi)
            camera = standard_cameras(size, centre=axis, phi0=turn, outer_radius=radius + 30)[name]
            image = field_stop(render(ROOM, camera, supersample=1), rim, radius, softness_px=softness)
            dimmed = vignette(
                image, rim, radius, falloff=rng.uniform(0, 0.5), dim=rng.uniform(0, 0.3), dim_angle=rng.uniform(0, 6.3)
            )
            found = find_image_circles(degrade(dimmed, rng))
            centre, outer = math.dist(found.centre, rim), abs(found.outer_radius - radius)
            if softness < 5:
                worst["centre"] = max(worst["centre"], centre)
                worst["outer"] = max(worst["outer"], outer)
            else:
                assert centre <= 0.75 and outer <= 0.5, (size, name, centre, outer)
    print({k: round(v, 3) for k, v in worst.items()})
    assert worst["centre"] <= 0.25
    assert worst["outer"] <= 0.4


@pytest.mark.parametrize(("size", "radius"), [((640, 480), 420.0), ((640, 360), 380.0)])
def test_a_full_frame_fisheye_has_no_rim_and_says_so(size: tuple[int, int], radius: float) -> None:
    """The circle holds the whole frame: no rim to fit; the answer carries the frame centre to start from."""
    rng = np.random.default_rng(5)
    for name in ["equidistant", "equisolid"]:
        camera = standard_cameras(size, phi0=rng.uniform(0, 2 * math.pi), outer_radius=radius)[name]
        with pytest.raises(NoImageCircle, match="no rim is visible") as raised:
            find_image_circles(degrade(render(ROOM, camera, supersample=1), rng))
        assert raised.value.frame_centre == ((size[0] - 1) / 2, (size[1] - 1) / 2)
        assert raised.value.cutoff is None  # a fisheye does not see itself
        assert isinstance(raised.value, PanomapError)  # callers that only know PanomapError still stop


@pytest.mark.slow
@pytest.mark.parametrize("housed", [False, True])
def test_a_mirror_image_that_overfills_the_frame_shows_its_cut_off_disc(housed: bool) -> None:
    """A mirror camera whose image is larger than the frame on every side: no rim, but the camera's own
    reflection, a dark disc near the middle (in a housing: a round lens in a square board with lighter parts).

    NoImageCircle carries the disc: a search about a grid of centres near the frame's middle (before, no disc
    was reported without a rim; the disc's search of an image with a rim, tried about a coarser grid, 2% of
    the short side apart, missed 3 of 10 discs whose centre lay 8-15 px from the nearest). Measured over these
    trials: centre within 0.045 px (vignetted) and 0.26 px (housed), radius 0.034 and 0.32 px. Full-frame
    fisheyes give none (the test above; on 16 more, the edges tried reached 31-48% of the rays, the bar 70%).
    """
    sizes = ((1024, 768), (1280, 960), (1920, 1920))
    for trial, size in enumerate(sizes):
        rng = np.random.default_rng(40 + trial + 10 * housed)
        short = min(size)
        axis = (
            (size[0] - 1) / 2 + rng.uniform(-0.02, 0.02) * short,
            (size[1] - 1) / 2 + rng.uniform(-0.02, 0.02) * short,
        )
        radius = math.hypot(*size) / 2 + 40
        name = ("hyperbolic", "parabolic", "spherical")[trial]
        camera = standard_cameras(size, centre=axis, phi0=rng.uniform(0, 2 * math.pi), outer_radius=radius)[name]
        image = render(ROOM, camera, supersample=1)
        if housed:
            image = housed_mirror(image, axis, radius, camera.cutoff_radius, rng)
        else:
            image = vignette(image, axis, radius, falloff=rng.uniform(0, 0.5), dim=0.0, dim_angle=0.0)
        with pytest.raises(NoImageCircle, match="a cut-off disc is") as raised:
            find_image_circles(noisy_jpeg(image, rng))
        disc = raised.value.cutoff
        assert disc is not None, (trial, housed)
        print(
            housed, trial, round(math.dist(disc.centre, camera.centre), 3), round(disc.radius - camera.cutoff_radius, 3)
        )
        assert math.dist(disc.centre, camera.centre) <= (0.75 if housed else 0.15), trial
        assert abs(disc.radius - camera.cutoff_radius) <= (1.0 if housed else 0.1), trial


def test_cli_centre_reports_the_cropping_and_a_missing_rim(tmp_path: Path) -> None:
    camera = standard_cameras((640, 480), centre=(321.4, 238.2), outer_radius=265.0)["hyperbolic"]
    cv2.imwrite(str(tmp_path / "cropped.png"), render(ROOM, camera, supersample=2))
    runner = CliRunner()
    text = runner.invoke(main, ["centre", str(tmp_path / "cropped.png")]).output
    assert "the frame cuts the image circle at its top and bottom edges" in text
    data = json.loads(runner.invoke(main, ["centre", str(tmp_path / "cropped.png"), "--json"]).output)
    assert data["cropped_by"] == ["top", "bottom"]
    # The part of a 265 px circle inside rows -0.5 .. 479.5 (pixel edges), its centre at row 238.2.
    inside = 1 - (math.acos(238.7 / 265.0) + math.acos((479.5 - 238.2) / 265.0)) / math.pi
    assert data["rim_in_frame"] == pytest.approx(inside, abs=0.01)
    # The arcs fitted lie in the frame: none reaches the top (270 deg) or the bottom (90 deg).
    arcs = data["rim_arcs_deg"]
    assert arcs and all(end - start <= 180 for start, end in arcs)
    for angle in (90.0, 270.0, 450.0, 630.0):
        assert not any(start <= angle <= end for start, end in arcs)
    assert sum(end - start for start, end in arcs) / 360 == pytest.approx(data["rim_seen"], abs=0.05)

    fisheye = standard_cameras((640, 480), outer_radius=420.0)["equidistant"]
    cv2.imwrite(str(tmp_path / "full.png"), render(ROOM, fisheye, supersample=1))
    failed = runner.invoke(main, ["centre", str(tmp_path / "full.png")])
    assert failed.exit_code == 1
    lines = failed.stderr.strip().splitlines()
    assert len(lines) == 1 and "no rim is visible" in lines[0] and "(319.5, 239.5)" in lines[0]


REAL = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"
# Per real set: worst distance (px) of the rim centre from the established calibration's
# centre (about twice the worst measured: the rim's centre is not the optical axis on a
# real camera), the images whose rim must be found, and those with a cut-off disc.
REAL_SETS = {
    "ocam_kaidan_catadioptric": (1.8, 17, 16),
    "ocam_vmr_catadioptric": (5.5, 10, 10),
    "mei_paracatadioptric": (7.0, 10, 10),
    "ocam_fisheye_imgback": (14.0, 11, 0),
    "ocam_miniomni_catadioptric": (21.0, 12, 11),
}


def real_reference(folder: Path) -> tuple[float, float]:
    """(u, v) centre of the calibration shipped in ``folder``, 0-based."""
    ocam = folder / "ocam_model.json"
    if ocam.exists():
        model = json.loads(ocam.read_text())
        return float(model["yc_col_0based"]), float(model["xc_row_0based"])
    data = json.loads((folder / "omnidir_calibration.json").read_text())
    k = data["models"][data["primary"]]["K"]
    return float(k[0][2]), float(k[1][2])


@pytest.mark.real_data
@pytest.mark.slow
@pytest.mark.skipif(not REAL.is_dir(), reason=f"real data not found at {REAL} (../shared is not beside the repo)")
@pytest.mark.parametrize("folder", list(REAL_SETS))
def test_real_sets(folder: str) -> None:
    """Measured (docs/centre.md): found on 17/17, 10/10, 10/10, 11/11 and 12/15 images (miniomni: 5/15 before the
    concentric search, 11/15 before the outermost edges' circle; 11 with the cut-off disc, 3 before the disc was
    searched for about its own centre); where not, NoImageCircle."""
    from panomap.io.images import read_image

    bound, least_found, least_cutoffs = REAL_SETS[folder]
    reference = real_reference(REAL / folder)
    found = cutoffs = 0
    worst = 0.0
    for path in sorted((REAL / folder / "images").iterdir()):
        try:
            circles = find_image_circles(read_image(path))
        except NoImageCircle:
            continue
        found += 1
        cutoffs += circles.cutoff is not None
        worst = max(worst, math.dist(circles.centre, reference))
    print(folder, found, cutoffs, round(worst, 2))
    assert found >= least_found
    assert cutoffs >= least_cutoffs
    assert worst <= bound


@pytest.mark.slow
def test_a_mirror_in_a_bright_blurred_housing() -> None:
    """The mirror fills the frame inside a bright, blurred housing; the rim's contrast changes sign.

    panomap.simulate.housed_mirror: darker inside on some arcs, a thin bright or dark line on
    others, and a square dark board with a round lens as the self-reflection. The issue's bar:
    centre <= 0.5 px, radius <= 1 px, the cut-off disc found (its radius within 1 px). Measured
    over these 12 trials (docs/centre.md): 12 found (11 before the concentric search; the other
    gave NoImageCircle), worst centre 0.20 px, outer radius 0.20 px, cut-off radius 0.52 px
    (0.48 and 0.33 px where the simulation left a dark band at the rim).
    """
    rng = np.random.default_rng(11)
    found_count = 0
    for trial in range(6):
        for size, radius in (((640, 600), None), ((640, 480), 260.0)):
            name = ["parabolic", "hyperbolic", "spherical"][trial % 3]
            centre = ((size[0] - 1) / 2 + rng.uniform(-20, 20), (size[1] - 1) / 2 + rng.uniform(-8, 8))
            camera = standard_cameras(size, centre=centre, phi0=rng.uniform(0, 2 * math.pi), outer_radius=radius)[name]
            image = render(ROOM, camera, supersample=2)
            housed = housed_mirror(image, camera.centre, camera.outer_radius, camera.cutoff_radius, rng)
            try:
                found = find_image_circles(noisy_jpeg(housed, rng))
            except NoImageCircle:
                continue
            found_count += 1
            assert math.dist(found.centre, camera.centre) <= 0.5, (trial, size)
            assert abs(found.outer_radius - camera.outer_radius) <= 1.0, (trial, size)
            assert found.cutoff is not None, (trial, size)
            assert abs(found.cutoff.radius - camera.cutoff_radius) <= 1.0, (trial, size)
            assert found.rim_polarity in ("dark inside", "mixed")
    assert found_count == 12


@pytest.mark.slow
@pytest.mark.parametrize(("faint", "bound_px"), [(0.4, 0.5), (0.55, 0.5), (0.62, 1.0)])
def test_a_housed_mirror_whose_rim_shows_on_part_of_it(faint: float, bound_px: float) -> None:
    """The housing as bright as the mirror on ``faint`` of the rim (housed_mirror(faint=...)), as on miniomni.

    The rim then shows an edge on 35-60% of the rays in the frame, under the 60% a circle
    needs on its own, while a circle of the scene inside the mirror passes: that circle was
    reported as the rim, 13-54 px too small. Past a circle that passed, a circle about the
    same centre is the rim with an edge on 40% of the rays, or on 20% in 4 sectors where the
    image past it is smooth (the housing out of focus). Measured over these trials: worst
    centre 0.36 px, radius 0.30 px at f <= 0.55; with 40% alone, 3 of the 6 at f = 0.55 wrong
    (two scene circles 38-50 px too small, one none), whose rims show on 36-45% of the rays, in
    5 sectors. At f = 0.62 the rim shows on 22-38% of the rays: centre 0.48 px, radius 0.40 px
    (the bar here 1 px, the scene's circles being 13-50 px off); with 30%, 2 of 6 wrong.
    """
    rng = np.random.default_rng(31)
    for trial in range(6):
        size, radius = ((640, 600), None) if trial % 2 == 0 else ((640, 480), 260.0)
        name = ["parabolic", "hyperbolic", "spherical"][trial % 3]
        centre = ((size[0] - 1) / 2 + rng.uniform(-20, 20), (size[1] - 1) / 2 + rng.uniform(-8, 8))
        camera = standard_cameras(size, centre=centre, phi0=rng.uniform(0, 2 * math.pi), outer_radius=radius)[name]
        image = render(ROOM, camera, supersample=2)
        housed = housed_mirror(image, camera.centre, camera.outer_radius, camera.cutoff_radius, rng, faint=faint)
        found = find_image_circles(noisy_jpeg(housed, rng))
        assert math.dist(found.centre, camera.centre) <= bound_px, trial
        assert abs(found.outer_radius - camera.outer_radius) <= max(0.7, bound_px), trial


@pytest.mark.slow
@pytest.mark.parametrize("size", [(1920, 1920), (1920, 1440)])
def test_a_housed_mirror_at_full_size(size: tuple[int, int]) -> None:
    """The housed mirror at 1920 px: the rim's thin line and the housing's blur (px, not scaled with the image)
    vanish in the downscaled circle transform, whose candidates then miss the rim by tens of px.

    The concentric search (the edge strength most rays reach, peaking at one radius about the
    right centre) finds it. 1920 x 1440 cuts the circle at top and bottom by 8% of its radius.
    Measured worst over these trials: centre 0.17 px, outer radius 0.08 px, cut-off radius 0.52 px
    (the spherical mirror at 1920 x 1920; 0.21 and 0.31 px for the rim where the simulation left a
    dark band at it); two to seven times that for the rim, the issue's bar (1 px) for the cut-off disc.
    """
    rng = np.random.default_rng(21 + size[1])
    for name in ["hyperbolic", "spherical"]:
        middle = ((size[0] - 1) / 2, (size[1] - 1) / 2)
        centre = (middle[0] + rng.uniform(-20, 20), middle[1] + rng.uniform(-20, 20))
        radius = None if size[0] == size[1] else 780.0
        camera = standard_cameras(size, centre=centre, phi0=rng.uniform(0, 2 * math.pi), outer_radius=radius)[name]
        image = render(ROOM, camera, supersample=1)
        housed = housed_mirror(image, camera.centre, camera.outer_radius, camera.cutoff_radius, rng)
        found = find_image_circles(noisy_jpeg(housed, rng))
        assert math.dist(found.centre, camera.centre) <= 0.4, name
        assert abs(found.outer_radius - camera.outer_radius) <= 0.6, name
        assert found.cutoff is not None, name
        assert abs(found.cutoff.radius - camera.cutoff_radius) <= 1.0, name
        assert found.rim_polarity in ("dark inside", "mixed")
        if radius is not None:
            assert found.cropped_by == ("top", "bottom")


@pytest.mark.slow
@pytest.mark.parametrize("crop", [0.08, 0.12])
def test_a_housed_mirror_cut_on_all_four_sides(crop: float) -> None:
    """A round image larger than its square frame: the housed mirror's rim shows as four arcs about the corners.

    Cut by 12% of its radius on every side, the rim lies in the frame on 37% of the rays;
    the concentric profile's share of all the rays never reached it, and the rim needed 6
    of the 12 sectors where the frame shows only 4 to 8 (both found nothing before:
    bench/bench_centre_sweep.py, seeds 4 and 5; both fail here without the two changes).
    Measured: centre 0.03 and 0.06 px, outer radius 0.17 and 0.04 px; the issue's bar
    (0.5 px, 1 px) is what is asserted.
    """
    rng = np.random.default_rng(int(100 * crop))
    size = (1920, 1920)
    centre = (959.5 + rng.uniform(-20, 20), 959.5 + rng.uniform(-20, 20))
    camera = standard_cameras(size, centre=centre, phi0=rng.uniform(0, 2 * math.pi), outer_radius=960 / (1 - crop))[
        "spherical"
    ]
    housed = housed_mirror(
        render(ROOM, camera, supersample=1), camera.centre, camera.outer_radius, camera.cutoff_radius, rng
    )
    found = find_image_circles(noisy_jpeg(housed, rng))
    assert math.dist(found.centre, camera.centre) <= 0.5
    assert abs(found.outer_radius - camera.outer_radius) <= 1.0
    assert found.cutoff is not None and abs(found.cutoff.radius - camera.cutoff_radius) <= 1.0
    assert set(found.cropped_by) == {"left", "top", "right", "bottom"}


@pytest.mark.slow
@pytest.mark.parametrize(("seed", "name", "size"), [(37, "hyperbolic", (1920, 1440)), (59, "parabolic", (1920, 1920))])
def test_a_housed_mirror_whose_first_centre_is_far_off(seed: int, name: str, size: tuple[int, int]) -> None:
    """Housed mirrors at 1920 px cut by the frame (10% and 12% of the radius), whose circle transform's centre falls
    20-30 px off the rim's.

    No concentric profile (about that centre or the grid search's) shows the thin rim line;
    the consensus circle through the outermost clear edge on each ray does. These are
    bench/bench_centre_sweep.py's seeds 37 and 59, drawn the same way: both found no circle
    before it (other draws of the same cameras passed without it). Measured: centre 0.06
    and 0.25 px; the bar asserted is the issue's (0.5 px, 1 px).
    """
    rng = np.random.default_rng(seed)
    rng.integers(6), rng.integers(5)  # the sweep's draws of the size and the camera (given here)
    crop = rng.uniform(0, 0.15)
    middle = ((size[0] - 1) / 2, (size[1] - 1) / 2)
    off = 0.02 * min(size)
    centre = (middle[0] + rng.uniform(-off, off), middle[1] + rng.uniform(-off, off))
    radius = min(size) / 2 / (1 - crop)
    camera = standard_cameras(size, centre=centre, phi0=rng.uniform(0, 2 * math.pi), outer_radius=radius)[name]
    image = render(ROOM, camera, supersample=1)
    rng.uniform()  # the sweep's draw of the housing
    housed = housed_mirror(image, camera.centre, camera.outer_radius, camera.cutoff_radius, rng)
    found = find_image_circles(noisy_jpeg(housed, rng))
    assert math.dist(found.centre, camera.centre) <= 0.5
    assert abs(found.outer_radius - camera.outer_radius) <= 1.0
    assert found.cutoff is not None and abs(found.cutoff.radius - camera.cutoff_radius) <= 1.0


def test_the_simulated_housing_is_brighter_than_the_mirror() -> None:
    """housed_mirror: the housing fills the frame around a darker mirror (no bright disc in a dark border)."""
    rng = np.random.default_rng(4)
    camera = standard_cameras((400, 400))["hyperbolic"]
    housed = housed_mirror(render(ROOM, camera, supersample=1), camera.centre, camera.outer_radius, 15.0, rng)
    grey = cv2.cvtColor(housed, cv2.COLOR_BGR2GRAY).astype(float)
    v, u = np.mgrid[0:400, 0:400]
    r = np.hypot(u - camera.centre[0], v - camera.centre[1])
    assert np.median(grey[r > camera.outer_radius + 3]) > np.median(grey[r < camera.outer_radius - 3])
    with pytest.raises(PanomapError, match="cutoff_radius"):
        housed_mirror(render(ROOM, camera, supersample=1), camera.centre, 100.0, 50.0, rng)
    with pytest.raises(PanomapError, match="faint"):
        housed_mirror(render(ROOM, camera, supersample=1), camera.centre, camera.outer_radius, 15.0, rng, faint=1.0)


def test_a_faint_arc_of_the_simulated_rim_has_no_contrast() -> None:
    """housed_mirror(faint=0.6) takes the rim's step or line away on 60% of it and leaves the rest as it was.

    The same seed draws the same arcs, levels and housing; only the faint arc (drawn after
    them) differs near the rim, where every arc had a step or a line of 40-80 grey levels.
    """
    camera = standard_cameras((400, 400))["hyperbolic"]
    image = render(ROOM, camera, supersample=1)
    v, u = np.mgrid[0:400, 0:400]
    r = np.hypot(u - camera.centre[0], v - camera.centre[1])
    degree = (np.degrees(np.arctan2(v - camera.centre[1], u - camera.centre[0])) % 360).astype(int)
    plain, faint = (
        housed_mirror(image, camera.centre, camera.outer_radius, 15.0, np.random.default_rng(4), faint=f)[..., 0]
        for f in (0.0, 0.6)
    )
    near = np.abs(r - camera.outer_radius) < 3
    change = np.abs(plain.astype(float) - faint)
    changed = np.array([np.max(change[near & (degree == d)]) > 20 for d in range(360)])
    assert abs(np.mean(changed) - 0.6) < 0.03


@pytest.mark.parametrize("offset_px", [3.0, 4.5])
def test_a_cut_off_disc_off_the_rims_centre_is_found_about_its_own(offset_px: float) -> None:
    """A mirror not quite centred in its housing: the rim's circle is ``offset_px`` from the optical axis,
    about which the camera's reflection (the cut-off disc) is centred (the miniomni camera: 3-5 px). Before the
    disc was searched for about its own centre, any disc more than 2 px (5% of its radius) off was dropped."""
    rng = np.random.default_rng(31)
    camera = standard_cameras(SIZE, centre=(321.4, 298.7))["hyperbolic"]
    image = render(ROOM, camera, supersample=2)
    rim = (camera.centre[0] + offset_px, camera.centre[1] - 0.5 * offset_px)
    v, u = np.mgrid[0 : SIZE[1], 0 : SIZE[0]]
    image[np.hypot(u - rim[0], v - rim[1]) > camera.outer_radius - 2 * offset_px] = 0
    found = find_image_circles(degrade(image, rng))
    assert math.dist(found.centre, rim) < 0.5  # the rim's own centre: the landmarks refine the axis
    assert found.cutoff is not None
    # Measured: the disc's centre 0.026 px from the axis, its radius 0.025 px off (both offsets).
    assert math.dist(found.cutoff.centre, camera.centre) < 0.5
    assert abs(found.cutoff.radius - camera.cutoff_radius) < 0.5


@pytest.mark.parametrize("offset_px", [1.5, 3.0])
def test_a_housed_mirror_whose_rim_is_off_the_axis(offset_px: float) -> None:
    """The simulator's rim off the optical axis (``field_stop``, and ``housed_mirror(lens_centre=...)``: the
    camera's reflection about the axis, the housing about the rim), as on the five real cameras (0.25-1% of
    the rim's radius): the circle is the rim's, the cut-off disc the axis's, each to the issue's bar.

    Measured: the rim's centre 0.19 and 0.20 px off (radius 0.14 px), the disc's 0.16 and 0.10 px from the
    axis (radius 0.09 and 0.07 px).
    """
    rng = np.random.default_rng(17)
    axis = (1279.5 / 2 + 7.3, 959.5 / 2 - 4.1)
    rim = (axis[0] + offset_px * 0.6, axis[1] + offset_px * 0.8)
    radius = 430.0
    camera = standard_cameras((1280, 960), centre=axis, outer_radius=radius + offset_px + 2)["hyperbolic"]
    image = field_stop(render(ROOM, camera, supersample=1), rim, radius)
    image = housed_mirror(image, rim, radius, camera.cutoff_radius, rng, lens_centre=axis)
    found = find_image_circles(noisy_jpeg(image, rng))
    assert math.dist(found.centre, rim) < 0.5
    assert abs(found.outer_radius - radius) < 1.0
    assert found.cutoff is not None
    assert math.dist(found.cutoff.centre, axis) < 0.5
    assert abs(found.cutoff.radius - camera.cutoff_radius) < 1.0


def test_cli_centre_draws_what_it_found_where_no_rim_is(tmp_path: Path) -> None:
    """No rim: the command fails (exit 1, one line), and ``--overlay`` still shows what was found: a mirror
    image that overfills the frame its cut-off disc (red, at the true radius about the true axis) and the
    disc's centre (a yellow cross); a full-frame fisheye only the frame's middle (before, nothing was drawn)."""
    size, axis = (640, 480), (326.3, 236.8)
    mirror = standard_cameras(size, centre=axis, outer_radius=math.hypot(*size) / 2 + 40)["parabolic"]
    fisheye = standard_cameras(size, outer_radius=420.0)["equidistant"]
    runner = CliRunner()
    for name, camera, start in [("mirror", mirror, axis), ("fisheye", fisheye, (319.5, 239.5))]:
        omni = vignette(render(ROOM, camera, supersample=1), camera.centre, 440.0, falloff=0.3, dim=0.0, dim_angle=0.0)
        cv2.imwrite(str(tmp_path / f"{name}.png"), omni)
        drawing = tmp_path / f"{name}_overlay.png"
        result = runner.invoke(main, ["centre", str(tmp_path / f"{name}.png"), "--overlay", str(drawing)])
        assert result.exit_code == 1
        assert result.stderr.count("\n") == 1 and "no rim is visible" in result.stderr
        assert f"wrote {drawing}" in result.output
        overlay = cv2.imread(str(drawing)).astype(int)
        drawn = np.any(overlay != cv2.imread(str(tmp_path / f"{name}.png")).astype(int), axis=-1)
        blue, green, red = np.moveaxis(overlay, -1, 0)
        v, u = np.nonzero(drawn & (red > 150) & (green < 100) & (blue < 100))
        if camera is fisheye:
            assert len(u) == 0  # no disc
        else:
            distance = np.hypot(u - axis[0], v - axis[1])
            assert len(distance) > 2 * math.pi * camera.cutoff_radius
            assert abs(np.median(distance) - camera.cutoff_radius) < 0.5
        # The cross: yellow pixels along a row and a column through the starting value, 12 px either side.
        v, u = np.nonzero(drawn & (red > 150) & (green > 150) & (blue < 100))
        assert len(u) >= 40, name
        assert abs(np.median(u) - start[0]) < 1.0 and abs(np.median(v) - start[1]) < 1.0, name
        assert np.ptp(u) <= 26 and np.ptp(v) <= 26, name


def test_the_rim_of_a_dark_picture_is_found() -> None:
    """A tracking camera's dark picture: a rendered room through a 190 deg fisheye on a 16:9 frame (the circle cut
    at top and bottom), its rim softened by 1 px, vignetted by 70%, at an eighth of its brightness, noise, JPEG.
    Before dark pictures were brightened this was refused ("no dark border"), and re-projected photographs at a
    quarter of their brightness lost 4 of 8 rims.

    Measured: centre 0.49 px from the truth, radius 0.46 px small.
    """
    from panomap.simulate.line_scenes import line_camera, render_line_scene

    camera = line_camera("fisheye190", 0.4, tilt_deg=0.0)
    scene = render_line_scene(camera, seed=4, supersample=1, noise=0.0, jpeg_quality=100, falloff=0.0)
    image = field_stop(scene.image, camera.centre, camera.outer_radius - 3.0, softness_px=1.0)
    image = vignette(image, camera.centre, camera.outer_radius, falloff=0.7)
    image = np.asarray(image * 0.12, dtype=np.uint8)
    image = noisy_jpeg(image, np.random.default_rng(4), noise=2.0, quality=85)
    circles = find_image_circles(image)
    assert math.dist(circles.centre, camera.centre) < 1.0
    assert circles.outer_radius == pytest.approx(camera.outer_radius - 3.0, abs=1.0)


def robot_fisheye(seed: int, name: str) -> tuple[np.ndarray, tuple[float, float], float]:
    """A robot's fisheye: its circle (0.40-0.56 of an 800 px square: cut by the square's sides past 0.5) vignetted
    by 60-80%, in a dark square (5-35 grey levels, a glow at the rim) inside a 1280 x 800 black frame, the whole
    picture at 30-100% brightness, noise, JPEG. Returns the image, the circle's centre and radius."""
    rng = np.random.default_rng(seed)
    square = (640 + rng.uniform(-150, 150), 399.5)
    radius = rng.uniform(0.40, 0.56) * 800
    centre = (square[0] + rng.uniform(-8, 8), square[1] + rng.uniform(-8, 8))
    camera = standard_cameras((1280, 800), centre=centre, phi0=rng.uniform(0, 6.3), outer_radius=radius)[name]
    image = vignette(render(ROOM, camera, supersample=1), centre, radius, falloff=rng.uniform(0.6, 0.8), power=3.0)
    gain = rng.uniform(0.3, 1.0)
    image = np.asarray(image * gain, np.uint8)
    level = rng.uniform(10, 30) * gain + 5
    image = dark_square(image, centre, radius, 399.5, level=level, square_centre=square, glow=rng.uniform(0, 10))
    return noisy_jpeg(image, rng, noise=3.0, quality=80), centre, radius


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 7])
def test_a_circle_in_a_dark_square_inside_a_black_frame(seed: int) -> None:
    """The rim steps down 5-15 grey levels to the dark square, whose edge steps 20-35 to the black frame: the
    bright blob was the square and the rim's step under the 8 levels asked for (before: "no rim is visible (a
    full-frame fisheye ...", seed 0; seed 7 was found). The square's floor taken off and the picture stretched,
    it is found. Measured: centre within 0.1 px, radius within 0.3 px (1 px allowed: the vignetted rim is soft)."""
    for name in ("equidistant", "equisolid"):
        image, centre, radius = robot_fisheye(seed, name)
        found = find_image_circles(image)
        assert math.dist(found.centre, centre) < 1.0, (name, found.centre, centre)
        assert found.outer_radius == pytest.approx(radius, abs=1.0)


@pytest.mark.slow
def test_a_rim_dark_to_near_black() -> None:
    """A tracking camera's lens whose picture darkens to near black before its edge (vignetted by 93-98%, the last
    tenth of the radius falling steeply), on 848 x 800: the rim steps by about 10 grey levels (before, one of
    these was not found, the rim's points off a circle). Measured: centre within 0.2 px, radius 0.4-2.7 px small
    (the picture's last px lie under the noise)."""
    for seed, name in ((8, "equisolid"), (2, "equidistant"), (6, "equidistant")):
        rng = np.random.default_rng(seed)
        radius = rng.uniform(380, 430)
        centre = (424 + rng.uniform(-10, 10), 400 + rng.uniform(-10, 10))
        camera = standard_cameras((848, 800), centre=centre, phi0=rng.uniform(0, 6.3), outer_radius=radius)[name]
        image = render(ROOM, camera, supersample=1)
        image = vignette(image, centre, radius, falloff=rng.uniform(0.93, 0.98), power=rng.uniform(4, 6))
        image = noisy_jpeg(
            np.asarray(image * rng.uniform(0.3, 1.0), np.uint8), rng, noise=rng.uniform(1, 4), quality=85
        )
        found = find_image_circles(image)
        assert math.dist(found.centre, centre) < 1.0, (seed, name)
        assert -4.0 < found.outer_radius - radius < 1.0, (seed, name)


def dark_tracking_frame(seed: int) -> tuple[np.ndarray, tuple[float, float], float]:
    """A tracking camera's dark frame (848 x 800): its circle (radius 390-470 px: cut by the frame at top and bottom,
    or on all four sides) with a stop blurred by 0.5-3 px, vignetted by 60-85%, at 10-35% brightness, over a floor
    of 0-6 grey levels; noise of 1-3 levels, JPEG. Returns the image, the circle's centre and radius."""
    rng = np.random.default_rng(seed)
    radius = rng.uniform(390, 470)
    centre = (424 + rng.uniform(-10, 10), 400 + rng.uniform(-10, 10))
    softness_px = rng.uniform(0.5, 3.0)
    name = ("equidistant", "equisolid")[rng.integers(2)]
    outer = radius + 3 * softness_px + 2
    camera = standard_cameras((848, 800), centre=centre, phi0=rng.uniform(0, 6.3), outer_radius=outer)[name]
    image = field_stop(render(ROOM, camera, supersample=1), centre, radius, softness_px=softness_px)
    image = vignette(image, centre, radius, falloff=rng.uniform(0.6, 0.85), power=rng.uniform(2, 4))
    image = np.asarray(image * rng.uniform(0.1, 0.35), np.uint8)
    image = dark_square(image, centre, radius, 1000.0, level=rng.uniform(0, 6))
    return noisy_jpeg(image, rng, noise=rng.uniform(1, 3), quality=85), centre, radius


@pytest.mark.slow
@pytest.mark.parametrize("seed", [9, 14])
def test_the_rim_of_a_dark_noisy_frame(seed: int) -> None:
    """Brightened up to 8x, the frame's noise is too: each ray's outermost clear drop fell on a blip past the rim,
    and these two were refused ("no rim is visible"; 5 of 24 such frames). The brightened picture smoothed in
    proportion (find.exposed), 3 of 24 are. Measured: centre 0.09 and 0.03 px from the truth, radius 5.1 px small
    and 1.9 px large (the circle cut on all four sides, seen about the corners)."""
    image, centre, radius = dark_tracking_frame(seed)
    found = find_image_circles(image)
    assert math.dist(found.centre, centre) < 1.0, found.centre
    assert found.outer_radius == pytest.approx(radius, abs=6.0)


def vignetted_tracking_frame(falloff: float) -> np.ndarray:
    """A tracking camera's frame (848 x 800, its circle of 430 px about (431.9, 405.5) cut at top and bottom, the
    stop blurred by 4 px) vignetted by ``falloff`` at the rim (the cube of the radius), at half brightness."""
    centre, radius = (431.9, 405.5), 430.0
    camera = standard_cameras((848, 800), centre=centre, phi0=1.0, outer_radius=radius + 14.0)["equidistant"]
    image = field_stop(render(ROOM, camera, supersample=1), centre, radius, softness_px=4.0)
    image = vignette(image, centre, radius, falloff=falloff, power=3.0)
    return noisy_jpeg(np.asarray(image * 0.52, np.uint8), np.random.default_rng(7), noise=2.0, quality=85)


def test_a_dark_rim_around_a_circle_of_its_scene() -> None:
    """Vignetted by 96% at its rim: a circle of the room (251 px, an edge on 43% of the rays) passed as a rim of
    either polarity, 25 px off; the bright disc's rim about it, stepping on 83% of its rays in the frame (not the
    85% that makes a rim convincing), was not taken. Now the disc that shows on more of its rays is. Measured:
    centre 0.02 px from the truth, radius 5.2 px small (the last px darker than the noise)."""
    found = find_image_circles(vignetted_tracking_frame(0.964))
    assert math.dist(found.centre, (431.9, 405.5)) < 1.0, found.centre
    assert found.outer_radius == pytest.approx(430.0, abs=8.0)


def test_a_round_image_whose_rim_is_not_found_is_no_full_frame_fisheye() -> None:
    """Vignetted by 98% at its rim: no rim passes, but the frame's corners are black around a picture, which a
    full-frame fisheye's are not. Before, it was said to be "no rim is visible (a full-frame fisheye, ...)" (and
    frames like it "... a cut-off disc is (... a mirror image that overfills the frame)"); the full-frame fisheyes
    above and the real car park's (corners at 30-45 grey levels) are still said to be full-frame."""
    with pytest.raises(NoImageCircle, match="corners are dark around a picture") as raised:
        find_image_circles(vignetted_tracking_frame(0.98))
    assert "a full-frame fisheye" not in str(raised.value) and raised.value.cutoff is None


def test_the_dark_square_is_drawn_with_its_levels() -> None:
    """simulate.dark_square: the square's level outside the disc, black past the square, the picture untouched."""
    image = np.full((100, 160), 200, np.uint8)
    image[np.hypot(*np.mgrid[0:100, 0:160][::-1] - np.array([80.0, 50.0])[:, None, None]) > 40] = 0
    out = dark_square(image, (80.0, 50.0), 40.0, 48.0, level=25.0)
    assert out[50, 80] == 200 and out[50, 125] == 25 and out[50, 5] == 0 and out[3, 80] == 25
    under = dark_square(image, (80.0, 50.0), 40.0, 48.0, level=25.0, under_disc=True)  # a pedestal under it all
    assert under[50, 80] == 225 and under[50, 125] == 25 and under[50, 5] == 0


def soft_robot_fisheye(seed: int, name: str, softness_px: float, glow: float) -> tuple[np.ndarray, tuple[float, float]]:
    """A robot's fisheye whose rim is soft: its field stop blurred by ``softness_px`` (a Gaussian's sigma, its half
    level on the circle), vignetted by 60-90%, in a dark square whose pedestal (5-35 grey levels, a glow of up to
    ``glow`` levels either side of the rim) lies under the picture too, inside a 1280 x 800 black frame; noise,
    JPEG. Returns the image and the circle's centre."""
    rng = np.random.default_rng(seed)
    square = (640 + rng.uniform(-150, 150), 399.5)
    radius = rng.uniform(0.40, 0.56) * 800
    centre = (square[0] + rng.uniform(-8, 8), square[1] + rng.uniform(-8, 8))
    outer = radius + 3 * softness_px + 2
    camera = standard_cameras((1280, 800), centre=centre, phi0=rng.uniform(0, 6.3), outer_radius=outer)[name]
    image = field_stop(render(ROOM, camera, supersample=1), centre, radius, softness_px=softness_px)
    image = vignette(image, centre, radius, falloff=rng.uniform(0.6, 0.9), power=rng.uniform(2, 4))
    gain = rng.uniform(0.3, 1.0)
    image = np.asarray(image * gain, np.uint8)
    level = rng.uniform(10, 30) * gain + 5
    glowing = rng.uniform(0, glow)
    image = dark_square(image, centre, radius, 399.5, level, square_centre=square, glow=glowing, under_disc=True)
    return noisy_jpeg(image, rng, noise=3.0, quality=80), centre


@pytest.mark.slow
@pytest.mark.parametrize(
    ("seed", "name", "softness_px", "glow"),
    [
        (22, "equidistant", 3.0, 10.0),
        (22, "equidistant", 10.0, 10.0),
        (25, "equisolid", 10.0, 10.0),
        (25, "equisolid", 15.0, 20.0),
    ],
)
def test_a_soft_rim_in_a_dark_square_over_its_pedestal(seed: int, name: str, softness_px: float, glow: float) -> None:
    """The square's pedestal under the picture too (as a sensor's is), the rim soft: it falls smoothly to the
    square's level. Each of these was said to be "no rim is visible (a full-frame fisheye ...)": the largest
    blob over the one threshold was the square, and the rim's points at full resolution lay off a circle. Round
    level lines of the picture and the picture shrunk by 2 and 4 find it. Measured: centre 0.04, 0.76, 0.20 and
    0.97 px from the truth (of 24 such renders, 23 found, worst 2.2 px; 19 before)."""
    image, centre = soft_robot_fisheye(seed, name, softness_px, glow)
    found = find_image_circles(image)
    assert math.dist(found.centre, centre) < 2.0, (found.centre, centre)


def test_a_soft_rim_around_a_circle_of_its_scene() -> None:
    """A robot's fisheye (1024 x 768) in a dark square over its pedestal (34 grey levels), its stop blurred by 6 px
    and vignetted by 85%: the rim's step falls over 20 px, while a circle of the scene inside it (the room's walls
    meeting its floor, round through the lens, 80 px further in) is an edge on 40% of the rays. That circle passed
    as a rim of either polarity, 15 px off the rim's centre (with one of six noise draws), before the bright disc
    around it (stepping all round in the picture shrunk by 2) was looked for. Measured: centre 0.04-0.14 px from
    the truth, radius 3.8 px small (the soft stop's half level read where the slope ends)."""
    centre, radius, softness_px = (583.84, 377.11), 302.55, 6.0
    camera = standard_cameras((1024, 768), centre=centre, phi0=3.355, outer_radius=radius + 20.0)["equidistant"]
    image = field_stop(render(ROOM, camera, supersample=1), centre, radius, softness_px=softness_px)
    image = vignette(image, centre, radius, falloff=0.853, power=3.0)
    image = np.asarray(image * 0.854, np.uint8)
    image = dark_square(image, centre, radius, 370.74, 33.6, square_centre=(586.57, 371.09), glow=1.1, under_disc=True)
    for seed in (1, 2):  # noise seed 1 gave the scene's circle; 2 (and 0, 3-5) the rim, before too
        found = find_image_circles(noisy_jpeg(image, np.random.default_rng(seed), noise=3.0, quality=80))
        assert found.rim_polarity == "bright inside", seed
        assert math.dist(found.centre, centre) < 1.0, (seed, found.centre)
        assert found.outer_radius == pytest.approx(radius, abs=6.0)
