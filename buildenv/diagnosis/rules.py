"""The naming rules of the gap diagnosis: when a candidate effect joins the model.

A candidate is one effect tried on top of the current model (:class:`Candidate`). Four rules judge it, each a named
object whose :meth:`check` returns None when the candidate passes, else why not in words; :func:`judge` applies
them in order and :func:`select` takes the candidate with the best held-out gain among those passing every rule.
The only knob is the significance level (``alpha``, shared by the step's candidates with Bonferroni).

1. :class:`EnoughData`: the fit and held-out weeks both have hours in which the effect can show
   (:mod:`buildenv.diagnosis.data_needs`), else the answer for it is "not enough data to tell".
2. :class:`Significant`: it improves the held-out weeks, significantly (:mod:`buildenv.diagnosis.evidence`).
3. :class:`ShowsWhereItShould`: the series it mainly shows in improves held out, and an effect carried by a
   building parameter makes neither series worse (a parameter trading one series against the other absorbs
   another miss).
4. :class:`PlausibleSize`: its estimate is of a size seen in practice (:meth:`buildenv.diagnosis.effects.Effect.
   plausible`): a smaller fit is the model borrowing the effect to absorb another miss.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from buildenv.diagnosis.effects import get_effect
from buildenv.diagnosis.evidence import SERIES, Evidence

NAMED = "named"
NOT_NAMED = "not named"
NOT_ENOUGH_DATA = "not enough data to tell"


@dataclass
class Candidate:
    """One effect tried on top of the current model.

    Attributes:
        name: the effect (:data:`buildenv.diagnosis.effects.EFFECTS`).
        evidence: its held-out test (:class:`buildenv.diagnosis.evidence.Evidence`), None when not tried for
            lack of data.
        parameters: its calibrated parameters (a carried effect: its building parameter), catalogue units.
        threshold: the p-value it must stay under (``alpha`` over the step's candidates with data; None when not
            judged for lack of data).
        baseline: what its gain is measured against.
        lacking: why the site cannot show it (:func:`buildenv.diagnosis.data_needs.lacking`), or None.
        failed: ``{rule: why}`` of the rules it fails (:func:`judge`).
        status: :data:`NAMED`, :data:`NOT_NAMED` or :data:`NOT_ENOUGH_DATA`.
    """

    name: str
    evidence: Evidence | None
    parameters: dict[str, float] = field(default_factory=dict)
    threshold: float | None = 0.05
    baseline: str = "control"
    lacking: str | None = None
    failed: dict[str, str] = field(default_factory=dict)
    status: str = NOT_NAMED

    @property
    def gain(self) -> float:
        """Held-out gain (0 when not tried)."""
        return self.evidence.gain if self.evidence is not None else 0.0

    @property
    def qualifies(self) -> bool:
        """Whether it passes every rule (:func:`judge` first)."""
        return not self.failed


class EnoughData:
    """The site's fit and held-out weeks have hours in which the effect can show."""

    name = "enough_data"

    def check(self, c: Candidate) -> str | None:
        return None if c.lacking is None else f"not enough data to tell: {c.lacking}"


class Significant:
    """A positive held-out gain, significant at the step's threshold."""

    name = "significant"

    def check(self, c: Candidate) -> str | None:
        e = c.evidence
        if e is None or e.gain <= 0.0:
            return "it does not improve the held-out weeks"
        if c.threshold is None or e.p_value >= c.threshold:
            return f"its held-out gain is not significant (p = {e.p_value:.2g}, needs < {c.threshold:.2g})"
        return None


class ShowsWhereItShould:
    """The effect's main series improves held out; a carried effect makes neither series worse (a building parameter
    moves both)."""

    name = "shows_where_it_should"

    def check(self, c: Candidate) -> str | None:
        effect = get_effect(c.name)
        gains = c.evidence.gain_by_series if c.evidence is not None else {}
        carried = effect.building_parameter is not None and effect.building_parameter in c.parameters
        series = (effect.series[0], *(s for s in SERIES if s != effect.series[0])) if carried else effect.series[:1]
        worse = [s for s in series if gains.get(s, 0.0) <= (0.0 if s == effect.series[0] else -1e-9)]
        if not worse:
            return None
        return f"the {' and '.join(worse)}, where it shows, is not improved held out"


class PlausibleSize:
    """The estimate is of a size seen in practice."""

    name = "plausible_size"

    def check(self, c: Candidate) -> str | None:
        effect = get_effect(c.name)
        if effect.plausible(c.parameters):
            return None
        return f"its estimate ({effect.estimate_text(c.parameters)}) is smaller than {effect.named_from()}"


RULES = (EnoughData(), Significant(), ShowsWhereItShould(), PlausibleSize())


def judge(candidates: list[Candidate]) -> list[Candidate]:
    """Apply :data:`RULES` to each candidate: its ``failed`` reasons (a candidate without enough data is judged by
    nothing else) and its status (named ones are set by :func:`select`'s caller); returns the same list, best
    held-out gain first."""
    for c in candidates:
        c.failed = {}
        for rule in RULES:
            why = rule.check(c)
            if why is not None:
                c.failed[rule.name] = why
                if isinstance(rule, EnoughData):
                    break
        c.status = NOT_ENOUGH_DATA if EnoughData.name in c.failed else NOT_NAMED
    candidates.sort(key=lambda c: -c.gain)
    return candidates


def select(candidates: list[Candidate]) -> Candidate | None:
    """The candidate with the best held-out gain of those passing every rule (:func:`judge` first), or None."""
    return max((c for c in candidates if c.qualifies), key=lambda c: c.gain, default=None)
