"""What discovery reports, as typed records: an unresolved group (and a local error that rivals
it), the stand-in a reversal of unknown cause is held by, the starting model's effects as fitted,
the reversal or structure an unresolved group shows, held without a name, and the choice between the
air log and screw growth. Each has `as_dict`, its JSON object
(`axiscal discover --json`, docs/discovery.md), keys in the order they have always had.

Units: deviations µm (the axis's deviation unit), positions mm (its position unit).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from typing import Any


@dataclass(frozen=True)
class Aliased:
    """A periodic effect the plan kept from being looked for: on targets evenly spaced `spacing` apart
    (position unit) a period shorter than `shortest` (twice the spacing) aliases, and the screw leads
    looked for end below it."""

    effect: str
    spacing: float
    shortest: float
    unit: str


@dataclass(frozen=True)
class LocalRival:
    """A local error that would fit as well as an unresolved effect (its `local_rivals`) or as a located
    local error of the other shape (LocalError.shape_rival): what it is, in words, and where (from, to); `between_mm`: for a step placed only between two targets, those targets (as
    LocalError.between_mm), else None."""

    sentence: str
    region_mm: tuple[float, float]
    between_mm: tuple[float, float] | None = None

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"sentence": self.sentence, "region_mm": list(self.region_mm)}
        if self.between_mm is not None:
            out["between_mm"] = list(self.between_mm)
        return out


@dataclass(frozen=True)
class Unresolved:
    """Effects the campaign cannot tell apart or pin down, none of them named: which (`effects`),
    why, the campaign that would tell (`how_to_tell`), and the evidence: each effect's ΔBIC
    (`delta_bic`), or for a period that is not identifiable its candidate periods, best first
    (`periods_mm`) with their ΔBIC to the best (`period_delta_bic`); the local errors that would
    fit as well (`local_rivals`)."""

    effects: tuple[str, ...]
    why: str
    how_to_tell: str
    delta_bic: Mapping[str, float] = field(default_factory=dict)
    periods_mm: tuple[float, ...] | None = None
    period_delta_bic: tuple[float, ...] = ()
    local_rivals: tuple[LocalRival, ...] = ()
    waits_s: float | None = None
    """The longest wait before capture a campaign that tells them needs, s (a named effect's time
    constant beside a rival it does not exclude: NotExcluded.waits_s); None: the planner's own."""
    not_excluded: bool = False
    """The group is a named effect beside a rival the data do not exclude (NotExcluded, planned as a
    follow-up), not effects none of which is named."""
    not_pinned_down: bool = False
    """The group's effects fit (they pass the tests), but the campaign does not pin down their values
    (a drift in time whose rate and pivot break the gates: vocabulary.drift_entry), not rivals."""

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"effects": list(self.effects), "why": self.why, "how_to_tell": self.how_to_tell}
        if self.periods_mm is not None:
            out.update(periods_mm=list(self.periods_mm), delta_bic=list(self.period_delta_bic))
        else:
            out["delta_bic"] = dict(self.delta_bic)
        if self.local_rivals:
            out["local_rivals"] = [r.as_dict() for r in self.local_rivals]
        if self.not_pinned_down:
            out["not_pinned_down"] = True
        return out


@dataclass(frozen=True)
class NotExcluded:
    """A rival of a named effect that the data leave room for: fitted beside the final model its size
    (`size_key`, `value` ± `error`) is under 2σ, but 2σ reaches a good share of the named effect's
    size, so the named effect's values may hold part of it; `how_to_tell`: the campaign that would
    show both; `named_size`: the named effect's own size (its first size parameter, the same unit);
    `waits_s`: for a named effect with a time constant, the longest wait that campaign needs (s; None
    otherwise)."""

    rival: str
    named: str
    size_key: str
    value: float
    error: float
    how_to_tell: str
    named_size: float
    waits_s: float | None = None

    def to_tell(self) -> Unresolved:
        """The group a follow-up should tell apart: the named effect and its rival, with the longest wait
        that would show a time constant fade (Unresolved.not_excluded)."""
        return Unresolved((self.named, self.rival), "not excluded", self.how_to_tell, waits_s=self.waits_s,
                          not_excluded=True)

    def as_dict(self) -> dict[str, Any]:
        return {"rival": self.rival, "beside": self.named, self.size_key: round(self.value, 4),
                "standard_error": round(self.error, 4), "how_to_tell": self.how_to_tell,
                "waits_up_to_s": None if self.waits_s is None else round(self.waits_s, 2)}


@dataclass(frozen=True)
class TableGap:
    """One table of a joint fit, its points alone (unweighted): the RMS of the final model's residual
    (`gap_um`) and the run-to-run scatter (`noise_um`), both in the deviation unit."""

    gap_um: float
    noise_um: float

    def as_dict(self) -> dict[str, float]:
        return {"gap_um": round(self.gap_um, 4), "noise_um": round(self.noise_um, 4)}


@dataclass(frozen=True)
class InTheFit:
    """A term in the final model that is not a named effect: the effect whose form it has
    (`effect`), the group it stands for (`rivals`), what the data show, in words (`observable`), its
    fitted `params`, and the gap had nothing been added for it (`gap_without_um`)."""

    effect: str
    rivals: tuple[str, ...]
    observable: str
    params: Mapping[str, float]
    gap_without_um: float

    def as_dict(self) -> dict[str, Any]:
        return {"effect": self.effect, "rivals": list(self.rivals), "observable": self.observable,
                "params": {k: round(float(v), 4) for k, v in self.params.items()},
                "gap_without_um": round(self.gap_without_um, 4)}


@dataclass(frozen=True)
class StandIn(InTheFit):
    """Rivals that predict the same deviation wherever the campaign's axis is used (backlash and
    settling at a constant wait): `effect` is the one in the final model in their place (not named)."""


@dataclass(frozen=True)
class Held(InTheFit):
    """What an unresolved group shows, held in the final model so that the gap shrinks, while the
    group stays unresolved: never named, never saved with the model. `effect`: the rival whose form
    holds it (the one that explains most)."""


@dataclass(frozen=True)
class StartingEffect:
    """An effect of the starting model as fitted at the end, beside the named effects: the
    parameters the model gave (`given`), whether all were (`fixed`: held, not fitted), its
    parameters and their 1-σ errors, and for a fitted one the F-test of the final fit against it left
    out (`p_value`) and whether it differs from zero (`significant`)."""

    given: tuple[str, ...]
    fixed: bool
    params: Mapping[str, float]
    errors: Mapping[str, float] = field(default_factory=dict)
    p_value: float | None = None
    significant: bool | None = None

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"given": list(self.given), "fixed": self.fixed,
                               "params": {k: round(float(v), 4) for k, v in self.params.items()}}
        if self.p_value is not None:
            out.update(significant=self.significant,
                       standard_errors={k: float(f"{v:.3g}") for k, v in self.errors.items()},
                       p_value=float(f"{self.p_value:.3g}"))
        return out


@dataclass(frozen=True)
class Choice:
    """Where environment and thermal_drift both explained the run-to-run slope change at a step:
    which was chosen, the other, thermal_drift's pivot (mm) and whether it is at the laser datum,
    what each explains (%) and its ΔBIC, and why, in words."""

    step: int
    chosen: str
    other: str
    pivot_mm: float
    pivot_at_laser_datum: bool
    environment_explained_pct: float
    thermal_drift_explained_pct: float
    delta_bic_environment: float
    delta_bic_thermal_drift: float
    why: str

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)
