"""A prototype, not part of flowmc: profile_loops.c through ctypes, in place of numba's flowmc/motion/profile_loops.py
of commit de49043 (the same functions and arguments). Measured in docs/planning.md; to repeat it:

    git archive de49043 | tar -x -C /tmp/ctree
    gcc -O2 -ffp-contract=off -fno-math-errno -shared -fPIC -o /tmp/ctree/flowmc/motion/libprofile_loops.so \\
        benchmarks/compiled_loops/profile_loops.c
    cp benchmarks/compiled_loops/profile_loops.py /tmp/ctree/flowmc/motion/
    PYTHONPATH=/tmp/ctree python3 benchmarks/plan_hashes.py --compare DIR   # DIR from --save on this tree
    python3 benchmarks/side_by_side.py . /tmp/ctree --cold 5
"""

from __future__ import annotations

import ctypes
from pathlib import Path

import numpy as np

_lib = ctypes.CDLL(str(Path(__file__).with_name("libprofile_loops.so")))
_P, _LONG = ctypes.c_void_p, ctypes.c_long
_lib.scan.argtypes = [_P] * 5 + [_LONG, _P]
_lib.budgets.argtypes = [_P, _P, _P, ctypes.c_int, _P] + [_P] * 9 + [ctypes.c_double, _LONG, _LONG] + [_P] * 4


def _doubles(*arrays):
    return [np.ascontiguousarray(a, dtype=float) for a in arrays]


def scan(cap, limit, ds, up, down):
    arrays = _doubles(cap, limit, ds, up, down)
    out = np.empty(len(arrays[0]))
    _lib.scan(*(a.ctypes.data for a in arrays), len(out), out.ctypes.data)
    return out


def budgets(cap, faster, slower, signed, widen, *terms_and_window):
    *terms, window = terms_and_window
    arrays = _doubles(cap, faster, slower, widen, *terms)
    n, rows = len(arrays[0]), arrays[4].shape[0]
    out, level, least = np.empty((2, n)), np.empty(n), np.empty(n if signed else 0)
    pointers = [a.ctypes.data for a in arrays]
    _lib.budgets(*pointers[:3], int(signed), *pointers[3:], float(window), rows, n, out[0].ctypes.data,
                 out[1].ctypes.data, level.ctypes.data, least.ctypes.data)
    return out[0], out[1]
