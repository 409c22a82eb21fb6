"""What discovery returns (campaign.discovery.search.discover): `Discovery`, with each `Step` that named
an effect and every `Candidate` tried at it; and the small questions asked of them (is a period among
these effects, unresolved, fitted). `note_once` adds a note to a result's notes without repeating it.

Units: deviations µm (the axis's deviation unit), positions mm (its position unit).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from campaign.discovery.effects import HELD_PREFIX, PERIOD_KEY
from campaign.discovery.fit import Fit
from campaign.discovery.local import LocalError
from campaign.discovery.locate import Located
from campaign.discovery.records import (
    Aliased,
    Choice,
    Held,
    NotExcluded,
    StandIn,
    StartingEffect,
    TableGap,
    Unresolved,
)
from campaign.model import EFFECT_PARAMS, ErrorModel


def periodic_in(names: Iterable[str]) -> bool:
    """Is one of these effects a periodic one (PERIOD_KEY)?"""
    return any(name in PERIOD_KEY for name in names)


def period_unresolved(unresolved: list[Unresolved]) -> bool:
    """Is a periodic effect in an unresolved group (its period not identifiable, or a rival's)?"""
    return any(periodic_in(u.effects) for u in unresolved)


def period_candidate(ranking: list[Candidate]) -> Candidate | None:
    """The fitted candidate of a periodic effect among `ranking`, if any."""
    return next((c for c in ranking if c.name in PERIOD_KEY and c.fit is not None), None)


@dataclass
class Candidate:
    """An effect tried at one step: its fit, the residual share it explains (%), and the tests."""

    @property
    def fitted(self) -> Fit:
        """The fit of an effect that was fitted; ValueError for one that could not be."""
        if self.fit is None:
            raise ValueError(f"{self.name} has no fit")
        return self.fit

    name: str
    fit: Fit | None
    explained_pct: float = 0.0
    delta_bic: float = 0.0
    p_value: float = 1.0
    cv_before_um: float = 0.0
    cv_after_um: float = 0.0
    verdict: str = ""
    periods: list[tuple[float, float]] = field(default_factory=list)
    """A periodic effect (PERIOD_KEY): the local optima of the period search, (period mm, ΔBIC to the best), best
    first, for the optima within PERIOD_LIST of the best."""

    @property
    def accepted(self) -> bool:
        return self.verdict == "accepted"


@dataclass(frozen=True)
class Step:
    """One named effect: its parameters and the gap (RMS of measured - simulated, µm) before and
    after; `ranking`: every candidate tried at this step; residuals µm per point."""

    effect: str
    params: dict[str, float]
    gap_before_um: float
    gap_after_um: float
    ranking: list[Candidate]
    residual_before: np.ndarray
    residual_after: np.ndarray
    errors: dict[str, float] = field(default_factory=dict)
    """1-σ standard errors of the fitted parameters (see discovery_fit.standard_errors); a
    period's includes the spread over its competing optima."""


STAND_IN_RIVALS = frozenset({"backlash", "settling"})
"""An unresolved group made only of these predicts one constant offset per direction at a constant
wait, wherever the axis is used: its size is known and is added (as backlash), its cause is not;
only when the waits do not vary (or are not recorded): where they vary, the two predict different
deviations at other waits, and neither stands in.
Rivals that predict differently between the measured points (aliased periods) get no stand-in."""


@dataclass
class Discovery:
    """The result. gaps µm; noise_um: pooled run-to-run scatter of the final residual per target
    and direction (µm); offset_um: the fitted datum offset; notes: confounding and caveats."""

    steps: list[Step]
    start: Fit
    final: Fit
    gap_before_um: float
    gap_after_um: float
    noise_um: float
    time_source: str
    notes: list[str] = field(default_factory=list)
    disagreement_before: dict = field(default_factory=dict)
    disagreement_after: dict = field(default_factory=dict)
    choices: list[Choice] = field(default_factory=list)
    """Where two confounded candidates were both plausible: step, chosen, other, why."""
    unresolved: list[Unresolved] = field(default_factory=list)
    """Effects the data cannot tell apart or pin down, none of them named: effects, why,
    how_to_tell (and periods_mm for a period that is not identifiable)."""
    errors: dict[str, dict[str, float]] = field(default_factory=dict)
    """1-σ standard errors of the final model's fitted parameters, per effect."""
    remaining: list[Candidate] = field(default_factory=list)
    """The candidates tried after the last step, none of them named."""
    remaining_beside: str | None = None
    """The unresolved effect the remaining candidates were tried beside (a stand-in), if any."""
    stand_in: StandIn | None = None
    """Rivals that predict the same deviation at every position the campaign can be used for
    (backlash and settling at a constant wait): one of them is in the final model in their place,
    not named (STAND_IN_RIVALS). effect, observable (what the data show, in words), rivals,
    params, errors, gap_without_um (the gap had nothing been added for it)."""
    averaged: dict[str, dict[str, float]] = field(default_factory=dict)
    """Beside a periodic error whose period is not identifiable: the other effects' parameters,
    averaged over its candidate periods (beside_unresolved_period); they replace the fitted ones."""
    local_errors: list[LocalError] = field(default_factory=list)
    """Errors outside the vocabulary, in the final model as local terms (bumps, steps; not named as
    effects of the model, not saved with it), in the order found (the one that explains most
    first; campaign.discovery.local.zones gives them along the axis)."""
    starting: dict[str, StartingEffect] = field(default_factory=dict)
    """The starting model's effects, as fitted at the end: params, errors, given (the keys the
    model gave), fixed, p_value (F-test of the effect against none of it) and significant."""
    located_before: Located | None = None
    """Where the campaign departs from the starting model beyond the noise, model-free
    (campaign.discovery.locate), before anything is named."""
    located_after: Located | None = None
    """The same for the final model: what it leaves unexplained, with its regions (what a held
    unresolved group holds included: model_prediction)."""
    tables: list[TableGap] = field(default_factory=list)
    """Tables fitted together: per table (campaign index order) its own gap and noise (gap_um,
    noise_um: its points alone, unweighted); gap_after_um and noise_um weigh each table as the fit
    does (campaign.discovery.local.gap_um). Empty for one table."""
    noise_measured: bool = True
    """False when no target is read twice in a direction: noise_um is then the residual itself, not
    a measured run-to-run scatter, and nothing can be said to be noise."""
    held: list[Held] = field(default_factory=list)
    """What an unresolved group shows (a reversal backlash and settling explain alike at waits that
    vary too little to tell them), held in the final fit by its better rival's form so that the gap
    shrinks (hold_unresolved): the group stays unresolved, nothing is named or saved for it."""
    not_excluded: list[NotExcluded] = field(default_factory=list)
    """Rivals of named effects the data leave room for (rivals_not_excluded)."""
    aliased: list[Aliased] = field(default_factory=list)
    """Periodic effects the plan's even spacing kept from being looked for (said on the summary)."""

    @property
    def local(self) -> LocalError | None:
        """The first error outside the vocabulary (the one that explains most), if any."""
        return self.local_errors[0] if self.local_errors else None

    def params(self) -> dict[str, dict[str, float]]:
        """The final model's parameters per effect (averaged over an unresolved period's candidates
        where that applies; a term holding an unresolved group, HELD_PREFIX, is not the model's: `held`)."""
        return {**{k: v for k, v in self.final.params().items() if not k.startswith(HELD_PREFIX)}, **self.averaged}

    @property
    def added(self) -> list[str]:
        return [s.effect for s in self.steps]

    def final_model(self, noise: dict[str, float] | None = None) -> ErrorModel:
        """The final model (the offset is left out: it belongs to the datum, not the axis; so is
        `environment`, which follows the log of one campaign and is not a parameter of the axis)."""
        effects = {name: {k: params[k] for k in EFFECT_PARAMS[name]} for name, params in self.params().items()
                   if name in EFFECT_PARAMS}
        effects["noise"] = noise or {"sigma_um": round(self.noise_um, 4)}
        return ErrorModel(effects)


def note_once(notes: list[str], text: str, topic: str | None = None) -> None:
    """Add a note once. `topic`: the start of a note whose numbers change from step to step; an
    earlier note on it is replaced, so the reader sees it once, with the final numbers."""
    if topic is not None:
        notes[:] = [n for n in notes if not n.startswith(topic)]
    if text not in notes:
        notes.append(text)
