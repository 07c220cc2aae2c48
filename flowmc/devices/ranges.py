"""What a card's I/O accepts: channel counts and the PWM, DA and spindle ranges of the 6050 card.

Figures from the LabVIEW thesis (000_*.txt, 4.1.5-4.1.6 and 4.4): 20 opto-isolated inputs,
8 outputs, one PWM output of 18-150,000 Hz (150 MHz clock, 1-128 prescaler, 16-bit counters)
sharing its terminal with a -10..+10 V DA output of 12-bit resolution, and a spindle inverter
whose 0-10 V input maps to 0-24,000 rpm. Pre-flight checks programs against a ``CardRanges``;
the simulated card also quantises what it outputs with the functions here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["CardRanges", "CARD_6050", "pwm_output", "da_output", "spindle_volts"]

PWM_CLOCK_HZ = 150e6
PWM_MAX_PRESCALE = 128
PWM_MAX_COUNT = 65536
DA_BITS = 12


@dataclass(frozen=True)
class CardRanges:
    """Channel counts and output ranges. ``analog`` says which of PWM/DA the shared terminal gives:
    ``"pwm"``, ``"da"`` or ``"both"`` (a device with separate outputs)."""

    inputs: int = 20
    outputs: int = 8
    pwm_hz: tuple[float, float] = (18.0, 150_000.0)
    duty_pct: tuple[float, float] = (0.0, 100.0)
    da_volts: tuple[float, float] = (-10.0, 10.0)
    spindle_rpm_max: float = 24_000.0
    spindle_volts_max: float = 10.0
    analog: str = "da"

    def with_analog(self, analog: str) -> "CardRanges":
        if analog not in ("pwm", "da", "both"):
            raise ValueError(f"analog must be 'pwm', 'da' or 'both', got {analog!r}")
        return CardRanges(self.inputs, self.outputs, self.pwm_hz, self.duty_pct, self.da_volts,
                          self.spindle_rpm_max, self.spindle_volts_max, analog)


CARD_6050 = CardRanges()


def pwm_output(freq_hz: float, duty_pct: float) -> tuple[float, float]:
    """The frequency and duty the card really produces for a request (already range-checked).

    The 150 MHz clock is divided by a prescaler (1-128), then by a 16-bit period counter; the duty
    is a compare value of the same counter. The smallest prescaler that fits gives the finest steps.
    """
    prescale = min(max(math.ceil(PWM_CLOCK_HZ / (PWM_MAX_COUNT * freq_hz)), 1), PWM_MAX_PRESCALE)
    count = min(max(round(PWM_CLOCK_HZ / (prescale * freq_hz)), 1), PWM_MAX_COUNT)
    compare = round(duty_pct / 100.0 * count)
    return PWM_CLOCK_HZ / (prescale * count), 100.0 * compare / count


def da_output(volts: float, lo: float = -10.0, hi: float = 10.0) -> float:
    """The voltage a 12-bit offset-binary DA gives for a request: code 2048 is 0 V, LSB = 20 V / 4096."""
    span = hi - lo
    levels = 2 ** DA_BITS
    code = min(max(round((volts - lo) / span * levels), 0), levels - 1)
    return lo + code * span / levels


def spindle_volts(rpm: float, ranges: CardRanges = CARD_6050) -> float:
    """DA volts for a spindle speed: 0-10 V is 0-24,000 rpm; the sign (direction) goes to an output."""
    return abs(rpm) / ranges.spindle_rpm_max * ranges.spindle_volts_max
