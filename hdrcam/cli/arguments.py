"""Argument types and options shared by several commands.

Imported by every command's ``register``: nothing here may import torch (or anything heavy) at module level,
so ``hdrcam --help`` and ``hdrcam COMMAND --help`` start in a fraction of a second."""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from hdrcam.profiles import DEFAULT_PROFILE

if TYPE_CHECKING:
    import torch

MAX_SEED = 2 ** 32 - 1  # numpy's seed sequences refuse negative seeds, torch's generators those past 2^64


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None


def positive_float(text: str) -> float:
    """A positive number; 'inf' allowed (ingest --max-gap: no limit). A number that is written into a JSON record
    takes :func:`positive_finite_float`: JSON has no infinity."""
    value = _number(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be positive, got {text!r}")
    return value


def positive_finite_float(text: str) -> float:
    """A positive, finite number (a learning rate: 'inf' would train to non-finite weights)."""
    value = positive_float(text)
    if value == float("inf"):
        raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
    return value


def non_negative_finite_float(text: str) -> float:
    """0 or a positive, finite number (a loss weight)."""
    value = _number(text)
    if not 0 <= value < float("inf"):
        raise argparse.ArgumentTypeError(f"must be 0 or a positive, finite number, got {text!r}")
    return value


def positive_int(text: str) -> int:
    return _int_at_least(text, 1)


def non_negative_int(text: str) -> int:
    return _int_at_least(text, 0)


def int_at_least(minimum: int):
    """An argparse type: an integer of at least ``minimum``."""
    return lambda text: _int_at_least(text, minimum)


def _int_at_least(text: str, minimum: int) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value < minimum:
        raise argparse.ArgumentTypeError(f"must be at least {minimum}, got {text!r}")
    return value


def random_seed(text: str) -> int:
    """A --seed: an integer from 0 to MAX_SEED, refused as a usage error before any work otherwise."""
    message = f"expected a seed from 0 to {MAX_SEED} (2^32 - 1), got {text!r}"
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(message) from None
    if not 0 <= value <= MAX_SEED:
        raise argparse.ArgumentTypeError(message)
    return value


def _fraction(text: str, examples: str) -> float:
    """'a/b' or a plain number; ArgumentTypeError naming ``examples`` otherwise."""
    numerator, _, denominator = text.partition("/")
    try:
        return float(numerator) / float(denominator) if denominator else float(numerator)
    except (ValueError, ZeroDivisionError):
        raise argparse.ArgumentTypeError(f"expected {examples}, got {text!r}") from None


def fraction_below_one(text: str) -> float:
    """A fraction from 0 up to (not including) 1, such as 2e-5 or 0.02."""
    value = _number(text)
    if not 0.0 <= value < 1.0:
        raise argparse.ArgumentTypeError(f"expected a fraction from 0 up to (not including) 1, got {text!r}")
    return value


def fraction_between_0_and_1(text: str) -> float:
    """A fraction strictly between 0 and 1, such as 0.015."""
    value = _number(text)
    if not 0.0 < value < 1.0:
        raise argparse.ArgumentTypeError(f"must lie between 0 and 1 (both excluded), got {text!r}")
    return value


def share(text: str) -> float:
    """A share in (0, 1], such as 0.9 or 1."""
    value = _number(text)
    if not 0.0 < value <= 1.0:
        raise argparse.ArgumentTypeError(f"must lie in (0, 1], got {text!r}")
    return value


def exposure_seconds(text: str) -> float:
    """A shutter time in seconds: '1/4000', '0.5' or '2'."""
    value = _fraction(text, "seconds such as 1/4000 or 0.5")
    if not 0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"must be positive, got {text!r}")
    return value


def integers(count: int, separator: str = ",", minimum: int = 0):
    """An argument type for ``count`` integers >= ``minimum``, e.g. '10,20,300,200' or '1024x768' (separator x)."""
    def parse(text: str) -> tuple[int, ...]:
        parts = text.lower().split(separator)
        try:
            values = tuple(int(part) for part in parts)
        except ValueError:
            values = ()
        if len(values) != count or min(values) < minimum:
            raise argparse.ArgumentTypeError(f"expected {count} integers >= {minimum} separated by "
                                             f"{separator!r}, got {text!r}")
        return values
    return parse


@contextlib.contextmanager
def naming_input(path: Path) -> Iterator[None]:
    """Put ``path`` in front of an InputError raised while reading it, when the message does not name it yet."""
    from hdrcam.errors import InputError

    try:
        yield
    except InputError as error:
        if str(path) in str(error):
            raise
        raise InputError(f"{path}: {error}") from error


def add_profile_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--profile", default=DEFAULT_PROFILE,
                        help=f"capture profile name or .toml path (default {DEFAULT_PROFILE})")


def add_compute_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--device", default="auto", choices=("auto", "cpu", "cuda"),
                        help="compute device (auto: CUDA when present)")
    parser.add_argument("--dtype", default="float32", choices=("float32", "float64"),
                        help="floating-point precision of the simulation")


def compute_device(name: str) -> torch.device:
    import torch

    from hdrcam.errors import InputError

    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name == "cuda" and not torch.cuda.is_available():
        raise InputError("--device cuda asked for, but torch sees no CUDA device")
    return torch.device(name)


def compute_dtype(name: str) -> torch.dtype:
    import torch

    return {"float32": torch.float32, "float64": torch.float64}[name]
