"""flowmc.motion.curve: derivatives asked for alone are the ones evaluated with the positions."""

import numpy as np

from flowmc.motion.path import Arc, EllipseArc, Line, Path
from flowmc.motion.smoothing import raw_curve


def test_derivatives_without_positions_are_the_same_bits():
    """The time law asks for derivatives alone (``lowest=1``) on lines, arcs and cubic intervals (a tabulated
    ellipse); they must be what a full evaluation gives, to the bit, so plans do not move."""
    path = Path([Line((0, 0, 0), (10, 0, 0), feed=100.0),
                 Arc((10, 0, 0), (15, 5, 1), (10, 5, 0), ccw=True, feed=100.0),
                 EllipseArc((9, 5, 1), (6, 0, 0), (0, 3, 0), 0.0, 2.0, feed=100.0)])
    curve, _ = raw_curve(path)
    kinds = set(curve.kind.tolist())
    assert len(kinds) == 2 and len(curve) > 3  # polynomial and arc rows, several cubic ones
    u = np.linspace(0.0, curve.length, 2001)
    index = curve.interval_at(u)
    for order in (1, 2, 3):
        full = curve.evaluate(u, order, index=index)
        for lowest in range(1, order + 1):
            part = curve.evaluate(u, order, index=index, lowest=lowest)
            assert len(part) == order + 1 - lowest
            for mine, theirs in zip(part, full[lowest:]):
                np.testing.assert_array_equal(mine, theirs)
    line_only = curve.evaluate(u[:100], 2, lowest=1)[0]  # on the line alone (the polynomial path)
    np.testing.assert_array_equal(line_only, np.tile([1.0, 0.0, 0.0], (100, 1)))
