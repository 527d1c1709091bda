"""Finding the image centre, the cut-off radius and the image circle.

Issue's bar: rendered images of every simulated camera, centre at random
sub-pixel places up to 40 px from the middle, Gaussian noise of 5 grey levels
and JPEG at quality 75: centre error <= 0.5 px and radii <= 1 px over 20 seeded
trials each.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from panomap.calibrate.circles import find_image_circles
from panomap.calibrate.landmarks import landmarks_to_csv
from panomap.cli.app import main
from panomap.errors import PanomapError
from panomap.simulate import load_room, render, standard_cameras
from panomap.table.file import load_table

from helpers import spread_landmarks

SIZE = (640, 600)
ROOM = load_room()
TRIALS = 20


def degrade(image: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Gaussian noise of 5 grey levels, then JPEG at quality 75."""
    noisy = np.clip(image + rng.normal(0.0, 5.0, image.shape), 0, 255).astype(np.uint8)
    ok, encoded = cv2.imencode(".jpg", noisy, [cv2.IMWRITE_JPEG_QUALITY, 75])
    assert ok
    return cv2.imdecode(encoded, cv2.IMREAD_UNCHANGED)


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
    assert worst["centre"] <= 0.5
    assert worst["outer"] <= 1.0
    assert worst["cutoff"] <= 1.0


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
    with pytest.raises(PanomapError, match="no image circle found"):
        find_image_circles(image)


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
    overlay = cv2.imread(str(tmp_path / "o.png"))
    assert overlay.shape == (480, 500, 3)
    # The overlay draws the rim in green where the image was black.
    rim = (round(camera.centre[0] + camera.outer_radius), round(camera.centre[1]))
    assert overlay[rim[1], rim[0], 1] > 150

    text = runner.invoke(main, ["centre", str(tmp_path / "omni.png")]).output
    assert text.startswith("centre: 251.3")
    plain = tmp_path / "photo.png"
    cv2.imwrite(str(plain), np.full((100, 120), 90, np.uint8))
    failed = runner.invoke(main, ["centre", str(plain)])
    assert failed.exit_code == 1
    assert failed.stderr.strip().startswith(f"panomap: error: {plain}: no image circle found")


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
    assert sources["centre"] == "detected" and sources["cutoff_radius"] == "detected"
    assert sources["outer_radius"] == "given" and table.outer_radius == 298
    assert math.dist(table.model.centre, camera.centre) < 0.2
    assert table.cutoff_radius == pytest.approx(camera.cutoff_radius, abs=0.5)
    assert "image_circles" in table.info
