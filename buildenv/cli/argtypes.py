"""Argument types the commands share: argparse refuses a bad value with its usage and one line."""

from __future__ import annotations

import argparse

from buildenv.calibration.problem import DAILY_WEIGHT


def positive_int(text: str) -> int:
    """A whole number of at least 1 (weeks, cases, storeys)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number of at least 1, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number of at least 1, got {text!r}")
    return value


def share(text: str) -> float:
    """A fraction from 0 to 1."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"expected a share from 0 to 1, got {text!r}")
    return value


def positive_minutes(text: str) -> float:
    """A positive number of minutes."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value > 0:
        raise argparse.ArgumentTypeError(f"expected a positive number of minutes, got {text!r}")
    return value


def weight(text: str) -> float:
    """A finite weight of 0 or more."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not 0.0 <= value < float("inf"):
        raise argparse.ArgumentTypeError(f"expected a weight of 0 or more, got {text!r}")
    return value


def daily_weight_argument(p: argparse.ArgumentParser) -> None:
    """``--daily-weight W``: the meters' daily totals in the calibration cost."""
    p.add_argument(
        "--daily-weight",
        metavar="W",
        type=weight,
        default=DAILY_WEIGHT,
        help=f"weight W of (1 - R2) of the meters' daily totals in the calibration cost, against a day's energy "
        f"level traded for its hours' shape (docs/calibration.md); default {DAILY_WEIGHT:g}, 0: the paper's cost",
    )


def strict_calibration_argument(p: argparse.ArgumentParser) -> None:
    """Add ``--strict-calibration``: refuse a site whose calibration fails ASHRAE Guideline 14 (else a warning)."""
    p.add_argument(
        "--strict-calibration",
        action="store_true",
        help="refuse a site whose calibration fails ASHRAE Guideline 14 (by default: a warning, once)",
    )
