"""Shutter and ISO notches of a Sony A7 (1/3 EV steps): nominal labels, true values, PTP encodings.

Shutter times are powers of two in thirds of a stop (1/125 s is really 2^-7 = 1/128 s); the nominal labels
are rounded, which is why brackets must have their exposure ratios estimated from the data
(REFERENCE.md sec. 4). PTP encodes a shutter time as (numerator << 16) | denominator (0xD20D) and ISO in the
low 24 bits of 0xD21E.
"""

from __future__ import annotations

import dataclasses
import math
import re
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


def exposure_label(exposure_s: float) -> str:
    """How cameras label ``exposure_s`` seconds: '1/640' below 0.35 s where 1 / exposure is a whole number (to 0.5 %),
    else seconds with the seconds mark ('2.5"'), as the A7's notches are labelled."""
    if exposure_s < 0.35 and abs(1 / exposure_s - round(1 / exposure_s)) <= 0.005 / exposure_s:
        return f"1/{round(1 / exposure_s)}"
    return f"{exposure_s:.4g}\""


NOMINAL_LABEL_MAKES = ("SONY",)  # bodies whose files label 1/3 EV notches nominally (1/125 for 2^-7 s)


def true_exposure_s(labelled_s: float, make: str) -> float:
    """The true time (seconds) of the shutter notch whose nominal label ``labelled_s`` is (1/125 s is 2^-7 s; to
    1e-6, as LibRaw's float32 keeps a label) in a file of a body of NOMINAL_LABEL_MAKES (an A7's notches are
    1/3 EV only); else ``labelled_s`` itself: a time off the series, or another make's file, which may record
    exact times (1/1000 s meaning 1/1000 s) or half-stop notches (1/6 s for 2^-2.5 s)."""
    if make.strip().upper() not in NOMINAL_LABEL_MAKES:
        return labelled_s
    for notch in SHUTTER_NOTCHES:
        if abs(labelled_s - float(notch.nominal)) <= 1e-6 * labelled_s:
            return notch.true_s
    return labelled_s


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


def shutter_notch_within_range(exposure_s: float) -> ShutterNotch:
    """The notch nearest ``exposure_s`` (seconds); InputError when that is more than half a notch (1/6 EV) past the
    shutter's shortest (1/8000) or longest (30 s) time: the camera cannot take it, and the nearest notch is not
    what was asked for."""
    if not 0 < exposure_s < math.inf:
        raise InputError(f"exposure {exposure_s!r} s: a shutter time is a positive number of seconds")
    notch = nearest_shutter(exposure_s)
    if abs(math.log2(notch.true_s / exposure_s)) > 0.5 / NOTCHES_PER_EV + 1e-9 and notch.index in (
            0, len(SHUTTER_NOTCHES) - 1):
        written = f"1/{1 / exposure_s:.6g}" if exposure_s < 0.35 else f"{exposure_s:.4g}"
        raise InputError(f"{written} s is beyond the shutter's range, {_seconds(SHUTTER_NOTCHES[-1])} to "
                         f"{_seconds(SHUTTER_NOTCHES[0])} s")
    return notch


def bracket_notches(shortest_s: float, stops: int, ev_step: float) -> list[ShutterNotch]:
    """``stops`` notches from the one nearest ``shortest_s`` (seconds) towards longer exposures, ``ev_step`` EV
    apart; InputError, with the plans that fit, when the longest would be beyond the shutter's 30 s."""
    step = notch_step(ev_step)
    first = nearest_shutter(shortest_s).index
    if first - (stops - 1) * step < 0:
        raise InputError(_beyond_the_shutter(first, stops, step))
    return [SHUTTER_NOTCHES[first - k * step] for k in range(stops)]


def notch_step(ev_step: float) -> int:
    """The number of 1/3 EV shutter notches in ``ev_step`` EV; InputError unless it is a positive multiple of 1/3."""
    step = round(ev_step * NOTCHES_PER_EV)
    if step < 1 or abs(step - ev_step * NOTCHES_PER_EV) > 1e-6:
        raise InputError(f"ev_step must be a positive multiple of 1/3 EV (the shutter's notches), got {ev_step:g}")
    return step


def _beyond_the_shutter(first: int, stops: int, step: int) -> str:
    """Why ``stops`` exposures ``step`` notches apart from notch ``first`` do not fit the shutter (stops >= 2), and
    the nearest plans that do: a shorter shortest exposure, fewer stops, a smaller EV step."""
    span = (stops - 1) * step
    doublings = span / NOTCHES_PER_EV  # past about 1000 a float overflows: --stops 100000 is a typo, not a plan
    longest = (f"{SHUTTER_NOTCHES[first].true_s * 2.0 ** doublings:.4g} s" if doublings < 1000 else
               f"about 10^{round(math.log10(SHUTTER_NOTCHES[first].true_s) + doublings * math.log10(2))} s")
    fixes = [f"fewer stops (--stops {first // step + 1} or fewer)"]
    if span < len(SHUTTER_NOTCHES):
        fixes.insert(0, f"a shorter shortest exposure (--shortest {_seconds(SHUTTER_NOTCHES[span])} or shorter)")
    if first // (stops - 1) >= 1:
        fixes.append(f"a smaller EV step (--ev-step {_ev_text(first // (stops - 1) / NOTCHES_PER_EV)} or less)")
    plan = f"{stops} exposures {_ev_text(step / NOTCHES_PER_EV)} EV apart from {_seconds(SHUTTER_NOTCHES[first])} s"
    return f"{plan} would need {longest}, longer than the shutter's 30 s: choose {_one_of(fixes)}"


def _one_of(choices: list[str]) -> str:
    return choices[0] if len(choices) == 1 else ", ".join(choices[:-1]) + " or " + choices[-1]


def _seconds(notch: ShutterNotch) -> str:
    """A notch's label without the camera's seconds mark: '1/4000', '2.5'."""
    return notch.label.rstrip('"')


def _ev_text(ev: float) -> str:
    """EV as people write it: a whole number, else thirds as a fraction ('1/3', '8/3'), else 3 significant digits."""
    thirds = Fraction(ev).limit_denominator(NOTCHES_PER_EV)
    return str(thirds) if abs(thirds - ev) < 1e-9 else f"{ev:.3g}"


def ev_step_from_text(text: str) -> float:
    """An EV step (EV) written as a fraction of integers equal to a multiple of 1/3 ('1/3', '2/3', '4/3', '3'), or as
    a decimal that is a multiple of 1/3 rounded to the digits written: the camera's labels 0.3, 0.7, 1.3, 1.7, ...
    and 0.33, 0.333, 0.67, 0.667 all stand for 1/3 or 2/3 EV, as do decimals of three digits or more cut short
    (0.666, 1.6666). ValueError otherwise: 0.5 (the shutter moves in 1/3 EV notches), 0.35, 0.30 (rounded to two
    digits, 1/3 reads 0.33)."""
    value, unit = _ev_number(text.strip())
    thirds = round(value * NOTCHES_PER_EV)
    exact = Fraction(thirds, NOTCHES_PER_EV)
    truncated = 0 < unit <= Fraction(1, 1000) and value <= exact < value + unit
    if thirds < 1 or (abs(value - exact) > unit / 2 and not truncated):
        raise ValueError(f"{text} EV is no whole number of the shutter's 1/3 EV notches: give a multiple of 1/3 as a "
                         "fraction (1/3, 2/3, 1, 4/3) or as the camera labels it (0.3, 0.7, 1, 1.3, 1.7; or 0.33, "
                         "0.67)")
    return thirds / NOTCHES_PER_EV


def _ev_number(text: str) -> tuple[Fraction, Fraction]:
    """The exact value of '2/3' or '0.67', and the unit of its last digit: 0 for a fraction (exact), 1/100 for
    '0.67'."""
    if re.fullmatch(r"\d+/[1-9]\d*", text):
        return Fraction(text), Fraction(0)
    if re.fullmatch(r"\d+\.?\d*|\.\d+", text):
        return Fraction(text), Fraction(1, 10 ** len(text.partition(".")[2]))
    raise ValueError(f"expected a positive EV step such as 1, 2/3 or 0.7, got {text!r}")


def iso_setting(iso: float) -> int:
    """``iso`` as one of the camera's ISO settings (ISO_VALUES, 1/3 EV apart); InputError naming the nearest ones
    otherwise: the camera would land on another ISO than asked, and the frames would disagree with the plan."""
    if iso in ISO_VALUES:
        return int(iso)
    if not 0 < iso < math.inf:
        raise InputError(f"ISO {iso!r}: the camera's settings are " + ", ".join(map(str, ISO_VALUES)))
    above = [value for value in ISO_VALUES if value > iso]
    below = [value for value in ISO_VALUES if value < iso]
    nearest = " and ".join(str(value) for value in (below[-1:] + above[:1]))
    raise InputError(f"the camera offers no ISO {iso:g} (nearest: {nearest}); its settings are "
                     + ", ".join(map(str, ISO_VALUES)))
