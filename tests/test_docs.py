"""The manual (docs/, Sphinx) builds without a warning, every relative link of README.md and docs/*.md resolves,
every public name is in the API reference with its parameters, and the manual's ten-line script runs."""

from __future__ import annotations

import contextlib
import inspect
import io
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import panomap

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PAGES = sorted(DOCS.glob("*.md"))
SCRIPT_MARK = "<!-- tests/test_docs.py runs the next script -->"

LINK = re.compile(r"!?\[(?:[^\]\[]|\[[^\]]*\])*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
FENCE = re.compile(r"^(```|~~~)")


@pytest.mark.slow
def test_the_manual_builds_without_a_warning(tmp_path: Path) -> None:
    """``sphinx-build -W --keep-going``: a broken reference, a page left out of the table of contents, a
    docstring that does not parse or an object of the API reference without a docstring fails the build."""
    env = {key: value for key, value in os.environ.items() if key != "PYTHONWARNINGS"}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT / "src"), env.get("PYTHONPATH")]))
    command = [
        sys.executable,
        "-m",
        "sphinx",
        "-W",
        "--keep-going",
        "-q",
        "-b",
        "dummy",
        "-d",
        str(tmp_path / "doctrees"),
    ]
    result = subprocess.run(
        [*command, str(DOCS), str(tmp_path / "out")], capture_output=True, text=True, env=env, timeout=280
    )
    assert result.returncode == 0, result.stdout + result.stderr


def _links(path: Path) -> list[tuple[int, str]]:
    """(line number, target) of every Markdown link and image of ``path`` outside code blocks and spans."""
    found: list[tuple[int, str]] = []
    fenced = False
    for number, line in enumerate(path.read_text().splitlines(), 1):
        if FENCE.match(line.lstrip()):
            fenced = not fenced
            continue
        if fenced:
            continue
        text = re.sub(r"`[^`]*`", "", line)
        found += [(number, target) for target in LINK.findall(text)]
    return found


def anchors(path: Path) -> set[str]:
    """The anchors of a Markdown page's headings, as GitHub and MyST make them: lower case, punctuation
    dropped but for hyphens and underscores, spaces made hyphens; a repeated one numbered."""
    seen: dict[str, int] = {}
    out: set[str] = set()
    fenced = False
    for line in path.read_text().splitlines():
        if FENCE.match(line.lstrip()):
            fenced = not fenced
        if fenced or not line.startswith("#"):
            continue
        title = line.lstrip("#").strip()
        slug = re.sub(r"[^\w\- ]", "", title.lower()).replace(" ", "-")
        count = seen.get(slug, 0)
        seen[slug] = count + 1
        out.add(slug if count == 0 else f"{slug}-{count}")
    return out


@pytest.mark.parametrize("page", [ROOT / "README.md", *PAGES], ids=lambda path: path.name)
def test_every_relative_link_resolves(page: Path) -> None:
    """Each link to a file names one that exists, and each anchor (``page.md#heading``) one of its headings."""
    broken = []
    for number, target in _links(page):
        if re.match(r"[a-z][a-z0-9+.-]*:", target):  # https:, mailto:
            continue
        file_part, _, anchor = target.partition("#")
        linked = (page.parent / file_part).resolve() if file_part else page
        if not linked.exists():
            broken.append(f"{page.name}:{number}: {target}: no such file")
        elif anchor and (linked.suffix != ".md" or anchor not in anchors(linked)):
            broken.append(f"{page.name}:{number}: {target}: no such heading")
    assert not broken, "\n".join(broken)


def test_the_link_check_sees_links_and_anchors(tmp_path: Path) -> None:
    """The check itself: links in code are not links, and an anchor is a heading's."""
    page = tmp_path / "page.md"
    page.write_text("# A `code` title: here\n\n[a](other.md#x) `[b](c.md)`\n\n```\n[d](e.md)\n```\n![f](img/g.png)\n")
    assert _links(page) == [(3, "other.md#x"), (8, "img/g.png")]
    assert anchors(page) == {"a-code-title-here"}


def test_every_public_name_is_in_the_api_reference_with_its_parameters() -> None:
    """docs/api.md documents each name of ``panomap.__all__`` (autodoc), each function's docstring names
    every parameter (numpydoc's PR01 and PR02), and each class has a docstring."""
    from numpydoc.validate import validate

    reference = (DOCS / "api.md").read_text()
    documented = set(re.findall(r"^\.\. (?:autofunction|autoclass|autoexception|data):: (\S+)$", reference, re.M))
    assert documented == set(panomap.__all__)
    problems = []
    for name in panomap.__all__[1:]:
        value = getattr(panomap, name)
        if not inspect.getdoc(value):
            problems.append(f"{name}: no docstring")
        elif inspect.isfunction(value):
            errors = validate(f"{value.__module__}.{value.__qualname__}")["errors"]
            problems += [f"{name}: {message}" for code, message in errors if code in ("PR01", "PR02")]
    assert not problems, "\n".join(problems)


def manual_scripts() -> list[str]:
    """The scripts the getting-started page shows after its marks, in order."""
    text = (DOCS / "getting-started.md").read_text()
    scripts = []
    for part in text.split(SCRIPT_MARK)[1:]:
        match = re.match(r"\s*```python\n(.*?)```", part, re.S)
        assert match is not None, "no python block after a mark"
        scripts.append(match.group(1))
    return scripts


@pytest.mark.slow
def test_the_getting_started_scripts_run_on_the_demo(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The getting-started page's scripts, as printed, after ``panomap demo`` (run here as the command runs it):
    the perspective view of the demo's table, then the ten-line script that learns the camera from the demo's
    picture alone and writes a table that loads."""
    from panomap.cli.demo import run_demo

    view, learn = manual_scripts()
    assert len(learn.strip().splitlines()) <= 10
    for _line in run_demo(tmp_path / "demo-out"):
        pass
    monkeypatch.chdir(tmp_path)
    exec(compile(view, "getting-started.md", "exec"), {"__name__": "__main__"})
    assert panomap.read_image(tmp_path / "ptz.png").shape[:2] == (720, 960)
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        exec(compile(learn, "getting-started.md", "exec"), {"__name__": "__main__"})
    assert printed.getvalue().startswith("learned from checkerboards: model unified, ")
    table = panomap.load_table(tmp_path / "learned.npz")
    assert table.info["source"] == "checkerboards" and table.info["images"] == ["demo-out/boards.png"]
    assert table.image_size == (1024, 1024) and table.model.s == -1


def test_the_readme_is_a_front_page_and_its_test_command_is_what_ci_runs() -> None:
    """README.md: at most 150 lines, its picture small; its test command is the command .ci/run runs (which
    the README says), but for pip's ``-q`` there."""
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 150
    assert "![" in readme and (DOCS / "img" / "front.png").stat().st_size < 300_000
    (command,) = [line for line in readme.splitlines() if line.startswith("scripts/install-test-deps.sh &&")]
    ci = (ROOT / ".ci" / "run").read_text().rstrip("\n").splitlines()[-1]
    assert ci.replace("pip install -q ", "pip install ") == command
