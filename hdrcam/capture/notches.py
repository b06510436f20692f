"""Shutter and ISO notches of a Sony A7 (1/3 EV steps): nominal labels, true values, PTP encodings.

Shutter times are powers of two in thirds of a stop (1/125 s is really 2^-7 = 1/128 s); the nominal labels
are rounded, which is why brackets must have their exposure ratios estimated from the data
(REFERENCE.md sec. 4). PTP encodes a shutter time as (numerator << 16) | denominator (0xD20D) and ISO in the
low 24 bits of 0xD21E.
"""

from __future__ import annotations

import dataclasses
import math
from fractions import Fraction

from hdrcam.errors import InputError

_SLOW_LABELS = ("30", "25", "20", "15", "13", "10", "8", "6", "5", "4", "3.2", "2.5", "2", "1.6", "1.3", "1",
                "0.8", "0.6", "0.5", "0.4")
_FAST_DENOMINATORS = (3, 4, 5, 6, 8, 10, 13, 15, 20, 25, 30, 40, 50, 60, 80, 100, 125, 160, 200, 250, 320, 400,
                      500, 640, 800, 1000, 1250, 1600, 2000, 2500, 3200, 4000, 5000, 6400, 8000)
ISO_VALUES = (100, 125, 160, 200, 250, 320, 400, 500, 640, 800, 1000, 1250, 1600, 2000, 2500, 3200, 4000, 5000,
              6400, 8000, 10000, 12800, 16000, 20000, 25600)
ISO_AUTO = 0xFFFFFF
_LONGEST_STOPS = 5  # 30 s nominal is 2^5 = 32 s


@dataclasses.dataclass(frozen=True)
class ShutterNotch:
    index: int  # 0 = 30 s, counting towards shorter exposures in 1/3 EV steps
    nominal: Fraction  # the label, in seconds
    true_s: float  # 2^(5 - index / 3) seconds

    @property
    def label(self) -> str:
        return f"1/{self.nominal.denominator}" if self.nominal < 0.35 else f"{float(self.nominal):g}\""

    @property
    def ptp_value(self) -> int:
        """Sony 0xD20D encoding: (numerator << 16) | denominator; tenths of a second for 0.4 s and longer."""
        if self.nominal < 0.35:
            return (1 << 16) | self.nominal.denominator
        return (int(self.nominal * 10) << 16) | 10


def _build_notches() -> tuple[ShutterNotch, ...]:
    nominal = [Fraction(label) for label in _SLOW_LABELS] + [Fraction(1, d) for d in _FAST_DENOMINATORS]
    return tuple(ShutterNotch(i, value, 2.0 ** (_LONGEST_STOPS - i / 3)) for i, value in enumerate(nominal))


SHUTTER_NOTCHES = _build_notches()
NOTCHES_PER_EV = 3


def shutter_from_ptp(value: int) -> ShutterNotch:
    """The notch of a 0xD20D value, read as the fraction numerator / denominator (libgphoto2's reading: 300/10
    and 30/1 are both 30 s); ValueError for Bulb (0) or a time that is no notch."""
    numerator, denominator = value >> 16, value & 0xFFFF
    if value == 0 or denominator == 0:
        raise ValueError(f"the shutter is on Bulb (0x{value:08X}); never use Bulb for calibration")
    seconds = Fraction(numerator, denominator)
    for notch in SHUTTER_NOTCHES:
        if notch.nominal == seconds:
            return notch
    raise ValueError(f"shutter value 0x{value:08X} ({numerator}/{denominator} s) is not a known notch")


def nearest_shutter(exposure_s: float) -> ShutterNotch:
    """The notch whose true time is nearest to ``exposure_s`` in stops."""
    if not exposure_s > 0:
        raise ValueError(f"exposure must be positive, got {exposure_s}")
    return min(SHUTTER_NOTCHES, key=lambda notch: abs(math.log2(notch.true_s / exposure_s)))


def bracket_notches(shortest_s: float, stops: int, ev_step: float) -> list[ShutterNotch]:
    """``stops`` notches from the one nearest ``shortest_s`` towards longer exposures, ``ev_step`` EV apart."""
    step = round(ev_step * NOTCHES_PER_EV)
    if step < 1 or abs(step - ev_step * NOTCHES_PER_EV) > 1e-6:
        raise InputError(f"ev_step must be a positive multiple of 1/3 EV, got {ev_step}")
    first = nearest_shutter(shortest_s).index
    indices = [first - k * step for k in range(stops)]
    if indices[-1] < 0:
        raise InputError(f"{stops} exposures {ev_step} EV apart from {shortest_s:g} s need longer than 30 s; "
                         "choose a longer shortest exposure or fewer stops")
    return [SHUTTER_NOTCHES[i] for i in indices]


def nearest_iso(iso: float) -> int:
    return min(ISO_VALUES, key=lambda value: abs(math.log2(value / iso)))
