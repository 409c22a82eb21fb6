"""A campaign's results in one place: the ISO 230-2 evaluation, the outliers, the uncertainty budget
and the verdict, for a campaign directory or a point table. `analyze`, `report`, `guide` and
`verify` all use it, so that they never disagree.

A campaign directory (or its points.csv) brings its plan (points and runs planned), its config
(tolerances, the instrument's certificate, the sensors) and whether it was measured on the
simulated machine. A bare point table has none of that: it is judged against the grid it shows,
with the uncertainty inputs' defaults, named as such.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from campaign import capture_methods
from campaign.config import Config
from campaign.errors import InputError
from campaign.iso230 import STANDARDS, Evaluation, Standard, evaluate
from campaign.outliers import Outliers, find_outliers
from campaign.pointtable import PointTable, read_points
from campaign.record import META_FILE, open_campaign, read_recorded_points, without_torn_line
from campaign.specs import PURPOSES
from campaign.uncertainty import Budget, budget
from campaign.verdict import Planned, Verdict, completeness, judge

TOLERANCE_KEYS = {"A": "tolerance", "E": "tolerance_e", "B": "tolerance_b", "R": "tolerance_r"}
"""Parameter -> its [campaign] key."""


@dataclass
class Assessment:
    """Everything said about one campaign. `directory`: the campaign directory, None for a bare
    table. `simulated`: measured on the simulated machine."""

    source: str
    table: PointTable
    evaluation: Evaluation
    outliers: Outliers
    uncertainty: Budget
    verdict: Verdict
    tolerances: dict[str, float]
    config: Config | None = None
    planned: Planned | None = None
    directory: Path | None = None
    meta: dict | None = None
    simulated: bool = False

    def as_json(self) -> dict:
        """The evaluation's JSON with `verdict`, `reasons`, `uncertainty`, `outliers`."""
        out = self.evaluation.as_json()
        v = self.verdict.as_json()
        out.update(verdict=v["verdict"], reasons=v["reasons"], decision_rule=v["rule"], checks=v["checks"],
                   verdict_notes=v["notes"], tolerances={k: t for k, t in self.tolerances.items() if t},
                   uncertainty=self.uncertainty.as_json(), points=len(self.table),
                   outliers=[o.as_dict() for o in self.outliers.found],
                   outlier_test={"alpha": self.outliers.alpha, "critical": self.outliers.critical,
                                 "s_with_outliers": self.outliers.s_with, "s_without_outliers": self.outliers.s_without},
                   simulated=self.simulated)
        if self.planned is not None:
            out["planned_points"] = self.planned.points
        return out


def assess(table: PointTable, config: Config | None = None, planned: Planned | None = None,
           tolerance: float | None = None, standard: Standard = STANDARDS["iso230-2:2014"], source: str = "",
           directory: Path | None = None, meta: dict | None = None) -> Assessment:
    """Assess `table`. `tolerance`: the tolerance on A (deviation unit), instead of the config's."""
    ev = evaluate(table, standard)
    tolerances = {k: float(getattr(config.campaign, key)) if config is not None else 0.0
                  for k, key in TOLERANCE_KEYS.items()}
    if tolerance is not None:
        tolerances["A"] = tolerance
    outliers = find_outliers(table)
    unc = budget(table, ev, config)
    purpose, follows = ((config.campaign.purpose, config.campaign.follows) if config is not None
                        else table_purpose(table))
    verdict = judge(table, ev, tolerances, unc, outliers, planned, purpose, follows)
    method = config.capture.method if config is not None else table.meta.get("capture", "")
    if method in capture_methods.METHODS and not capture_methods.method(method).iso_230_2:
        why = (f"captured with the {method} method, not an ISO 230-2 test: "
               f"{capture_methods.method(method).not_iso_why}, so A, E, B and R are indicative")
        verdict = replace(verdict, reasons=(why, *verdict.reasons))
    simulated = is_simulated(table, config, meta)
    return Assessment(source or table.source, table, ev, outliers, unc, verdict, tolerances, config, planned,
                      directory, meta, simulated)


def table_purpose(table: PointTable) -> tuple[str, str]:
    """A bare table's purpose and what it follows, from its `# purpose:` and `# follows:` comments
    (a scan's table says `diagnostic`); acceptance when it says nothing."""
    purpose = table.meta.get("purpose", "acceptance")
    if purpose not in PURPOSES:
        raise InputError(f"{table.source}: '# purpose: {purpose}' must be one of {', '.join(PURPOSES)}")
    return purpose, table.meta.get("follows", "")


def is_simulated(table: PointTable, config: Config | None, meta: dict | None) -> bool:
    """Measured on the simulated machine or with the simulated laser (a LinuxCNC demo: a real
    controller, a simulated reading): said by meta.json, the config, or the table's own comment."""
    if meta and (meta.get("simulated") or meta.get("driver") == "sim"):
        return True
    if config is not None and config.simulated:
        return True
    return str(table.meta.get("simulated", "")).startswith("yes")


def campaign_dir_of(path: str | Path) -> Path | None:
    """The campaign directory `path` is, or whose points.csv it is; None for a bare table."""
    p = Path(path)
    if p.is_dir():
        return p
    if p.name == "points.csv" and (p.parent / META_FILE).is_file():
        return p.parent
    return None


def incomplete(path: str | Path, table: PointTable | None = None) -> list[str]:
    """Why the campaign whose directory or points.csv `path` is was not measured completely (its
    plan's points and runs); for a bare point table, the points its own grid lacks (targets ×
    directions × runs), of `table` when the caller has read it already (a dense table takes a
    second or so to read)."""
    directory = campaign_dir_of(path)
    if directory is None:
        return completeness(read_points(path, partial=True) if table is None else table, None)
    a = assess_path(directory)
    return completeness(a.table, a.planned)


def assess_path(path: str | Path, tolerance: float | None = None,
                standard: Standard = STANDARDS["iso230-2:2014"]) -> Assessment:
    """Assess a campaign directory, a campaign's points.csv, or a bare point table. A table still
    being recorded, or one stopped early, is assessed as far as it goes (never an error)."""
    directory = campaign_dir_of(path)
    if directory is None:
        table = read_points(path, partial=True)
        return assess(table, tolerance=tolerance, standard=standard, source=str(path))
    campaign = open_campaign(directory)
    points = directory / "points.csv"
    if not points.is_file() or not any(ln[:1].isdigit() for ln in without_torn_line(points).splitlines()):
        raise InputError(f"{points}: no point recorded yet")
    table = read_recorded_points(directory)  # a torn last line, the point in progress at a crash, left out
    config = campaign.config()  # config.toml, or the config plan.jsonl describes
    planned_points = campaign.meta.get("points_planned")
    planned = Planned(int(planned_points), int(config.plan.cycles)) if planned_points else None
    return assess(table, config, planned, tolerance, standard, str(directory), directory, campaign.meta)
