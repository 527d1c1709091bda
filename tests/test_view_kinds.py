"""A view kind is declared once: its spec keys, its command's options and their older names all come from it."""

from __future__ import annotations

import math

import click
import numpy as np
import pytest

from panomap.camera.model import CameraModel
from panomap.camera.radial import RadialFunction
from panomap.cli.app import COMMANDS
from panomap.cli.views import make_view
from panomap.errors import PanomapError
from panomap.geometry import azimuth_elevation
from panomap.table.table import PanoMappingTable, fill_entries
from panomap.views import GenericPanorama, View, view_kinds
from panomap.views.base import ParameterError, Value
from panomap.views.spec import KINDS, parse_view_spec, view_from_params

SHARED = {"table", "images", "output", "save_map", "each", "save_map_pgm", "quiet", "interp", "table_sampling"}
# The flags the README and docs have always used: each must stay an alias of its parameter.
LEGACY = {
    "--start-deg": ("panorama", "start"),
    "--plane-width": ("plane", "width"),
    "--azimuth-deg": ("plane", "azimuth"),
    "--yaw-deg": ("perspective", "yaw"),
    "--pitch-deg": ("perspective", "pitch"),
    "--roll-deg": ("perspective", "roll"),
    "--fov-deg": ("perspective", "fov"),
}
COMMAND = {command.name: command for command in COMMANDS}


def kind_options(kind: str) -> list[click.Option]:
    return [p for p in COMMAND[kind].params if isinstance(p, click.Option) and p.name not in SHARED]


def example_args(cls: type[View], legacy: bool) -> list[str]:
    """The kind's example spec as command-line arguments, under the new names or the older ones."""
    declared = {param.name: param for param in cls.params}
    args = []
    for item in cls.example.split(","):
        key, _, value = item.partition("=")
        param = declared[key]
        flag = param.aliases[0] if legacy and param.aliases else f"--{key}"
        args += [flag, *(value.split(":") if param.value is Value.PAIR else [value])]
    return args


def view_from_command(kind: str, args: list[str]) -> View:
    """Parse ``args`` as the kind's command does, and build its view, without reading or writing files."""
    with COMMAND[kind].make_context(kind, ["cam.npz", "omni.png", "-o", "out.png", *args]) as ctx:
        return make_view(kind, {name: value for name, value in ctx.params.items() if name not in SHARED})


def test_every_kind_is_one_file_registered_once_in_the_order_of_the_commands() -> None:
    assert KINDS == tuple(view_kinds()) == ("panorama", "cylinder", "plane", "perspective", "floor", "equirect")
    for kind, cls in view_kinds().items():
        assert cls.kind == kind
        assert cls.__module__ == f"panomap.views.{kind}"
    assert [name for name in COMMAND if name in view_kinds()] == list(view_kinds())


@pytest.mark.parametrize("kind", list(view_kinds()))
def test_every_kind_has_a_command_whose_options_are_its_declared_parameters(kind: str) -> None:
    cls = view_kinds()[kind]
    options = kind_options(kind)
    assert [option.name for option in options] == [param.name for param in cls.params]
    for option, param in zip(options, cls.params, strict=True):
        assert option.opts == [f"--{param.name}", *param.aliases]
        assert option.required == param.required
        assert option.nargs == (2 if param.value is Value.PAIR else 1)
        assert option.help == param.help
    assert COMMAND[kind].help == cls.summary


@pytest.mark.parametrize("kind", list(view_kinds()))
def test_every_kind_takes_its_declared_parameters_as_spec_keys(kind: str) -> None:
    names = sorted(param.name for param in view_kinds()[kind].params)
    with pytest.raises(PanomapError, match=rf"a {kind} view has no key nokey \(keys: {', '.join(names)}\)"):
        view_from_params(kind, {"nokey": "1"})
    required = [param.name for param in view_kinds()[kind].params if param.required]
    if required:
        with pytest.raises(PanomapError, match=f"a {kind} view needs {', '.join(f'{key}=' for key in required)}"):
            view_from_params(kind, {})


@pytest.mark.parametrize("kind", list(view_kinds()))
def test_a_spec_the_options_and_their_older_names_build_the_same_view(kind: str) -> None:
    cls = view_kinds()[kind]
    from_spec = parse_view_spec(f"{kind}:{cls.example}")[1]
    assert type(from_spec) is cls and from_spec.kind == kind
    assert view_from_command(kind, example_args(cls, legacy=False)) == from_spec
    assert view_from_command(kind, example_args(cls, legacy=True)) == from_spec


def test_the_documented_older_flags_are_still_aliases() -> None:
    for flag, (kind, name) in LEGACY.items():
        (option,) = [option for option in kind_options(kind) if option.name == name]
        assert flag in option.opts
    # Degrees on the command line, under either name; radians in the view.
    view = view_from_command("perspective", ["--yaw-deg", "30", "--pitch", "-20", "--fov-deg", "90", "--size", "8x6"])
    assert view == parse_view_spec("perspective:yaw=30,pitch=-20,fov=90,size=8x6")[1]
    assert view.yaw_rad == math.radians(30)  # type: ignore[attr-defined]


def test_size_errors_speak_the_callers_words() -> None:
    message = "0x5: width and height must be positive"
    with pytest.raises(ParameterError, match=f"^size {message}$"):
        GenericPanorama((0, 5))
    with pytest.raises(PanomapError, match=f"^view spec 'panorama:size=0x5': size {message}$"):
        parse_view_spec("panorama:size=0x5")
    # On the command line a size out of range is a usage error (exit 2) under its option's name.
    with pytest.raises(click.BadParameter, match=f"^{message}$") as raised:
        view_from_command("panorama", ["--size", "0x5"])
    assert raised.value.param_hint == "'--size'"


def test_one_of_two_parameters_is_required_in_the_callers_words() -> None:
    with pytest.raises(PanomapError, match="a floor view needs size=WxH or resolution=R, one of the two"):
        parse_view_spec("floor:z=0,x=0:6,y=0:5")
    with pytest.raises(PanomapError, match="a floor view needs size=WxH or resolution=R, one of the two"):
        parse_view_spec("floor:z=0,x=0:6,y=0:5,size=6x5,resolution=1")
    with pytest.raises(click.UsageError, match="give the output size as --size WxH or --resolution R, one of the two"):
        view_from_command("floor", ["--z", "0", "--x", "0", "6", "--y", "0", "5"])
    assert view_from_command("floor", ["--z", "0", "--x", "0", "6", "--y", "0", "5", "--resolution", "1"]).size == (
        6,
        5,
    )


def table_at(position: tuple[float, float, float]) -> PanoMappingTable:
    """An equidistant camera looking down, r = 100 alpha, elevation -90..0 deg, at ``position``."""
    model = CameraModel((50.0, 60.0), RadialFunction("odd1", (100.0,), "down"))
    elevations = (-math.pi / 2, 0.0)
    return PanoMappingTable(fill_entries(model, (8, 4), elevations), elevations, model, position, None, 0.0, 160.0)


@pytest.mark.parametrize("kind", list(view_kinds()))
def test_views_of_a_surface_give_its_points_relative_to_the_camera(kind: str) -> None:
    """Every view of a surface gives points relative to O_m, whose angles are the view's; others give None."""
    table = table_at((3.1, 2.4, 2.45))
    view = parse_view_spec(f"{kind}:{view_kinds()[kind].example}")[1]
    points = view.points(table)
    if kind in ("panorama", "perspective", "equirect"):
        assert points is None  # they see directions, not a surface
        return
    assert points is not None
    theta, rho = view.angles(table)
    theta_seen, rho_seen = azimuth_elevation(points)
    # float32 angles (perspective and floor) round to about 2.4e-7 rad.
    assert np.max(np.abs(np.angle(np.exp(1j * (theta_seen - theta))))) < 2e-6
    assert np.max(np.abs(rho_seen - rho)) < 2e-6


def test_every_angle_in_the_python_api_says_its_unit() -> None:
    """A view's angle fields are named ``..._rad`` (issue 14: ``PlaneView(..., azimuth=90)`` was 90 rad,
    silently); the specs and the command line keep their degree names. Positional use still works."""
    from dataclasses import fields

    from panomap.views import Band, CylinderPanorama, PerspectiveView, PlaneView

    angle_params = {kind: {p.name for p in cls.params if p.value is Value.ANGLE} for kind, cls in view_kinds().items()}
    assert angle_params == {
        "panorama": {"start"},
        "cylinder": {"start"},
        "plane": {"azimuth"},
        "perspective": {"yaw", "pitch", "roll", "fov"},
        "equirect": {"yaw", "pitch", "roll"},
        "floor": set(),
    }
    named = {
        kind: [f.name for f in fields(cls) if f.name.endswith(("_rad", "_deg"))] for kind, cls in view_kinds().items()
    }  # type: ignore[arg-type]
    assert named == {
        "panorama": ["theta_start_rad"],
        "cylinder": ["theta_start_rad"],
        "plane": ["azimuth_rad"],
        "perspective": ["yaw_rad", "pitch_rad", "roll_rad", "fov_rad"],
        "floor": [],
        "equirect": ["yaw_rad", "pitch_rad", "roll_rad"],
    }
    band = Band(-1.0, 0.5)
    # The unitless names, and degree names, are not taken: the caller must say radians.
    for make in (
        lambda: PlaneView(2.0, 2.0, band, azimuth=90, size=(10, 10)),  # type: ignore[call-arg]
        lambda: PlaneView(2.0, 2.0, band, azimuth_deg=90, size=(10, 10)),  # type: ignore[call-arg]
        lambda: PerspectiveView(yaw=0.0, pitch=0.0, roll=0.0, fov=1.0, size=(10, 10)),  # type: ignore[call-arg]
        lambda: GenericPanorama((10, 10), theta_start=1.0),  # type: ignore[call-arg]
        lambda: CylinderPanorama(2.0, band, (10, 10), theta_start=1.0),  # type: ignore[call-arg]
    ):
        with pytest.raises(TypeError, match="unexpected keyword argument"):
            make()
    # Positional use is unchanged, and a field of view or a pitch given in degrees is out of range.
    view = PlaneView(2.0, 2.0, band, math.radians(90), (10, 10))
    spec = {"distance": 2, "width": 2, "band": (-1, 0.5), "azimuth": 90, "size": (10, 10)}
    assert view == view_from_params("plane", spec)  # the spec's azimuth=90 is in degrees
    with pytest.raises(
        PanomapError, match=r"field of view must be more than 0 and less than 180 deg, not 5156\.62 deg"
    ):
        PerspectiveView(0.0, 0.0, 0.0, 90.0, (10, 10))
    with pytest.raises(PanomapError, match="pitch must be between -90 and 90 deg"):
        PerspectiveView(0.0, -30.0, 0.0, 1.0, (10, 10))
