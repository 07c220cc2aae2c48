"""Developer habits as suite checks (docs/checks.md): ruff with the rule set in pyproject.toml, and mypy
on flowmc/ failing on any finding that is not in the reviewed baseline.

The baseline (mypy_baseline.txt) lists findings that predate the check, one per line without line
numbers, so edits elsewhere in a file do not disturb it. It may only shrink: when a finding is
fixed, or a new one cannot be avoided, rewrite it with ``python tests/core/test_lint.py`` and review
the diff.
"""

from __future__ import annotations

import re
import subprocess
import sys
from collections import Counter
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
BASELINE = Path(__file__).with_name("mypy_baseline.txt")
LINT_PATHS = ("flowmc", "tests", "benchmarks", "examples")
_FINDING = re.compile(r"^(?P<file>[^:\n]+\.py):(?P<line>\d+): error: (?P<message>.*)$")


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", *args], cwd=REPO, capture_output=True, text=True, timeout=900)


def mypy_findings() -> tuple[Counter, dict[str, list[str]]]:
    """``Counter`` of "file: message  [code]" and, for each, the lines it was found on."""
    proc = run("mypy", "--no-error-summary", "--hide-error-context", "--no-pretty")
    assert proc.returncode in (0, 1), proc.stdout + proc.stderr  # 2: mypy itself failed
    found, lines = Counter(), {}
    for text in proc.stdout.splitlines():
        match = _FINDING.match(text)
        if match:
            key = f"{match['file']}: {match['message']}"
            found[key] += 1
            lines.setdefault(key, []).append(f"{match['file']}:{match['line']}")
    return found, lines


def baseline() -> Counter:
    return Counter(line for line in BASELINE.read_text(encoding="utf-8").splitlines() if line and not line.startswith("#"))


def test_ruff_finds_nothing():
    proc = run("ruff", "check", "--output-format", "concise", *LINT_PATHS)
    assert proc.returncode == 0, f"ruff (fix with `python -m ruff check --fix`, see docs/checks.md):\n{proc.stdout}{proc.stderr}"


def test_mypy_finds_nothing_new_and_the_baseline_only_shrinks():
    found, lines = mypy_findings()
    known = baseline()
    new = found - known
    assert not new, "new mypy findings (docs/checks.md):\n" + "\n".join(
        f"{where}: {key.split(': ', 1)[1]}" for key in sorted(new) for where in lines[key])
    fixed = known - found
    assert not fixed, ("these baseline findings are fixed; run `python tests/core/test_lint.py` to shrink "
                       "the baseline:\n" + "\n".join(sorted(fixed.elements())))


def test_the_baseline_parser_reads_mypy_lines():
    match = _FINDING.match('flowmc/ui/app.py:107: error: Cannot infer type of lambda  [misc]')
    assert match and (match["file"], match["line"], match["message"]) == (
        "flowmc/ui/app.py", "107", "Cannot infer type of lambda  [misc]")
    assert _FINDING.match("flowmc/ui/app.py:107: note: See https://...") is None


if __name__ == "__main__":  # rewrite the baseline from the current findings
    current, _ = mypy_findings()
    header = "# mypy findings that predate the check (tests/core/test_lint.py); this list may only shrink.\n"
    BASELINE.write_text(header + "".join(f"{key}\n" for key in sorted(current.elements())), encoding="utf-8")
    print(f"{BASELINE.relative_to(REPO)}: {sum(current.values())} findings")
