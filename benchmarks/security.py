"""Security benchmark: the issue-18 probes (peak RSS and time of each, against the 500 MB target) and a
large fuzz run (mutated graph files and G-code programs: tracebacks, internal errors, runs over 500 MB).

Each probe and each fuzz case runs in its own ``flowmc`` child process (peak RSS from ``os.wait4``), so
the numbers are what a user's command would use. Prints tables; exits 1 if a target is missed.

    python3 benchmarks/security.py                 # the probes
    python3 benchmarks/security.py --fuzz 10000    # and 10,000 graph + 10,000 G-code mutations
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "security"))

from probes import NEAR_CAPS, PROBES, run_probe  # noqa: E402

TARGET_MB = 500.0


def probes_table() -> bool:
    print(f"{'probe':52s} {'exit':>4s} {'seconds':>8s} {'peak MB':>8s}  message")
    ok = True
    for probe in PROBES + NEAR_CAPS:
        with tempfile.TemporaryDirectory() as folder:
            out = run_probe(probe, Path(folder), timeout=300)
        last = out.stderr.strip().splitlines()[-1] if out.stderr.strip() else ""
        clean = out.code in ((0,) if probe.ok else (1, 2)) and "internal error" not in out.stderr \
            and "Traceback" not in out.stderr
        ok &= clean and out.peak_mb < TARGET_MB
        print(f"{probe.name:52s} {str(out.code):>4s} {out.seconds:8.2f} {out.peak_mb:8.0f}  {last[:110]}")
    return ok


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fuzz", type=int, default=0, help="graph mutations and G-code mutations to run (each)")
    parser.add_argument("--seed", type=int, default=18)
    args = parser.parse_args()
    ok = probes_table()
    if args.fuzz:
        from fuzzing import fuzz_table

        ok &= fuzz_table(args.fuzz, args.seed, TARGET_MB)
    print("all targets met" if ok else "TARGET MISSED")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
