"""Every code block of README.md and docs/*.md runs as printed (issue 53), so a doc cannot drift.

The ``python`` blocks run as scripts and the ``console`` blocks command by command, in the page's order, in one
folder per page holding what ``panomap demo`` writes (``demo-out/``). A block that cannot run as printed (it
installs, needs a network, the user's own camera or a video, or serves a page until Ctrl-C) says so in the page:
``<!-- not run: REASON -->`` on the line before it. Every fence names its kind (``console``, ``python``,
``text``...), so a command cannot hide in a block of another kind.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest
from click.testing import CliRunner

from panomap.cli.app import main

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^(```|~~~)(.*)$")
NOT_RUN = re.compile(r"^<!--\s*not run:\s*(\S.*?)\s*-->$")
RUN = {"python", "console"}
# The kinds a block may be: run (above), or shown (output, diagrams, file contents, the manual's directives).
SHOWN = {"text", "csv", "json", "yaml", "{toctree}", "{eval-rst}"}
# The blocks marked not run, at most (each marked in its page with its reason): a ceiling, so that marking
# another block is a decision seen here.
# 16: installing (5), serving a page (3), ffmpeg, Dask machines, a stream and a capture device, other tools'
# calibration files (2), a car's four cameras (2), the shared Theta pictures. The demo writes a clip, a fisheye
# looking ahead and a dual fisheye with their calibrations, and a manifest (issue 53).
MOST_NOT_RUN = 16


@dataclass(frozen=True)
class Block:
    """A fenced block of a page: where it starts (1-based line of its fence), its kind, its text, and the reason
    it is not run (None: it runs)."""

    page: Path
    line: int
    kind: str
    text: str
    not_run: str | None

    @property
    def where(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"


def blocks(page: Path) -> list[Block]:
    """The fenced blocks of ``page``, in order."""
    lines = page.read_text(encoding="utf-8").splitlines()
    found: list[Block] = []
    k = 0
    while k < len(lines):
        opening = FENCE.match(lines[k])
        if opening is None:
            k += 1
            continue
        fence, kind = opening.group(1), opening.group(2).strip()
        end = next((j for j in range(k + 1, len(lines)) if lines[j].strip() == fence), len(lines))
        before = next((lines[j].strip() for j in range(k - 1, -1, -1) if lines[j].strip()), "")
        marked = NOT_RUN.match(before)
        found.append(Block(page, k + 1, kind, "\n".join(lines[k + 1 : end]), marked.group(1) if marked else None))
        k = end + 1
    return found


def commands(block: Block) -> list[tuple[int, list[str]]]:
    """A console block's commands (its line number, its words as the shell splits them): continuation lines
    joined, comments and blank lines left out."""
    out: list[tuple[int, list[str]]] = []
    pending, start = "", 0
    for offset, line in enumerate(block.text.splitlines(), 1):
        if not pending:
            start = block.line + offset
        if line.rstrip().endswith("\\"):
            pending += line.rstrip()[:-1] + " "
            continue
        words = shlex.split(pending + line, comments=True)
        pending = ""
        if words:
            out.append((start, words))
    return out


EVERY_BLOCK = [block for page in PAGES for block in blocks(page)]


def test_every_block_names_its_kind_and_every_command_block_is_console() -> None:
    """A bare fence (or one of another kind) holding a command would escape the run below."""
    unnamed = [block.where for block in EVERY_BLOCK if block.kind not in RUN | SHOWN]
    assert unnamed == [], f"blocks of no known kind (name it: console, python, text...): {unnamed}"
    command = re.compile(r"(\$ )?panomap [a-z]+ [^\[]*$")  # (a synopsis, with [OPTIONAL] parts, is text)
    hidden = [
        block.where
        for block in EVERY_BLOCK
        if block.kind == "text" and any(command.match(line) for line in block.text.splitlines())
    ]
    assert hidden == [], f"commands in text blocks (make them console blocks): {hidden}"


def test_blocks_not_run_say_why_and_are_few() -> None:
    marked = [(block.where, block.not_run) for block in EVERY_BLOCK if block.not_run is not None]
    assert all(block.kind in RUN for block in EVERY_BLOCK if block.not_run is not None), marked
    assert len(marked) <= MOST_NOT_RUN, "\n".join(f"{where}: {why}" for where, why in marked)


def test_console_blocks_run_only_panomap() -> None:
    """Other programs (pip, ffmpeg, dask) install or need what the tests do not have: such blocks are marked."""
    others = [
        f"{block.where}: {words[0]}"
        for block in EVERY_BLOCK
        if block.kind == "console" and block.not_run is None
        for _, words in commands(block)
        if words[0] != "panomap"
    ]
    assert others == [], others


def test_the_parser_joins_continuations_and_drops_comments(tmp_path: Path) -> None:
    page = tmp_path / "page.md"
    page.write_text(
        "text\n\n<!-- not run: serves a page -->\n```console\npanomap learn a.png\n```\n\n"
        "```console\n# a comment\npanomap video cam.npz in.mp4 -o 'out_{name}.mp4' \\\n"
        "    --view panorama:size=64x16   # the panorama\n\npanomap info cam.npz\n```\n"
    )
    first, second = blocks(page)
    assert (first.line, first.kind, first.not_run) == (4, "console", "serves a page")
    assert second.not_run is None and commands(second) == [
        (10, ["panomap", "video", "cam.npz", "in.mp4", "-o", "out_{name}.mp4", "--view", "panorama:size=64x16"]),
        (13, ["panomap", "info", "cam.npz"]),
    ]


@pytest.fixture(scope="module")
def demo_out(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """What ``panomap demo`` writes, made once."""
    folder = tmp_path_factory.mktemp("demo")
    result = CliRunner().invoke(main, ["demo", "--out", str(folder / "demo-out")])
    assert result.exit_code == 0, result.output
    return folder / "demo-out"


RUN_PAGES = [page for page in PAGES if any(b.kind in RUN and b.not_run is None for b in blocks(page))]


@pytest.mark.slow
@pytest.mark.parametrize("page", RUN_PAGES, ids=[page.name for page in RUN_PAGES])
def test_the_blocks_of_a_page_run_as_printed(
    page: Path, demo_out: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    shutil.copytree(demo_out, tmp_path / "demo-out")
    monkeypatch.chdir(tmp_path)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT / "src"), os.environ.get("PYTHONPATH")])))
    env.pop("PYTHONWARNINGS", None)
    for block in blocks(page):
        if block.kind not in RUN or block.not_run is not None:
            continue
        if block.kind == "python":
            ran = subprocess.run(
                [sys.executable, "-c", block.text], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=280
            )
            assert ran.returncode == 0, f"{block.where}: the python block failed:\n{ran.stdout}{ran.stderr}"
            continue
        for line, words in commands(block):
            result = CliRunner().invoke(main, words[1:])
            assert result.exit_code == 0, f"{page.relative_to(ROOT)}:{line}: {shlex.join(words)}\n{result.output}"
