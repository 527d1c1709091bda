"""The benchmark runs, and the paper's per-pixel algorithm and ours give the same image."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parents[1] / "bench" / "bench_unwarp.py"


def test_paper_per_pixel_algorithm_and_ours_agree_pixel_for_pixel() -> None:
    result = subprocess.run([sys.executable, str(BENCH), "--quick"], capture_output=True, text=True, check=True)
    assert "outputs equal: True (0 of 65536 pixels differ)" in result.stdout, result.stdout
