"""What discovery knows about a measured campaign: where, from which side, when, and how long after
arrival each point was captured; and the starting model with the parameters the user gave.

Units: positions mm (deg), deviations µm (arcsec), times s; without a time column the time is the
point order (one unit per point).
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from campaign import capture_methods
from campaign.config import Config
from campaign.discovery.simulate import SAMPLE_PERIOD_META, sample_times
from campaign.edlen import refractive_index
from campaign.errors import InputError, read_input_bytes, read_toml
from campaign.model import ErrorModel, model_from_dict
from campaign.pointtable import AXIS_KINDS, PointTable, decode_csv, read_points, split_csv
from protocols.units import UNITS, unit_label

CAPTURE_COLUMNS = ("capture_wait_s", "samples")
"""Point-table columns the recorder writes that discovery uses when present."""


@dataclass
class CampaignData:
    """One measured campaign, one entry per point (rows of t and w: one column per sample).

    x: target, mm. d: approach direction, ±1. run: run number. y: deviation, µm.
    t: sample times, s since start (or point order). w: sample waits since arrival, s (None when
    unknown). time_source: "time_s" or "point order". env: environment columns present.
    air_index_change: n/n0 - 1 per point from the air log (n0: the first point's index; a column
    that is missing is taken at its standard value), None without an air log.
    campaign: which campaign each point belongs to (0, 1, ...; None: all of one campaign). Campaigns
    fitted together (`join_campaigns`) share the effects and get an offset each (a new laser datum);
    their times and runs are each their own campaign's.
    kind: the axis kind, "linear" (mm, µm) or "rotary" (deg, arcsec): x and y are in its units.
    u: each point's standard uncertainty, deviation unit (None: every point alike). The fit weighs
    each point by 1/u² and the significance tests use it (docs/discovery.md, "Tables fitted
    together"): a table's repeatability, or a scan profile's bin uncertainty (`profile_uncertainty`).
    datum: which offset each point has (0, 1, ...; None: one per campaign). A scan profile's every
    sweep (pass and direction) has its own: its level is referred to one rest and shifted by the
    clocks' offset times the velocity, with the sign of the direction (docs/scan.md).
    sloped: True at the points whose datum has its own slope along the axis too, when fitted with
    another table (None: none has): a scan profile's sweeps, whose timing error grows along each
    with the clocks' rate error (tenths of a ppm) and their wander, differently in each sweep.
    """

    x: np.ndarray
    d: np.ndarray
    run: np.ndarray
    y: np.ndarray
    t: np.ndarray
    w: np.ndarray | None
    time_source: str
    env: dict[str, np.ndarray]
    air_index_change: np.ndarray | None = None
    campaign: np.ndarray | None = None
    kind: str = "linear"
    u: np.ndarray | None = None
    datum: np.ndarray | None = None
    sloped: np.ndarray | None = None
    remembered: OrderedDict = field(default_factory=OrderedDict, init=False, repr=False, compare=False)
    """Arrays computed from this data set once (campaign.discovery.fit.remembered): its arrays
    are not to be changed in place."""
    remembered_bytes: int = field(default=0, init=False, repr=False, compare=False)
    """The bytes the arrays in `remembered` hold (kept as they come and go: summing them on every
    call costs more than the products they save once there are thousands of small ones)."""

    @property
    def position_unit(self) -> str:
        """The targets' unit as people read it: mm, or deg on a rotary axis."""
        return UNITS[self.kind][0]

    @property
    def deviation_unit(self) -> str:
        """The deviations' unit as people read it: µm, or arcsec on a rotary axis."""
        return unit_label(UNITS[self.kind][1])

    def __len__(self) -> int:
        return len(self.y)

    @cached_property
    def targets_mm(self) -> np.ndarray:
        """The distinct targets, sorted (positions rounded to 1e-6, as target_index; computed once: the
        local search asks for them at every step)."""
        targets = np.unique(np.round(self.x, 6))
        targets.flags.writeable = False  # shared by every caller
        return targets

    @cached_property
    def target_index(self) -> np.ndarray:
        """Index of each point's target among the distinct targets (computed once: the arrays are not
        changed in place, and on a dense table every cross-validation asks for it): its place in targets_mm."""
        return np.searchsorted(self.targets_mm, np.round(self.x, 6))

    @property
    def campaign_index(self) -> np.ndarray:
        """The campaign of each point (0 for a single campaign)."""
        return np.zeros(len(self.y), dtype=int) if self.campaign is None else self.campaign

    @property
    def datum_index(self) -> np.ndarray:
        """The offset (datum) of each point: its sweep's on a scan profile, else its campaign's."""
        return self.campaign_index if self.datum is None else self.datum

    @property
    def datums(self) -> int:
        """How many offsets are fitted (one per datum)."""
        return int(self.datum_index.max()) + 1 if len(self.y) else 1

    @property
    def row_scale(self) -> np.ndarray | None:
        """Each point's weight's square root, u_ref / u (u_ref: the largest u, the coarsest table's,
        so that a weighted residual is in that table's deviation unit whatever order the tables were
        given in); None when every point is alike."""
        if self.u is None or not len(self.u) or np.all(self.u == self.u[0]):
            return None
        return np.asarray(float(np.max(self.u)) / self.u)

    @property
    def campaigns(self) -> int:
        """How many campaigns are fitted together."""
        return int(self.campaign_index.max()) + 1 if len(self.y) else 1

    @property
    def time_unit(self) -> str:
        return "s" if self.time_source == "time_s" else "points"


def keep_rows(data: CampaignData, keep: np.ndarray) -> CampaignData:
    """The campaign with only the points where `keep` (bool per point) is True (tables and datums
    numbered anew in their order: a table left without points is no longer one)."""
    return CampaignData(x=data.x[keep], d=data.d[keep], run=data.run[keep], y=data.y[keep], t=data.t[keep],
                        w=None if data.w is None else data.w[keep], time_source=data.time_source,
                        env={k: v[keep] for k, v in data.env.items()},
                        air_index_change=None if data.air_index_change is None else data.air_index_change[keep],
                        campaign=None if data.campaign is None else _renumbered(data.campaign[keep]), kind=data.kind,
                        u=None if data.u is None else data.u[keep],
                        datum=None if data.datum is None else _renumbered(data.datum[keep]),
                        sloped=None if data.sloped is None else data.sloped[keep])


def _renumbered(index: np.ndarray) -> np.ndarray:
    """Group numbers 0, 1, ... in the order of their first appearance kept (rows left out may
    have emptied a group)."""
    _, first, inverse = np.unique(index, return_index=True, return_inverse=True)
    order = np.argsort(np.argsort(first))
    return np.asarray(order[inverse.ravel()])


def _padded(rows: list[np.ndarray]) -> np.ndarray:
    """Sample matrices of several campaigns stacked, padded with NaN to the widest."""
    width = max(r.shape[1] for r in rows)
    return np.vstack([np.pad(r, ((0, 0), (0, width - r.shape[1])), constant_values=np.nan) for r in rows])


def join_campaigns(parts: list[CampaignData], names: list[str]) -> CampaignData:
    """Several campaigns of one axis as one data set for a joint fit: the points of each in turn,
    `campaign` saying whose; runs numbered on (the second campaign's run 1 follows the first's
    last run), each campaign's times its own (time since its own start: a thermal drift starts
    again with each campaign). A wait or an air log is used only when every campaign has it.
    InputError when some have a time column and others not, or when the tables are of different axis
    kinds (and so units: mm and µm, deg and arcsec) (`names`: the files, for the message)."""
    if len(parts) == 1:
        return parts[0]
    other = next((i for i, p in enumerate(parts) if p.kind != parts[0].kind), None)
    if other is not None:
        one, then = parts[0], parts[other]
        raise InputError(f"{names[other]}: a {then.kind} axis's table ({then.position_unit}, {then.deviation_unit}), "
                         f"but {names[0]} is a {one.kind} axis's ({one.position_unit}, {one.deviation_unit}): "
                         "campaigns fitted together must be of one axis, in one unit")
    sources = {p.time_source for p in parts}
    if len(sources) > 1:
        with_time = [n for n, p in zip(names, parts) if p.time_source == "time_s"]
        without = [n for n, p in zip(names, parts) if p.time_source != "time_s"]
        raise InputError(f"{without[0]}: no time_s column, but {with_time[0]} has one: campaigns fitted together "
                         "must all have a time column or none")
    runs, first = [], 0
    for p in parts:
        runs.append(p.run - p.run.min() + 1 + first)
        first = int(runs[-1].max())
    datums, first = [], 0
    for p in parts:
        datums.append(p.datum_index + first)
        first += p.datums
    # a scan profile's bins are captured moving, long after any arrival: an infinite wait (settled)
    moving = [p.w if p.w is not None else np.full((len(p), 1), np.inf) if p.u is not None else None for p in parts]
    waits = None if any(w is None for w in moving) or all(p.w is None for p in parts) else _padded(
        [w for w in moving if w is not None])
    env_keys = set.intersection(*(set(p.env) for p in parts))
    air = None if any(p.air_index_change is None for p in parts) else np.concatenate(
        [p.air_index_change for p in parts if p.air_index_change is not None])
    return CampaignData(x=np.concatenate([p.x for p in parts]), d=np.concatenate([p.d for p in parts]),
                        run=np.concatenate(runs), y=np.concatenate([p.y for p in parts]),
                        t=_padded([p.t for p in parts]), w=waits, time_source=parts[0].time_source,
                        env={k: np.concatenate([p.env[k] for p in parts]) for k in sorted(env_keys)},
                        air_index_change=air,
                        campaign=np.concatenate([np.full(len(p), i) for i, p in enumerate(parts)]),
                        kind=parts[0].kind,
                        u=np.concatenate([np.full(len(p), own) if np.isscalar(own) else own
                                          for p, own in zip(parts, _own_uncertainties(parts))]),
                        datum=np.concatenate(datums),
                        sloped=np.concatenate([p.sloped if p.sloped is not None else np.zeros(len(p), dtype=bool)
                                               for p in parts]))


def _own_uncertainties(parts: list[CampaignData]) -> list[np.ndarray | float]:
    """Each part's points' uncertainty in a joint fit, deviation unit: a profile's own per bin, a
    stop-and-go table's repeatability; a table that repeats nothing (one run, as a follow-up of one
    cycle) cannot show its scatter, and takes the pooled repeatability of the parts that can (one
    axis, one laser): the spread of its deviations would be the size of the errors sought, and
    its points would weigh next to nothing. The spread only when no part repeats anything."""
    own: list[np.ndarray | float | None] = [p.u if p.u is not None else repeated_scatter(p) for p in parts]
    known = [float(o) for o in own if isinstance(o, float)]
    pooled = float(np.sqrt(np.mean(np.square(known)))) if known else None
    return [o if o is not None else (pooled if pooled is not None else repeatability(p))
            for p, o in zip(parts, own)]


def repeatability(data: CampaignData) -> float:
    """A stop-and-go table's repeatability, deviation unit (`repeated_scatter`); the RMS about the
    mean when nothing is repeated."""
    scatter = repeated_scatter(data)
    return scatter if scatter is not None else (float(np.std(data.y)) or 1.0)


def repeated_scatter(data: CampaignData) -> float | None:
    """The scatter of a stop-and-go table's points left when each (target, direction) has its mean
    and each run its level (the run-to-run drift of a warming axis is not scatter), pooled,
    deviation unit; None when nothing is repeated (one run). The unit of its points' weights in a
    joint fit (`join_campaigns`)."""
    _, cell = np.unique(data.target_index * 2 + (data.d > 0), return_inverse=True)
    _, run = np.unique(data.run, return_inverse=True)
    cell, run = cell.ravel(), run.ravel()
    cells, runs = int(cell.max()) + 1 if len(cell) else 0, int(run.max()) + 1 if len(run) else 0
    dof = len(data) - cells - runs + 1
    if dof <= 0 or runs < 2:
        return None
    left, level = data.y.astype(float), np.zeros(runs)
    for _ in range(100):  # the two-way means by alternating (backfitting): linear in the rows
        by_cell = np.bincount(cell, left - level[run], cells) / np.bincount(cell, minlength=cells)
        new = np.bincount(run, left - by_cell[cell], runs) / np.bincount(run, minlength=runs)
        if np.max(np.abs(new - level)) < 1e-9:
            level = new
            break
        level = new
    residual = left - by_cell[cell] - level[run]
    return float(np.sqrt(np.sum(residual**2) / dof)) or 1.0


def campaign_data(table: PointTable, capture: dict[str, np.ndarray] | None = None,
                  sample_period_s: float | None = None) -> CampaignData:
    """CampaignData from a point table. `capture`: capture_wait_s (s) and samples per point, if
    known (a table from campaign.discovery.simulate carries them in `optional`); sample_period_s: the
    instrument's sample period, s (default: table metadata, else one sample per point)."""
    capture = dict(capture or {})
    for name in CAPTURE_COLUMNS:
        if name in table.optional:
            capture.setdefault(name, table.optional[name])
    if sample_period_s is None and SAMPLE_PERIOD_META in table.meta:
        sample_period_s = float(table.meta[SAMPLE_PERIOD_META])
    n = len(table)
    if "time_s" in table.optional:
        end, source = table.optional["time_s"], "time_s"
    else:
        end, source = np.arange(n, dtype=float), "point order"
    wait = capture.get("capture_wait_s")
    samples = capture.get("samples") if sample_period_s and source == "time_s" else None
    if samples is None:
        samples, period = np.ones(n), 1.0
    else:
        period = sample_period_s or 1.0  # samples are known only with a sample period
    t, w = sample_times(end, wait if wait is not None else np.zeros(n), samples, period)
    env = {k: v for k, v in table.optional.items() if k not in ("time_s", *CAPTURE_COLUMNS)}
    u, datum, sloped = None, None, None
    if PROFILE_U in table.extra:  # a scan profile's bins: their uncertainty, each sweep its own offset
        u = table.extra[PROFILE_U].astype(float)
        datum = _renumbered(table.run.astype(np.int64) * 2 + (table.direction > 0))
        sloped = np.ones(n, dtype=bool)
    return CampaignData(x=table.target.astype(float), d=table.direction.astype(float), run=table.run,
                        y=table.deviation.astype(float), t=t, w=w if wait is not None else None,
                        time_source=source, env=env, air_index_change=air_index_change(env, n), kind=table.kind,
                        u=u, datum=datum, sloped=sloped)


AIR_STANDARD = {"air_temp_c": 20.0, "air_pressure_hpa": 1013.25, "humidity_pct": 50.0}
"""Values taken for an air column the table does not have (°C, hPa, %)."""


def air_index_change(env: dict[str, np.ndarray], n: int) -> np.ndarray | None:
    """n/n0 - 1 per point (dimensionless) from the air columns present (Edlén, reference §6), with
    n0 the first point's index; None when the table has no air column."""
    if not n or not set(AIR_STANDARD) & set(env):
        return None
    cols = {k: env.get(k, np.full(n, v)) for k, v in AIR_STANDARD.items()}
    index = np.array([refractive_index(t, p * 100.0, rh) for t, p, rh in
                      zip(cols["air_temp_c"], cols["air_pressure_hpa"], cols["humidity_pct"])])
    return index / index[0] - 1


def read_campaign(path: str | Path, table: PointTable | None = None, recorded: Config | None = None) -> CampaignData:
    """Read a point table for discovery: the table itself (`table` when it was read already), its
    capture columns and, from the campaign's config it was `recorded` with (read by the command line),
    the sample period (1/instrument.rate_hz) and the capture method: a method that captures the position
    at its window's end (capture_methods.CaptureMethod.value_at_end: the stability trigger's fitted line)
    is modelled there, not as its window's mean (a settling that decays through the window would
    otherwise differ between the directions like a backlash: -0.26 µm on the shipped horizontal axis,
    given its own model)."""
    table = read_points(path) if table is None else table
    capture = {name: table.extra[name] for name in CAPTURE_COLUMNS if name in table.extra}
    period = None
    if "samples" in capture and recorded is not None and SAMPLE_PERIOD_META not in table.meta:
        period = 1.0 / recorded.instrument.rate_hz
        if capture_methods.method(recorded.capture.method).value_at_end:
            capture["samples"] = np.ones(len(table))  # the position at the capture's end
    return campaign_data(table, capture, period)


def read_start_model(path: str | Path | None) -> tuple[ErrorModel, dict[str, set[str]]]:
    """The starting model and, per effect, the parameter names the file gives (the rest is fitted).
    Without a file: linear_scale with its slope to fit."""
    if path is None:
        return ErrorModel({"linear_scale": {}}), {"linear_scale": set()}
    name = str(path)
    data = read_toml(path, "a model TOML file")
    model = model_from_dict(data, name, require_all=False)
    given = {effect: set(params) for effect, params in data.get("effects", {}).items()}
    model.effects = {effect: {k: v for k, v in params.items() if k in given[effect]}
                     for effect, params in model.effects.items()}
    return model, given


PROFILE_BIN = 0.05
"""A scan's profile (campaign/stream/scan.py, profile.csv) is averaged per pass and direction over
bins this wide (axis unit: mm or deg), centred on multiples of it, or a multiple of it holding at
least PROFILE_BIN_SAMPLES samples on a fast or slowly sampled scan. Averaging over a bin of width h
scales a wave of period P by sinc(h/P): 0.1 % for the shortest screw lead looked for (2 mm) at
0.05 mm, 0.004 % for a 10 mm one; a bump or step narrower than a few bins cannot be told from the
wave anyway."""
PROFILE_BIN_SAMPLES = 4
"""The fewest samples a bin holds on average (the bin widens in steps of PROFILE_BIN until it does)."""
PROFILE_MIN_SHARE = 0.9
"""A bin is kept only when it holds at least this share of the median bin's samples: a bin at the
end of a pass, which the constant-velocity stretch only partly covers, would have its mean position
off its centre, and is left out."""
PROFILE_HEADER = ("direction", "pass", "time_s")
"""The profile's columns besides position_<unit> and deviation_<unit> (docs/scan.md)."""


def is_profile(path: str | Path) -> bool:
    """Does the file start (after its `#` comments) with a scan profile's header (position_...)?"""
    try:
        with open(path, encoding="utf-8-sig", errors="replace") as f:
            for line in f:
                if line.strip() and not line.lstrip().startswith("#"):
                    return line.strip().lower().startswith("position_")
    except OSError:
        return False
    return False


def read_profile(path: str | Path) -> tuple[PointTable, str]:
    """A scan's profile.csv as a point table for discovery: per pass (the table's run) and direction,
    the samples averaged over bins PROFILE_BIN wide (target: the bin's centre; deviation and time_s:
    the means), only the bins every pass and direction fill (PROFILE_MIN_SHARE), in time order; its
    `# key: value` comments kept as metadata. Also a sentence saying what was averaged. InputError
    naming the file and line on a malformed file."""
    name = str(path)
    meta, header, number, lines = split_csv(decode_csv(name, read_input_bytes(path, "a scan profile")))
    headers = {k: [t.replace("target", "position"), "direction", "pass", dev, "time_s"]
               for k, (t, dev) in AXIS_KINDS.items()}
    kind = next((k for k, wanted in headers.items() if header is not None and header[:5] == wanted), "")
    if not kind:
        got = ",".join(header or [])[:80]
        raise InputError(f"{name}:{number}: not a scan profile's header: expected "
                         f"{','.join(headers['linear'])} (docs/scan.md), got {got}")
    rows: list[list[float]] = []
    for number, cells in lines:
        row = ",".join(cells)[:60]
        if len(cells) < 5:
            raise InputError(f"{name}:{number}: {len(cells)} columns, the header has 5")
        try:
            direction = {"+": 1.0, "-": -1.0}[cells[1]]
            values = [float(cells[0]), direction, float(cells[2]), float(cells[3]), float(cells[4])]
        except (KeyError, ValueError):
            raise InputError(f"{name}:{number}: '{row}' is not a profile row (position, +/-, pass, "
                             "deviation, time)") from None
        if not all(np.isfinite(values)):
            raise InputError(f"{name}:{number}: '{row}' has a value that is not a finite number")
        rows.append(values)
    if not rows:
        raise InputError(f"{name}: no profile rows")
    table, said = profile_table(np.array(rows), kind, meta, name)
    return table, said


def profile_table(samples: np.ndarray, kind: str, meta: dict[str, str], name: str) -> tuple[PointTable, str]:
    """The point table of a profile's samples (rows: position, direction ±1, pass, deviation, time
    s): see read_profile."""
    pos, d, passes, dev, time = samples.T
    lane = np.flatnonzero((np.diff(passes) == 0) & (np.diff(d) == 0))
    spacing = float(np.median(np.abs(np.diff(pos)[lane]))) if len(lane) else 0.0
    width = PROFILE_BIN * max(1, math.ceil(PROFILE_BIN_SAMPLES * spacing / PROFILE_BIN - 1e-9))
    cell = np.round(pos / width).astype(np.int64)
    groups = np.column_stack([passes.astype(np.int64), d.astype(np.int64), cell])
    keys, where, count = np.unique(groups, axis=0, return_inverse=True, return_counts=True)
    where = where.ravel()
    mean_dev = np.bincount(where, dev) / count
    mean_time = np.bincount(where, time) / count
    mean_pos = np.bincount(where, pos) / count
    full = count >= PROFILE_MIN_SHARE * np.median(count)
    lanes = {(int(p), int(s)) for p, s, _ in keys}
    cells_in: dict[int, set[tuple[int, int]]] = {}
    for (p, s, c), ok in zip(keys.tolist(), full):
        if ok:
            cells_in.setdefault(c, set()).add((p, s))
    common = {c for c, have in cells_in.items() if have == lanes}
    keep = full & np.array([c in common for c in keys[:, 2].tolist()])
    if not keep.any():
        raise InputError(f"{name}: no position is covered by every pass in both directions: nothing to compare")
    order = np.flatnonzero(keep)[np.argsort(mean_time[keep], kind="stable")]
    target = np.round(keys[order, 2] * width, 6)
    u = profile_uncertainty(keys[order, 0], keys[order, 1], target, mean_dev[order])
    off = float(np.max(np.abs(mean_pos[order] - target)))
    unit = UNITS[kind][0]
    table = PointTable(kind=kind, run=keys[order, 0].astype(int), direction=keys[order, 1].astype(int),
                       target=target, deviation=mean_dev[order],
                       optional={"time_s": mean_time[order] - float(time.min())},
                       meta={**meta, "profile_bin": f"{width:g} {unit}"}, extra={PROFILE_U: u}, source=name)
    said = (f"{name}: a scan's profile: {len(dev)} samples averaged per pass and direction over bins "
            f"{width:g} {unit} wide, {len(common)} positions from {target.min():g} to {target.max():g} {unit} "
            f"({len(table)} points; a bin's mean position is within {off:.2g} {unit} of its centre)")
    return table, said


PROFILE_U = "uncertainty"
"""The column of a profile's point table (`profile_table`, its `extra`) with each bin's standard
uncertainty, deviation unit (`profile_uncertainty`)."""


def profile_uncertainty(run: np.ndarray, direction: np.ndarray, target: np.ndarray, deviation: np.ndarray) -> np.ndarray:
    """Each bin's standard uncertainty (deviation unit), one value per sweep (pass and direction):
    the bins' own scatter, from the second differences of the bins along the sweep (var = 6·u² for
    independent bins; a screw lead or a bow hardly changes a second difference over a fraction of a
    millimetre). What the timing adds that averaging does not shrink is the same along a sweep
    (the clocks' offset times the velocity) or grows along it (their rate error, as a scale error):
    it is no weight but each sweep's own offset and slope (read_campaign, CampaignData.datum and
    sloped)."""
    out = np.zeros(len(target))
    for p, s in set(zip(run.tolist(), direction.tolist())):
        bins = np.flatnonzero((run == p) & (direction == s))
        bins = bins[np.argsort(target[bins])]
        second = np.diff(deviation[bins], 2)
        out[bins] = math.sqrt(float(np.mean(second**2)) / 6) if len(second) else math.nan
    if np.all(np.isnan(out)):
        return np.ones(len(target))
    return np.where(np.isnan(out), np.nanmax(out), np.maximum(out, 1e-6))
