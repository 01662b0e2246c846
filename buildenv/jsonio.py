"""Standard JSON out: no ``NaN`` or ``Infinity`` tokens (RFC 8259 has none; Python's ``json`` writes them).

:func:`dumps` is ``json.dumps`` that also writes numpy scalars and arrays, and either refuses a non-finite number
(:class:`~buildenv.errors.NonFiniteError`, naming where in the object it is: a metric that came out NaN is a
fault to report, not a value) or writes it as ``null`` (where NaN deliberately means "not defined", such as a
share with nothing to share).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from buildenv.errors import NonFiniteError

__all__ = ["dumps"]


def dumps(
    obj: Any,
    *,
    where: str,
    nonfinite: str = "refuse",
    hint: str = "",
    default: Callable[[Any], Any] | None = None,
    **kwargs: Any,
) -> str:
    """``obj`` as standard JSON text.

    Args:
        obj: dicts, lists, tuples, numbers, strings, None, numpy scalars and arrays; anything else goes through
            ``default`` first (as with :func:`json.dumps`).
        where: what ``obj`` is, for the error message (``"the evaluation result"``).
        nonfinite: ``"refuse"``: raise on NaN or an infinity; ``"null"``: write it as ``null``.
        hint: the error message's end: the likely cause, what to do.
        default: as in :func:`json.dumps`; what it returns is checked too.
        kwargs: passed to :func:`json.dumps` (``indent``, ``separators``, ``sort_keys``).
    Raises:
        NonFiniteError: ``nonfinite="refuse"`` and ``obj`` holds NaN or an infinity; the message names the first
            by its key path and counts the others (``the evaluation result: loss is nan (and 3 more values:
            mse_t, ...); <hint>``).
        ValueError: ``nonfinite`` is neither ``"refuse"`` nor ``"null"``.
        TypeError: a value neither JSON, numpy, nor made JSON by ``default``.
    """
    if nonfinite not in ("refuse", "null"):
        raise ValueError(f"nonfinite must be 'refuse' or 'null', not {nonfinite!r}")
    bad: list[tuple[str, float]] = []  # where and what, of the non-finite values refused

    def clean(value: Any, at: str) -> Any:
        if isinstance(value, (bool, np.bool_)):
            return bool(value)
        if isinstance(value, (int, np.integer)):
            return int(value)
        if isinstance(value, (float, np.floating)):  # float subclasses (np.float64) bypass ``default``
            value = float(value)
            if math.isfinite(value):
                return value
            if nonfinite == "refuse":
                bad.append((at or "the value", value))
            return None
        if isinstance(value, str) or value is None:
            return value
        if isinstance(value, Mapping):
            return {k: clean(v, f"{at}.{k}" if at else str(k)) for k, v in value.items()}
        if isinstance(value, (list, tuple)):
            return [clean(v, f"{at}[{i}]") for i, v in enumerate(value)]
        if isinstance(value, np.ndarray):
            return clean(value.tolist(), at)
        if default is None:
            raise TypeError(f"{where}: {at or 'the value'} is a {type(value).__name__}, not JSON serialisable")
        return clean(default(value), at)

    cleaned = clean(obj, "")
    if bad:
        (first, value), more = bad[0], [at for at, _ in bad[1:]]
        others = f" (and {len(more)} more: {', '.join(more[:3])}{', ...' if len(more) > 3 else ''})" if more else ""
        raise NonFiniteError(f"{where}: {first} is {value}{others}" + (f"; {hint}" if hint else ""))
    return json.dumps(cleaned, allow_nan=False, **kwargs)
