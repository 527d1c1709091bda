"""Checkerboards: what limits the held-out RMS (BabelCalib's half-set protocol): the held-out residuals' structure.

Run: ``.venv/bin/python bench/bench_board_residuals.py [--data ../shared/data/real] [--only NAME]``

For each real set, as ``bench_board_heldout.py`` splits it (the even images calibrate, the odd ones measure;
the corners of ``corners.csv``), panomap's camera (:func:`fit_boards`, its own choices) is fitted to the even
images; every board's pose is then fitted to its corners under that camera, held (the even ones' too: their
in-sample residuals). Of the held-out corners' residuals (px) it prints:

- **noise**: the corners' own noise, from the boards alone (no camera): third to fifth differences of the
  corners along the board's rows and columns (a smooth image of a grid leaves them near zero; independent
  noise of sigma px gives them variances 20, 70 and 252 sigma^2 per axis). Orders that agree say the smooth
  part is gone; the fifth's sigma is the detector's repeatability, and ``sqrt(2) sigma sqrt(1 - 6 / 2n)`` the
  held-out RMS a board's pose fit leaves of it (n corners a board): the floor no camera can go below;
- **held-out** RMS, its radial and tangential parts (about the camera's centre) and by ring of radius;
- **board-local**: the share of the held-out residuals' squares that a smooth map of each board's own grid
  explains (an affine + quadratic map of the grid places, 12 values a board), beside the share pure noise
  would give (12 / 2n): above it, each board has its own pattern (a board not flat, a pose the camera
  cannot take) that no camera term can predict;
- **image field**: a smooth field over the image (a polynomial of degree 1-4 in the offsets from the centre,
  ridge-regularised), fitted to the even images' in-sample residuals and added to the camera's pixels; the
  held-out RMS with it (poses refitted): a field that predicts the images left out lowers it;
- **the image field in folds** (``--folds``: this and the field alone): whether the rule that keeps a term
  (:mod:`panomap.calibrate.boards.terms`: 5 folds of whole images, better by more than one standard error
  and 3%) would keep that field, within the even images (the camera refitted without each fold);
- **the board's shape**: one shape for the set's board (a print not square; a bend off its plane, a
  polynomial of degree 2 or 3 of its places), fitted to the even images with the camera held; the held-out
  RMS where the held-out boards' poses are fitted with that shape (a board that is not flat, the same in
  every image, predicts the images left out), and, the camera refitted to the corners a flat board would
  have given (three rounds), the held-out RMS of the protocol (flat boards) and with the shape.

With ``--drift``: where the camera fitted to all the set's corners, with its terms (``auto``) and without
(``none``), departs from the established calibration inside the boards' radii and beyond them.
"""

from __future__ import annotations

import argparse
import itertools
import math
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from bench_board_heldout import _flipped, load_cv2, panomap_camera, pose_from_rays, set_boards

FloatArray = NDArray[np.float64]
Boards = list[tuple[FloatArray, NDArray[np.intp]]]


def fitted_residuals(project, lift, boards: Boards, cv2, shape=None) -> list[FloatArray]:  # type: ignore[no-untyped-def]
    """Each board's residuals (n, 2) px (model minus detection) under a fixed camera, its pose fitted (its
    points, squares, ``shape(grid)`` where given, else flat)."""
    out = []
    for pixels, grid in boards:
        plane = np.column_stack([grid.astype(np.float64), np.zeros(len(grid))]) if shape is None else shape(grid)

        def residuals(pose: FloatArray, plane: FloatArray = plane, pixels: FloatArray = pixels) -> FloatArray:
            points = Rotation.from_rotvec(pose[:3]).apply(plane) + pose[3:]
            res = (project(points) - pixels).ravel()
            return np.where(np.isfinite(res), res, 1e3)

        start = pose_from_rays(lift(pixels), grid, cv2)
        fits = [least_squares(residuals, s, x_scale="jac", method="lm", max_nfev=400) for s in (start, _flipped(start))]
        out.append(min(fits, key=lambda s: float(s.cost)).fun.reshape(-1, 2))
    return out


def board_shape(values: FloatArray, span: float):  # type: ignore[no-untyped-def]
    """The board's points (n, 3), squares, of its grid places (n, 2): the x places stretched by values[0] (a print
    not square), then off the plane by a polynomial of the places over ``span`` (degree 2, 3: values[1:])."""

    def points(grid: NDArray[np.intp]) -> FloatArray:
        g = grid.astype(np.float64)
        x, y = (g / span - 0.5).T
        monomials = [x * x, x * y, y * y, x**3, x * x * y, x * y * y, y**3][: len(values) - 1]
        z = sum((c * m for c, m in zip(values[1:], monomials, strict=True)), np.zeros(len(g)))
        return np.column_stack([g[:, 0] * (1 + values[0]), g[:, 1], z])

    return points


def shape_fit(project, lift, trains: Boards, cv2, count: int) -> tuple[FloatArray, FloatArray]:  # type: ignore[no-untyped-def]
    """The board's shape values (count,) that best explain the training corners, the camera held, poses free;
    and the boards' poses (boards, 6)."""
    span = float(max(np.ptp(g) for _, g in trains))
    starts = []
    for pixels, grid in trains:
        plane = np.column_stack([grid.astype(np.float64), np.zeros(len(grid))])

        def one(pose: FloatArray, plane: FloatArray = plane, pixels: FloatArray = pixels) -> FloatArray:
            res = (project(Rotation.from_rotvec(pose[:3]).apply(plane) + pose[3:]) - pixels).ravel()
            return np.where(np.isfinite(res), res, 1e3)

        start = pose_from_rays(lift(pixels), grid, cv2)
        fits = [least_squares(one, s, x_scale="jac", method="lm", max_nfev=400) for s in (start, _flipped(start))]
        starts.append(min(fits, key=lambda s: float(s.cost)).x)

    def residuals(x: FloatArray) -> FloatArray:
        shape = board_shape(x[:count], span)
        out = []
        for k, (pixels, grid) in enumerate(trains):
            pose = x[count + 6 * k : count + 6 * k + 6]
            out.append((project(Rotation.from_rotvec(pose[:3]).apply(shape(grid)) + pose[3:]) - pixels).ravel())
        res = np.concatenate(out)
        return np.where(np.isfinite(res), res, 1e3)

    solution = least_squares(residuals, np.concatenate([np.zeros(count), *starts]), method="lm", max_nfev=2000)
    return np.asarray(solution.x[:count]), np.asarray(solution.x[count:]).reshape(-1, 6)


def flattened(project, trains: Boards, values: FloatArray, poses: FloatArray) -> Boards:  # type: ignore[no-untyped-def]
    """The training corners moved to where a flat board at each fitted pose would have put them."""
    span = float(max(np.ptp(g) for _, g in trains))
    shape, out = board_shape(values, span), []
    for (pixels, grid), pose in zip(trains, poses, strict=True):
        turn = Rotation.from_rotvec(pose[:3])
        flat = np.column_stack([grid.astype(np.float64), np.zeros(len(grid))])
        out.append((pixels + project(turn.apply(flat) + pose[3:]) - project(turn.apply(shape(grid)) + pose[3:]), grid))
    return out


def difference_noise(boards: Boards, order: int) -> float:
    """The corners' noise sigma (px) from ``order``-th differences along the boards' rows and columns."""
    weight = float(sum(math.comb(order, k) ** 2 for k in range(order + 1)))  # 20 for order 3, 70 for 4
    taps = np.array([(-1) ** (order - k) * math.comb(order, k) for k in range(order + 1)], dtype=np.float64)
    values = []
    for pixels, grid in boards:
        at = {(int(a), int(b)): p for (a, b), p in zip(grid, pixels, strict=True)}
        for a, b in at:
            for step in ((1, 0), (0, 1)):
                run = [at.get((a + k * step[0], b + k * step[1])) for k in range(order + 1)]
                if all(p is not None for p in run):
                    values.append(taps @ np.array(run))
    diffs = np.array(values)
    return float(np.sqrt(np.mean(diffs**2) / weight))


def board_local_share(residuals: list[FloatArray], boards: Boards) -> tuple[float, float]:
    """The share of the residuals' squares an affine + quadratic map of each board's grid explains, and the
    share pure noise would give (12 values a board over its 2n residuals)."""
    explained = total = expected = 0.0
    for res, (_, grid) in zip(residuals, boards, strict=True):
        g = (grid - grid.mean(axis=0)) / max(float(np.ptp(grid)), 1.0)
        design = np.column_stack([np.ones(len(g)), g, g**2, g[:, 0] * g[:, 1]])
        coef, *_ = np.linalg.lstsq(design, res, rcond=None)
        explained += float(np.sum((design @ coef) ** 2))
        total += float(np.sum(res**2))
        expected += 12.0 / (2 * len(g)) * float(np.sum(res**2))
    return explained / total, expected / total


def field_design(offsets: FloatArray, scale: float, degree: int, lowest: int = 1) -> FloatArray:
    """Monomials x^i y^j, lowest <= i + j <= degree, of the offsets (n, 2) / scale: (n, terms)."""
    x, y = (offsets / scale).T
    return np.column_stack([x**i * y ** (d - i) for d in range(lowest, degree + 1) for i in range(d + 1)])


def with_field(project, centre, scale, degree, coef, lowest=1):  # type: ignore[no-untyped-def]
    """The camera's pixels moved by the field (coef: terms x 2) at them."""

    def moved(points: FloatArray) -> FloatArray:
        pixels = project(points)
        return pixels - field_design(pixels - centre, scale, degree, lowest) @ coef

    return moved


def field_fit(project, residuals, trains, centre, scale, degree, ridge, lowest=1):  # type: ignore[no-untyped-def]
    """The field (terms, 2) a ridge fit finds in the training residuals (model minus detection) at the detections."""
    design = np.concatenate([field_design(p - centre, scale, degree, lowest) for p, _ in trains])
    target = np.concatenate(residuals)
    gram = design.T @ design + ridge * len(design) * np.eye(design.shape[1])
    return np.linalg.solve(gram, design.T @ target)


def rms(residuals: list[FloatArray]) -> float:
    return float(np.sqrt(np.mean(np.concatenate(residuals) ** 2) * 2))


def structure_line(held: list[FloatArray], tests: Boards, centre: FloatArray) -> str:
    """The held-out residuals' radial and tangential parts (per axis), by ring of radius, by board, and the
    share each board's own smooth map explains."""
    radial, tangential, radii = [], [], []
    for res, (pixels, _) in zip(held, tests, strict=True):
        d = pixels - centre
        r = np.hypot(*d.T)
        e = d / r[:, None]
        radial.append(np.sum(res * e, axis=1))
        tangential.append(res[:, 0] * -e[:, 1] + res[:, 1] * e[:, 0])
        radii.append(r)
    rad, tan, rr = np.concatenate(radial), np.concatenate(tangential), np.concatenate(radii)
    by_ring = []
    for lo, hi in itertools.pairwise(np.quantile(rr, [0, 1 / 3, 2 / 3, 1])):
        on = (rr >= lo) & (rr <= hi)
        by_ring.append(f"{lo:.0f}-{hi:.0f} px {math.sqrt(np.mean(rad[on] ** 2 + tan[on] ** 2)):.3f}")
    share, expected = board_local_share(held, tests)
    per_board = ", ".join(f"{math.sqrt(np.mean(r**2) * 2):.2f}" for r in held)
    return (
        f"held-out {rms(held):.3f} px (radial {math.sqrt(np.mean(rad**2)):.3f}, tangential "
        f"{math.sqrt(np.mean(tan**2)):.3f} per axis); by ring {'; '.join(by_ring)}; per board [{per_board}]; "
        f"board-local share {share:.2f} (noise alone {expected:.2f})"
    )


def field_line(project, lift, seen, trains: Boards, tests: Boards, centre: FloatArray, cv2) -> str:  # type: ignore[no-untyped-def]
    """The held-out RMS with an image field fitted to the even images' residuals, by degree and ridge."""
    scale = float(max(np.hypot(*(p - centre).T).max() for p, _ in trains + tests))
    cells = []
    for degree, lowest in ((1, 1), (2, 1), (3, 1), (4, 1), (2, 2), (3, 2), (4, 2)):
        for ridge in (1e-4, 1e-2):
            coef = field_fit(project, seen, trains, centre, scale, degree, ridge, lowest)
            moved = with_field(project, centre, scale, degree, coef, lowest)
            cells.append(f"deg {lowest}-{degree} ridge {ridge:g}: {rms(fitted_residuals(moved, lift, tests, cv2)):.3f}")
    return f"image field fitted to the even images' residuals, held-out: {'; '.join(cells)}"


def field_folds_line(trains: Boards, refit, cv2) -> str:  # type: ignore[no-untyped-def]
    """Would the rule of :mod:`panomap.calibrate.boards.terms` keep the image field? The even images dealt into 5
    folds: the camera refitted to every fold but one (``refit``: boards -> fit), the field fitted to its
    residuals, each left-out image's mean squared distance with and without it; kept (KEPT) where the mean gain
    exceeds one standard error and the folds' RMS falls 3%."""
    folds = min(5, len(trains))
    variants = [(d, lo, r) for d, lo in ((2, 2), (3, 2), (4, 2), (1, 1), (3, 1), (4, 1)) for r in (1e-4, 1e-2)]
    base: list[float] = []
    withs: dict[tuple[int, int, float], list[float]] = {v: [] for v in variants}
    counts: list[int] = []
    for k in range(folds):
        inside = [b for j, b in enumerate(trains) if j % folds != k]
        out = [b for j, b in enumerate(trains) if j % folds == k]
        fit = refit(inside)
        project, lift = panomap_camera(fit)
        centre = np.asarray(fit.model.centre, dtype=np.float64)
        scale = float(max(np.hypot(*(p - centre).T).max() for p, _ in trains))
        seen = fitted_residuals(project, lift, inside, cv2)
        base += [float(np.sum(r**2)) for r in fitted_residuals(project, lift, out, cv2)]
        counts += [len(p) for p, _ in out]
        for degree, lowest, ridge in variants:
            coef = field_fit(project, seen, inside, centre, scale, degree, ridge, lowest)
            moved = with_field(project, centre, scale, degree, coef, lowest)
            withs[(degree, lowest, ridge)] += [float(np.sum(r**2)) for r in fitted_residuals(moved, lift, out, cv2)]
    n, b = np.array(counts, dtype=np.float64), np.array(base)
    cells = [f"none {math.sqrt(b.sum() / n.sum()):.3f}"]
    for (degree, lowest, ridge), values in withs.items():
        w = np.array(values)
        gains = b / n - w / n
        held = math.sqrt(w.sum() / n.sum())
        kept = gains.mean() > gains.std(ddof=1) / math.sqrt(gains.size) and held <= 0.97 * cells_rms(b, n)
        cells.append(f"deg {lowest}-{degree} ridge {ridge:g} {held:.3f}{' KEPT' if kept else ''}")
    return f"image field in 5 folds of the even images (the rule of terms.py): {'; '.join(cells)}"


def cells_rms(squares: FloatArray, counts: FloatArray) -> float:
    return math.sqrt(squares.sum() / counts.sum())


def shape_lines(project, lift, trains: Boards, tests: Boards, refit, cv2) -> list[str]:  # type: ignore[no-untyped-def]
    """The held-out RMS with the board's shape fitted to the even images (the camera held), and with the camera
    refitted (``refit``: boards -> (project, lift)) to the corners a flat board would have given, alternated."""
    span = float(max(np.ptp(g) for _, g in trains))
    cells = []
    for count, what in ((1, "print aspect"), (4, "+ bend deg 2"), (8, "+ deg 3")):
        values, poses = shape_fit(project, lift, trains, cv2, count)
        held_shaped = rms(fitted_residuals(project, lift, tests, cv2, board_shape(values, span)))
        cells.append(f"{what} {held_shaped:.3f} ({', '.join(f'{v:.4f}' for v in values)})")
    out = [f"the board's shape fitted to the even images (camera held), held-out with it: {'; '.join(cells)}"]
    values, poses = shape_fit(project, lift, trains, cv2, 4)
    cells = []
    for _ in range(3):  # the camera refitted to the corners a flat board would have given, then the shape
        project, lift = refit(flattened(project, trains, values, poses))
        values, poses = shape_fit(project, lift, trains, cv2, 4)
        flat_rms = rms(fitted_residuals(project, lift, tests, cv2))
        bent_rms = rms(fitted_residuals(project, lift, tests, cv2, board_shape(values, span)))
        cells.append(f"flat {flat_rms:.3f} / bent {bent_rms:.3f}")
    out.append(f"camera and bend (deg 2) alternated on the even images, held-out: {'; '.join(cells)}")
    return out


def measure(folder: Path, cv2, folds_only: bool = False) -> None:  # type: ignore[no-untyped-def]
    from panomap.calibrate.boards.detect import Board
    from panomap.calibrate.boards.fit import fit_boards
    from panomap.calibrate.lines.fit import LineFitOptions
    from panomap.calibrate.lines.frame_circles import line_circles
    from panomap.io.images import read_image

    names, boards = set_boards(folder)
    trains, tests = [boards[n] for n in names[0::2]], [boards[n] for n in names[1::2]]
    circles = line_circles(read_image(folder / "images" / names[0]))
    everything = trains + tests
    n_mean = np.mean([len(p) for p, _ in everything])
    sigmas = [difference_noise(everything, order) for order in (3, 4, 5)]
    floor = math.sqrt(2.0) * sigmas[-1] * math.sqrt(1 - 6 / (2 * n_mean))
    print(
        f"  {folder.name}: the corners' noise sigma (3rd / 4th / 5th differences) "
        f"{' / '.join(f'{s:.3f}' for s in sigmas)} px per axis; the held-out RMS a pose fit leaves of it {floor:.3f} px"
    )
    for terms in ("auto",) if folds_only else ("auto", "none"):

        def refit(these: Boards, terms: str = terms):  # type: ignore[no-untyped-def]
            options = LineFitOptions(terms=terms)
            return fit_boards([Board(k, p, g) for k, (p, g) in enumerate(these)], circles, options)

        fit = refit(trains)
        project, lift = panomap_camera(fit)
        held, seen = fitted_residuals(project, lift, tests, cv2), fitted_residuals(project, lift, trains, cv2)
        centre = np.asarray(fit.model.centre, dtype=np.float64)
        kept = "+".join(fit.report.terms.kept) if fit.report.terms else "-"
        print(f"    terms {terms} ({fit.report.model}, kept {kept or 'none'}), in-sample {rms(seen):.3f} px: ", end="")
        print(structure_line(held, tests, centre))
        print(f"      {field_line(project, lift, seen, trains, tests, centre, cv2)}")
        print(f"      {field_folds_line(trains, refit, cv2)}")
        if folds_only:
            continue
        for line in shape_lines(project, lift, trains, tests, lambda b, f=refit: panomap_camera(f(b)), cv2):
            print(f"      {line}")


def drift(folder: Path) -> None:
    """Where the camera fitted to all of the set's corners with its terms (``auto``) and without (``none``)
    departs from the set's established calibration: the best rotation of the frame fitted over the boards'
    radii, the distances (px, p50 / p90 / max) inside them and beyond (nearer the centre, farther out, to the
    image circle)."""
    from bench_boards import calibration_boards, reference_of
    from bench_lines import best_orthogonal, camera_frame_pixels, camera_frame_rays, corner_radii, ring_grid
    from panomap.calibrate.boards.fit import fit_boards
    from panomap.calibrate.lines.fit import LineFitOptions
    from panomap.calibrate.lines.frame_circles import line_circles
    from panomap.io.images import read_image

    paths = sorted((folder / "images").iterdir())
    image = read_image(paths[0])
    size = (image.shape[1], image.shape[0])
    circles = line_circles(image)
    centre, reference = reference_of(folder)
    r_min, r_max, _ = corner_radii(folder, centre)
    outer = float(circles.outer_radius)
    bands = {
        "inside": ring_grid(centre, r_min, r_max, size),
        f"nearer ({r_min * 0.5:.0f}-{r_min:.0f} px)": ring_grid(centre, r_min * 0.5, r_min, size),
        f"just beyond ({r_max:.0f}-{min(1.25 * r_max, outer):.0f} px)": ring_grid(
            centre, r_max, min(1.25 * r_max, outer), size
        ),
        f"farther ({r_max:.0f}-{outer:.0f} px)": ring_grid(centre, r_max, outer, size),
    }
    for terms in ("auto", "none"):
        fit = fit_boards(calibration_boards(folder, [p.name for p in paths]), circles, LineFitOptions(terms=terms))
        inside = bands["inside"]
        ref, mine = reference(inside), camera_frame_rays(fit.model, inside)
        ok = np.all(np.isfinite(ref), axis=1) & np.all(np.isfinite(mine), axis=1)
        q = best_orthogonal(ref[ok], mine[ok])
        cells = []
        for name, pixels in bands.items():
            error = np.hypot(*(camera_frame_pixels(fit.model, reference(pixels) @ q.T) - pixels).T)
            error = error[np.isfinite(error)]
            cells.append(f"{name} {np.percentile(error, 50):.2f} / {np.percentile(error, 90):.2f} / {error.max():.2f}")
        kept = "+".join(fit.report.terms.kept) if fit.report.terms else "-"
        print(f"    drift from the established calibration, terms {terms} (kept {kept or 'none'}): {'; '.join(cells)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[1].parent / "shared/data/real")
    parser.add_argument("--contrib", type=Path, default=Path("/tmp/contrib"))
    parser.add_argument("--only", help="one set (its folder's name)")
    parser.add_argument("--folds", action="store_true", help="only the image field, and its fold test")
    parser.add_argument("--drift", action="store_true", help="only the drift from the established calibrations")
    args = parser.parse_args()
    cv2 = load_cv2(args.contrib)
    for folder in sorted(p for p in args.data.iterdir() if p.is_dir()):
        if args.only is None or args.only == folder.name:
            if args.drift:
                print(f"  {folder.name}")
                drift(folder)
            else:
                measure(folder, cv2, args.folds)


if __name__ == "__main__":
    main()
