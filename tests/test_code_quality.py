"""The house style's checks run with the tests, so CI enforces them: ruff (lint and format)
over the whole tree and mypy --strict over the packages."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = [
    "localizer",
    "lighting",
    "sim",
    "recording",
    "rf_gateway",
    "sensors",
    "store",
    "live",
    "server",
    "web",
    "calibration",
    "irloc",
    "fleet",
    "agent",
    "export",
    "survey",
    "commissioning",
    "pubsub",
    "ros2",
]
PYTHON_DIRS = [*PACKAGES, "bench", "tests"]


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", *args], cwd=ROOT, capture_output=True, text=True, timeout=600
    )


@pytest.mark.slow
def test_ruff_lint_and_format_are_clean() -> None:
    if shutil.which("ruff") is None and _run("ruff", "--version").returncode != 0:
        pytest.skip("ruff is not installed (pip install -e .[dev])")
    lint = _run("ruff", "check", *PYTHON_DIRS)
    assert lint.returncode == 0, lint.stdout + lint.stderr
    fmt = _run("ruff", "format", "--check", *PYTHON_DIRS)
    assert fmt.returncode == 0, fmt.stdout + fmt.stderr


@pytest.mark.slow
def test_mypy_strict_is_clean_on_the_packages() -> None:
    result = _run("mypy", *PACKAGES)
    assert result.returncode == 0, result.stdout + result.stderr
