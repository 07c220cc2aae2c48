"""One version: CHANGELOG.md's newest release, ``flowmc.__version__``, the installed metadata and ``flowmc --version``."""

from __future__ import annotations

import re
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import flowmc

CHANGELOG = Path(__file__).resolve().parents[2] / "CHANGELOG.md"


def test_the_version_is_the_changelogs_newest_release():
    headings = re.findall(r"^## \[([^\]]+)\]", CHANGELOG.read_text(encoding="utf-8"), re.M)
    assert headings[0] == "Unreleased"
    released = headings[1]
    assert re.fullmatch(r"\d+\.\d+\.\d+", released)
    assert flowmc.__version__ == released == metadata.version("flowmc")
    proc = subprocess.run([sys.executable, "-m", "flowmc", "--version"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0 and proc.stdout.strip() == f"flowmc {released}"
