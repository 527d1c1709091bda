"""The table file: round trip, and every way it can be wrong."""

from __future__ import annotations

import io
import json
import math
import re
import zipfile
from pathlib import Path

import numpy as np
import pytest

from panomap.camera.model import CameraModel
from panomap.camera.radial import RadialFunction
from panomap.errors import PanomapError
from panomap.table.file import _digest, load_table, metadata_digest, save_table
from panomap.table.table import PanoMappingTable, fill_entries

from helpers import assert_one_line_error, run


def small_table() -> PanoMappingTable:
    model = CameraModel((320.5, 240.25), RadialFunction("unified", (250.0, 0.8), "down"), -1, 0.3)
    rng = (-math.radians(80), math.radians(5))
    return PanoMappingTable(
        fill_entries(model, (64, 16), rng),
        rng,
        model,
        (1.0, 2.0, 2.5),
        (640, 480),
        30.0,
        240.0,
        info={"sources": {"centre": "given"}},
    )


def rewrite(path: Path, meta_change: dict | None = None, entries: np.ndarray | None = None, seal: bool = True) -> None:
    """Change the metadata (and the entries); ``seal``: with a metadata checksum that matches, as an
    editor who knows the format would, so that what is checked behind the checksum shows."""
    with np.load(path) as archive:
        meta = json.loads(str(archive["meta"][()]))
        stored = archive["entries"]
    meta.update(meta_change or {})
    if seal and "metadata_sha256" in meta:
        meta["metadata_sha256"] = metadata_digest(meta)
    np.savez(path, entries=stored if entries is None else entries, meta=np.array(json.dumps(meta)))


def test_round_trip_keeps_everything(tmp_path: Path) -> None:
    table = small_table()
    save_table(table, tmp_path / "t.npz")
    loaded = load_table(tmp_path / "t.npz")
    np.testing.assert_array_equal(loaded.entries, table.entries)
    assert loaded.model == table.model
    assert loaded.elevation_range == table.elevation_range
    assert loaded.image_size == (640, 480) and loaded.camera_position == (1.0, 2.0, 2.5)
    assert (loaded.cutoff_radius, loaded.outer_radius) == (30.0, 240.0)
    assert loaded.info == table.info


def test_save_leaves_no_temporary_files(tmp_path: Path) -> None:
    save_table(small_table(), tmp_path / "t.npz")
    assert [p.name for p in tmp_path.iterdir()] == ["t.npz"]


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(PanomapError, match=r"t\.npz: no such table file"):
        load_table(tmp_path / "t.npz")


@pytest.mark.parametrize("keep", [0.1, 0.5, 0.95])
def test_truncated_file(tmp_path: Path, keep: float) -> None:
    path = tmp_path / "t.npz"
    save_table(small_table(), path)
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * keep)])
    with pytest.raises(PanomapError, match="corrupt or truncated"):
        load_table(path)


def test_not_a_table(tmp_path: Path) -> None:
    path = tmp_path / "t.npz"
    path.write_text("u,v,X,Y,Z\n")
    with pytest.raises(PanomapError, match=r"not a panomap table \(not a .npz archive; panomap import"):
        load_table(path)
    path.write_bytes(b"")
    with pytest.raises(PanomapError, match=r"not a panomap table \(an empty file"):
        load_table(path)
    np.savez(path, something=np.zeros(3))
    with pytest.raises(PanomapError, match="not a panomap table"):
        load_table(path)


def test_other_version(tmp_path: Path) -> None:
    path = tmp_path / "t.npz"
    save_table(small_table(), path)
    rewrite(path, {"version": 6})
    with pytest.raises(PanomapError, match="version 6; this panomap reads versions 1, 2, 3, 4 and 5"):
        load_table(path)


@pytest.mark.parametrize(("version", "shown"), [(None, "None"), (True, "True"), ("2", "'2'"), (2.0, "2.0")])
def test_a_version_missing_or_not_an_integer_is_refused_in_one_line(
    tmp_path: Path, version: object, shown: str
) -> None:
    """No version, JSON true (which Python would take for 1), "2" or 2.0 (equal to 2 in Python): refused, by the
    library and by the command line in one line naming the file."""
    path = tmp_path / "t.npz"
    save_table(small_table(), path)
    with np.load(path) as archive:
        meta = json.loads(str(archive["meta"][()]))
        entries = archive["entries"]
    if version is None:
        del meta["version"]
    else:
        meta["version"] = version
    meta["metadata_sha256"] = metadata_digest(meta)
    np.savez(path, entries=entries, meta=np.array(json.dumps(meta)))
    message = f"table format version {shown}; this panomap reads versions 1, 2, 3, 4 and 5"
    with pytest.raises(PanomapError, match=re.escape(message)):
        load_table(path)
    assert_one_line_error(run("info", path), f"{path}: ", message, exit_code=1)


def test_flipped_byte_in_entries_is_caught_by_the_checksum(tmp_path: Path) -> None:
    path = tmp_path / "t.npz"
    save_table(small_table(), path)
    with np.load(path) as archive:
        entries = archive["entries"].copy()
    entries[3, 4, 0] += 0.5
    rewrite(path, entries=entries)
    with pytest.raises(PanomapError, match="checksum"):
        load_table(path)


def test_entries_that_disagree_with_the_model(tmp_path: Path) -> None:
    path = tmp_path / "t.npz"
    table = small_table()
    save_table(table, path)
    with np.load(path) as archive:
        meta = json.loads(str(archive["meta"][()]))
    # Same entries, but a model with another centre, and a checksum that matches the entries.
    meta["model"]["centre"] = [300.0, 240.25]
    rewrite(path, meta)
    with pytest.raises(PanomapError, match="disagree with the table's own model"):
        load_table(path)


@pytest.mark.parametrize(("row", "change"), [(0, 0.05), (300, -0.05), (599, 0.05), (450, math.nan)])
def test_one_entry_off_in_any_block_of_azimuths_is_caught(tmp_path: Path, row: int, change: float) -> None:
    """The model check runs 256 azimuths at a time: an entry in any block, the last one included, counts."""
    model = CameraModel((320.5, 240.25), RadialFunction("unified", (250.0, 0.8), "down"), -1, 0.3)
    rng = (-math.radians(80), math.radians(5))
    table = PanoMappingTable(fill_entries(model, (600, 16), rng), rng, model, (1.0, 2.0, 2.5), (640, 480), 30.0, 240.0)
    path = tmp_path / "t.npz"
    save_table(table, path)
    load_table(path)  # as written: fine
    entries = table.entries.copy()
    entries[row, 7, 1] += change
    rewrite(path, {"entries_sha256": _digest(entries)}, entries)
    with pytest.raises(PanomapError, match="disagree with the table's own model"):
        load_table(path)


def test_entries_are_the_closed_form_and_some_azimuths_are_those_rows() -> None:
    """Algorithm 2 written out for small_table's model: theta_i = 2 pi i / M, rho_j = rho_s + j
    (rho_e - rho_s) / N, alpha = rho + pi/2 from the downward axis, r = 250 sin(alpha) / (0.8 +
    cos(alpha)) (unified), phi = -theta + 0.3; float32 entries (1e-4 px at these radii)."""
    table = small_table()
    (m, n), (rho_s, rho_e) = table.size, table.elevation_range
    theta = 2 * np.pi * np.arange(m) / m
    alpha = rho_s + np.arange(n) * (rho_e - rho_s) / n + np.pi / 2
    r = 250.0 * np.sin(alpha) / (0.8 + np.cos(alpha))
    phi = -theta + 0.3
    expected = np.stack(
        [320.5 + np.cos(phi)[:, None] * r[None, :], 240.25 + np.sin(phi)[:, None] * r[None, :]], axis=-1
    )
    np.testing.assert_allclose(table.entries, expected, rtol=0, atol=1e-4)
    some = fill_entries(table.model, table.size, table.elevation_range, slice(10, 37))
    np.testing.assert_allclose(some, expected[10:37], rtol=0, atol=1e-4)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"size": [64, 17]}, "metadata says"),
        ({"model": {"centre": [1, 2]}}, "malformed"),
        ({"model": None}, "malformed"),
        ({"elevation_range_rad": [0.5, 0.1]}, "not an interval"),
        ({"format": "other"}, "wrong format"),
    ],
)
def test_malformed_metadata(tmp_path: Path, change: dict, message: str) -> None:
    path = tmp_path / "t.npz"
    save_table(small_table(), path)
    rewrite(path, change)
    with pytest.raises(PanomapError, match=message):
        load_table(path)


def test_metadata_that_is_not_json(tmp_path: Path) -> None:
    path = tmp_path / "t.npz"
    save_table(small_table(), path)
    with np.load(path) as archive:
        entries = archive["entries"]
    buffer = io.BytesIO()
    np.savez(buffer, entries=entries, meta=np.array("{not json"))
    path.write_bytes(buffer.getvalue())
    assert zipfile.is_zipfile(path)
    with pytest.raises(PanomapError, match="not valid JSON"):
        load_table(path)
