"""x4 quadrature decoding as the 6050's FPGA does it (thesis 4.1.8)."""

from __future__ import annotations

import numpy as np

from flowmc.devices.sim.encoder import ab_levels, decode, line_samples


def test_forward_sequence_counts_up_and_reverse_counts_down():
    # A leads B: 00 -> 10 -> 11 -> 01 -> 00, one count per transition
    a, b = [0, 1, 1, 0, 0], [0, 0, 1, 1, 0]
    up = decode(a, b)
    assert up.counts.tolist() == [0, 1, 2, 3, 4] and len(up.illegal) == 0
    # B leads A: 00 -> 01 -> 11 -> 10 -> 00
    down = decode([0, 0, 1, 1, 0], [0, 1, 1, 0, 0], start=10)
    assert down.counts.tolist() == [10, 9, 8, 7, 6] and len(down.illegal) == 0


def test_an_illegal_00_to_11_jump_is_flagged_and_not_counted():
    a, b = [0, 1, 0, 1, 1], [0, 0, 0, 1, 0]  # 00 10 00 11 10: the 00 -> 11 jump skips a state
    result = decode(a, b)
    assert result.illegal.tolist() == [3]
    assert result.counts.tolist() == [0, 1, 0, 0, -1]
    assert decode([1, 0], [0, 1]).illegal.tolist() == [1]  # 10 -> 01 too


def test_levels_and_decoding_round_trip_a_random_walk():
    rng = np.random.default_rng(7)
    positions = np.cumsum(rng.integers(-40, 41, size=300))
    lines = line_samples(positions)
    assert np.abs(np.diff(lines)).max() == 1  # the lines move one state at a time
    a, b = ab_levels(lines)
    result = decode(a, b, start=int(lines[0]))
    assert len(result.illegal) == 0
    assert result.counts.tolist() == lines.tolist()
    # sampled too slowly (only at the positions), moves of 2 mod 4 are ambiguous and get flagged
    a2, b2 = ab_levels(positions)
    coarse = decode(a2, b2, start=int(positions[0]))
    jumps = np.flatnonzero(np.mod(np.diff(positions), 4) == 2) + 1
    assert coarse.illegal.tolist() == jumps.tolist()


def test_the_card_reports_encoder_counts_and_line_levels():
    from flowmc.devices.sim import SimCard
    from flowmc.motion.machine import Machine

    card = SimCard(Machine(period=0.001))
    card.jog("X", 0.0025 * 5, 10.0)  # five counts: phase 1 of 00, 10, 11, 01
    card.jog("Y", -0.0025 * 2, 10.0)  # minus two: phase 2
    status = card.status()
    assert status["encoder"] == [5, -2, 0]
    assert status["encoder_ab"] == ["10", "11", "00"]
