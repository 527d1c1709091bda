"""The package's layers: every module imports on its own, and no layer imports one above it.

The order, lowest first (STYLE.md, habit 17: layers never climb):

    errors, geometry, files < camera < table, remap < views < rig < interop < calibrate < io < video
    < learn, viewer < batch < cli

A module may import its own layer and the ones below. ``simulate`` is the ground truth, outside
the chain: it imports only ``errors`` and ``geometry``, and only the command line (the demo) uses
it. ``panomap/__init__.py`` (the lazy export list) and ``panomap/__main__.py`` are exempt.
"""

from __future__ import annotations

import ast
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import panomap

PACKAGE = Path(panomap.__file__).resolve().parent

LAYERS = [
    {"errors", "geometry", "files", "values", "inputs", "strips", "robust"},
    {"camera"},
    {"table", "remap"},
    {"views"},
    {"rig"},
    {"interop"},
    {"calibrate"},
    {"io"},
    {"video"},
    {"learn", "viewer"},
    {"batch"},
    {"cli"},
]
RANK = {name: rank for rank, names in enumerate(LAYERS) for name in names}
GROUND_TRUTH = "simulate"
GROUND_TRUTH_MAY_IMPORT = {"errors", "geometry"}
GROUND_TRUTH_USED_BY = {"cli"}
EXEMPT = {"panomap", "panomap.__main__"}

# Known climbs that another part of the restructuring removes; delete each once it has merged.
KNOWN_EXCEPTIONS: set[tuple[str, str]] = set()


def module_name(path: Path) -> str:
    parts = ("panomap", *path.relative_to(PACKAGE).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(path): path for path in sorted(PACKAGE.rglob("*.py"))}


def imported_modules(name: str, path: Path) -> set[str]:
    """Every panomap module ``name`` imports, at the top or inside functions, absolute or relative.

    ``from panomap import X`` counts as an import of the module that defines X (the export list).
    """
    is_package = path.name == "__init__.py"
    package = name if is_package else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                target = ".".join([*base, node.module] if node.module else base)
            else:
                target = node.module or ""
            for alias in node.names:
                # ``from .x import y``: y is a name in x, or a submodule of it.
                submodule = f"{target}.{alias.name}"
                if submodule in MODULES:
                    found.add(submodule)
                elif target == "panomap" and alias.name in panomap._EXPORTS:
                    found.add(f"panomap.{panomap._EXPORTS[alias.name]}")
                else:
                    found.add(target)
    return {module for module in found if module == "panomap" or module.startswith("panomap.")}


def layer(module: str) -> str:
    """``panomap.calibrate.landmarks.fit`` -> ``calibrate``; ``panomap.errors`` -> ``errors``."""
    return module.split(".")[1]


def climbs(importer: str, imported: str) -> str | None:
    """Why ``importer`` may not import ``imported``, or None if it may."""
    if importer in EXEMPT or imported in EXEMPT:
        return None
    low, high = layer(imported), layer(importer)
    if low == high:
        return None
    if high == GROUND_TRUTH:
        return None if low in GROUND_TRUTH_MAY_IMPORT else "the ground truth imports the code under test"
    if low == GROUND_TRUTH:
        return None if high in GROUND_TRUTH_USED_BY else "the library uses the ground truth"
    if high not in RANK or low not in RANK:
        return f"{high if high not in RANK else low!r} is in no declared layer (add it to LAYERS)"
    if RANK[low] > RANK[high]:
        return f"{high} (layer {RANK[high]}) reaches up to {low} (layer {RANK[low]})"
    return None


def test_every_module_is_in_a_declared_layer() -> None:
    unknown = sorted(
        name for name in MODULES if name not in EXEMPT and layer(name) not in RANK and layer(name) != GROUND_TRUTH
    )
    assert unknown == [], f"modules in no declared layer: {unknown}"


def test_layers_never_climb() -> None:
    violations = []
    seen = set()
    for importer, path in MODULES.items():
        for imported in sorted(imported_modules(importer, path)):
            reason = climbs(importer, imported)
            if reason is not None:
                seen.add((importer, imported))
                if (importer, imported) not in KNOWN_EXCEPTIONS:
                    violations.append(f"{importer} imports {imported}: {reason}")
    print("\n".join(["layer violations:", *violations]) if violations else "no layer violation")
    assert violations == [], "\n".join(violations)
    # A known exception that no longer happens must be removed from the list.
    assert KNOWN_EXCEPTIONS <= seen, f"no longer needed: {sorted(KNOWN_EXCEPTIONS - seen)}"


def test_the_import_scanner_reads_relative_lazy_and_package_imports() -> None:
    # Pins what the layer check reads: a relative import two levels up, an import inside a
    # function, and a name imported from the package (resolved through its export list).
    assert "panomap.calibrate.landmarks.pairs" in imported_modules(
        "panomap.learn.session", MODULES["panomap.learn.session"]
    )
    assert "panomap.cli.app" in imported_modules("panomap.__main__", MODULES["panomap.__main__"])
    assert climbs("panomap.table.table", "panomap.views.views") is not None
    assert climbs("panomap.views.views", "panomap.table.table") is None
    assert climbs("panomap.simulate.room", "panomap.calibrate.landmarks.pairs") is not None
    assert climbs("panomap.simulate.room", "panomap.errors") is None


def run_python(code: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False, timeout=120)


@pytest.mark.slow
def test_every_module_imports_on_its_own() -> None:
    """No import cycle: each module, imported first in a clean package, loads.

    One interpreter for all (within the time budget): before each import every ``panomap``
    module is dropped from ``sys.modules``, so that each one starts the import chain itself.
    """
    names = sorted(name for name in MODULES if name != "panomap.__main__")
    code = textwrap.dedent(
        f"""
        import importlib, sys, traceback
        failed = []
        for name in {names!r}:
            for loaded in [m for m in sys.modules if m == "panomap" or m.startswith("panomap.")]:
                del sys.modules[loaded]
            try:
                importlib.import_module(name)
            except Exception:
                failed.append(name + ": " + traceback.format_exc().strip().splitlines()[-1])
        print("\\n".join(failed))
        sys.exit(1 if failed else 0)
        """
    )
    result = run_python(code)
    assert result.returncode == 0, result.stdout + result.stderr
    assert len(names) > 30  # the scan found the package


def loads(module: str, *forbidden: str) -> list[str]:
    """Which of ``forbidden`` (modules or packages) ``import module`` loads, in a fresh interpreter."""
    code = (
        f"import sys, {module}; "
        f"print(' '.join(f for f in {list(forbidden)!r} if any(m == f or m.startswith(f + '.') for m in sys.modules)))"
    )
    result = run_python(code)
    assert result.returncode == 0, result.stderr
    return result.stdout.split()


def test_the_learning_session_loads_no_command_line_and_no_video() -> None:
    assert loads("panomap.learn.session", "click", "av", "panomap.cli") == []


def test_the_table_loads_no_fitting_code() -> None:
    assert loads("panomap.table.table", "panomap.calibrate") == []


def module_graph() -> dict[str, set[str]]:
    """Each module's imports of other panomap modules (top level and inside functions)."""
    return {
        name: {module for module in imported_modules(name, path) if module in MODULES and module != name}
        for name, path in MODULES.items()
    }


def test_no_import_cycle() -> None:
    """No chain of imports leads back to where it started (table/file <-> table/table was one)."""
    graph = module_graph()
    state: dict[str, int] = {}
    cycles: list[list[str]] = []

    def visit(module: str, path: list[str]) -> None:
        state[module] = 1
        for imported in sorted(graph[module]):
            if state.get(imported) == 1:
                cycles.append([*path[path.index(imported) :], imported])
            elif imported not in state:
                visit(imported, [*path, imported])
        state[module] = 2

    for module in sorted(graph):
        if module not in state:
            visit(module, [module])
    assert cycles == [], "\n".join(" -> ".join(cycle) for cycle in cycles)


# calibrate/, a package per method over one shared core (docs/architecture.md), lowest first: a module of
# calibrate/ imports only its own package and the ones before it. ``pictures`` (lines and boards together)
# is a module at the top, ``dual_fisheye`` (a rig's two lenses from their pictures) above it; ``panomap.calibrate``
# itself imports nothing.
CALIBRATE_PACKAGES = ["core", "circles", "lines", "boards", "landmarks", "pictures", "level", "dual_fisheye"]


def calibrate_package(module: str) -> str | None:
    """``panomap.calibrate.landmarks.fit`` -> ``landmarks``; None outside calibrate/ (or for the package itself)."""
    parts = module.split(".")
    return parts[2] if len(parts) > 2 and parts[:2] == ["panomap", "calibrate"] else None


def test_calibrate_packages_never_climb() -> None:
    graph = module_graph()
    rank = {name: position for position, name in enumerate(CALIBRATE_PACKAGES)}
    packages = {calibrate_package(name) for name in MODULES} - {None}
    assert packages == set(rank), f"calibrate/ packages not in CALIBRATE_PACKAGES: {sorted(packages ^ set(rank))}"
    climbs_up = sorted(
        f"{importer} imports {imported}"
        for importer, imports in graph.items()
        if (low := calibrate_package(importer)) is not None
        for imported in imports
        if (high := calibrate_package(imported)) is not None and rank[high] > rank[low]
    )
    assert climbs_up == [], "\n".join(climbs_up)


def test_the_calibrate_order_fails_a_climb() -> None:
    # The core may not know a method; a method may not know one above it.
    assert calibrate_package("panomap.calibrate.core.report") == "core"
    assert calibrate_package("panomap.calibrate") is None
    rank = {name: position for position, name in enumerate(CALIBRATE_PACKAGES)}
    assert rank["core"] < rank["circles"] < rank["lines"] < rank["boards"] < rank["landmarks"] < rank["pictures"]


# Within the core and the landmark method, as a newcomer reads them (docs/architecture.md), lowest first: each
# file imports only files before it. (A module of calibrate/ not listed is not checked here; the packages'
# order above still is.)
CALIBRATE_ORDER = [
    "core.sources",
    "core.line_report",
    "core.report",
    "core.table_range",
    "core.noise",
    "core.refine",
    "core.start",
    "core.selection",
    "core.distinct",
    "circles.thresholds",
    "circles.types",
    "circles.frame",
    "circles.sampling",
    "circles.fitting",
    "circles.evidence",
    "circles.starts",
    "circles.rim",
    "circles.cutoff",
    "circles.find",
    "circles",
    "landmarks.pairs",
    "landmarks.outliers",
    "landmarks.mount",
    "landmarks.joint",
    "landmarks.viewpoint",
    "landmarks.fit",
    "landmarks.diagnosis",
    "landmarks.table",
    "landmarks.pipeline",
]


def test_calibrate_reads_one_way() -> None:
    graph = module_graph()
    rank = {f"panomap.calibrate.{name}": position for position, name in enumerate(CALIBRATE_ORDER)}
    assert set(rank) <= set(MODULES), f"not modules: {sorted(set(rank) - set(MODULES))}"
    backwards = sorted(
        f"{importer} imports {imported}"
        for importer, imports in graph.items()
        if importer in rank
        for imported in imports
        if imported in rank and rank[imported] >= rank[importer]
    )
    assert backwards == [], "\n".join(backwards)


# Sizes a reader takes in at once (issue 46): no module outside the ground truth over this many lines, no
# function over this many (from its ``def`` through its last line).
MAX_MODULE_LINES = 800
MAX_FUNCTION_LINES = 120


def test_no_module_or_function_too_long() -> None:
    too_long = []
    for name, path in MODULES.items():
        if name != "panomap" and layer(name) == GROUND_TRUTH:
            continue
        text = path.read_text()
        if (lines := len(text.splitlines())) > MAX_MODULE_LINES:
            too_long.append(f"{name}: {lines} lines")
        for node in ast.walk(ast.parse(text, str(path))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                size = (node.end_lineno or node.lineno) - node.lineno + 1
                if size > MAX_FUNCTION_LINES:
                    too_long.append(f"{name}.{node.name} (line {node.lineno}): {size} lines")
    assert too_long == [], "\n".join(too_long)
