"""`axiscal discover POINTS.csv [MORE.csv ...] [--model MODEL.toml] [--json] [--plot OUT] [--save NEW.toml]
[--follow-up -o FOLLOW.toml [--config CONFIG]]`: name the effects the model is missing, and plan the
campaign that would separate what is left unresolved (campaign/discovery/, docs/discovery.md)."""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Collection, Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from campaign.commands import SUMMARY, kept_sim_model
from campaign.config import Config, load_config
from campaign.discovery.data import (
    CampaignData,
    is_profile,
    join_campaigns,
    keep_rows,
    read_campaign,
    read_profile,
    read_start_model,
)
from campaign.discovery.fit import derived
from campaign.discovery.followup import FollowUp, is_drift_shape_group, plan_follow_up, regions_to_measure
from campaign.discovery.local import LocalError, Zone, zones
from campaign.discovery.locate import Located, row_of_singles, short
from campaign.discovery.records import Unresolved
from campaign.discovery.result import Candidate, Discovery
from campaign.discovery.search import discover
from campaign.effects import effect as registered
from campaign.errors import InputError
from campaign.model import ErrorModel, is_model_name
from campaign.outliers import Outliers, find_outliers
from campaign.plan import build_plan
from campaign.plot import check_plot_path
from campaign.pointtable import PointTable, read_points
from campaign.record import META_FILE, read_recorded_points
from campaign.views import make_console, print_json
from protocols.units import UNITS, unit_label


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("discover", help=SUMMARY["discover"],
                       description="Fit MODEL to a measured point table, then name, add and refit the "
                                   "effects the residual shows, until what is left is noise.")
    p.add_argument("files", nargs="+", metavar="POINTS.csv",
                   help="point table CSV (see docs/point-table.md), or a scan's profile.csv (averaged over "
                        "0.05 mm bins, see docs/discovery.md); several campaigns of one axis are fitted "
                        "together: shared effects, an offset per campaign (a new laser datum), each campaign's "
                        "time its own")
    p.add_argument("--model", metavar="MODEL.toml",
                   help="starting model, [effects.NAME] tables; a parameter left out is fitted "
                        "(default: linear_scale only)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    p.add_argument("--verbose", action="store_true",
                   help="after the summary, every step's candidates (ΔBIC, p, cross-validation), the unresolved "
                        "groups in full and the notes")
    p.add_argument("--plot", metavar="OUT", help="write the residual before and after each step (.png or .svg)")
    p.add_argument("--save", metavar="NEW.toml", help="write the final model in the model TOML format")
    p.add_argument("--follow-up", action="store_true",
                   help="write (with -o) a campaign config for the same axis that would separate what is "
                        "unresolved, within its limits, with why each part is there and its machine time")
    p.add_argument("-o", "--output", metavar="FOLLOW.toml", help="--follow-up: where to write the campaign config")
    p.add_argument("--budget-min", type=float, metavar="MIN",
                   help="--follow-up: the most machine time the follow-up may take, min (default: the first "
                        "campaign's)")
    p.add_argument("--config", metavar="CONFIG",
                   help="--follow-up: the first campaign's config (default: config.toml next to the first table)")
    p.set_defaults(func=run)


ROTARY_UNITS = {"µm": "arcsec", "mm": "deg"}
"""A parameter's unit on a rotary axis (the model's keys say µm and mm: they are arcsec and deg there)."""


def unit_of(effect: str, key: str, time_unit: str, kind: str = "linear") -> str:
    """The unit of a model parameter, from its description in its effect's module (campaign/effects/;
    on a rotary axis µm is arcsec and mm is deg; without a time column the time constant of an
    effect in time, one cross-validated by run such as thermal_drift, is in points)."""
    described = registered(effect)
    if key == "tau_s" and described.form is not None and described.form.group == "run" and time_unit != "s":
        return time_unit
    unit = described.params[key].rsplit(", ", 1)[-1].split(" (")[0]
    if kind == "rotary":
        unit = ROTARY_UNITS.get(unit, unit)
    return "" if unit == "1" else unit


def with_error(value: float, error: float | None, unit: str) -> str:
    """'250 s ± 9.1 s (3.6 %)', '10 mm ± 0.0011 mm (0.011 %)' or '250 s'."""
    text = f"{value:.4g} {unit}".rstrip()
    if error is None:
        return text
    pct = 100 * error / abs(value) if value else None
    share = "" if pct is None else f" ({pct:.1f} %)" if pct >= 1 else f" ({pct:.2g} %)"
    return f"{text} ± {error:.2g}{(' ' + unit) if unit else ''}{share}"


SPAN_KEYS = ("start_mm", "end_mm")


def param_text(effect: str, key: str, value: float, errors: dict[str, float], given: Collection[str],
               time_unit: str, kind: str = "linear") -> str:
    """One parameter, once, with its unit and its error; a parameter that is not fitted says why
    it has none: given in the model, or the bow's span (the targets' range)."""
    unit = unit_of(effect, key, time_unit, kind)
    if key in errors:
        return f"{key} = {with_error(value, errors[key], unit)}"
    why = "given" if key in given else "the targets' span, not fitted" if key in SPAN_KEYS else "no error: too few points"
    return f"{key} = {with_error(value, None, unit)} ({why})"


def params_text(effect: str, params: dict[str, float], errors: dict[str, float], given: Collection[str],
                time_unit: str, kind: str = "linear") -> str:
    text = ", ".join(param_text(effect, k, v, errors, given, time_unit, kind) for k, v in params.items())
    if effect == "thermal_drift" and time_unit == "s" and "tau_s" in params:
        rate = drift_rate(effect, params)["initial_rate_ppm_per_h"]
        text += f"; initially {with_error(rate, errors.get('initial_rate_ppm_per_h'), 'µm/m per hour')}"
    return text


SAVED_TAU_POINTS = "time constant in points (no time column)"


def rounded(params: dict[str, float]) -> dict[str, float]:
    return {k: round(float(v), 4) for k, v in params.items()}


def drift_rate(effect: str, params: dict[str, float]) -> dict[str, float]:
    """For thermal drift, the initial rate of the slope change, µm/m per hour (per point without a
    time column: then it is per 3600 points); see discovery.fit.DERIVED."""
    return {k: round(v, 4) for k, v in derived(effect, params).items()}


def outliers_json(outliers: Outliers) -> dict:
    return {"outliers": [o.as_dict() for o in outliers.found],
            "scatter_um": {"with_outliers": None if outliers.s_with is None else round(outliers.s_with, 4),
                           "without_outliers": None if outliers.s_without is None else round(outliers.s_without, 4)}}


def all_outliers_json(outliers: list[Outliers], files: list[str]) -> dict:
    """outliers_json of one campaign; of several: each outlier with its file, the scatter per file."""
    if len(outliers) == 1:
        return outliers_json(outliers[0])
    each = [outliers_json(o) for o in outliers]
    return {"outliers": [{**o, "campaign": f} for e, f in zip(each, files) for o in e["outliers"]],
            "scatter_um": {f: e["scatter_um"] for e, f in zip(each, files)}}


def ranking_json(ranking: list[Candidate]) -> list[dict[str, Any]]:
    return [{"effect": c.name, "explained_pct": round(c.explained_pct, 2), "delta_bic": round(c.delta_bic, 2),
             "p_value": float(f"{c.p_value:.3g}"), "cv_before_um": round(c.cv_before_um, 4),
             "cv_after_um": round(c.cv_after_um, 4), "verdict": c.verdict} for c in ranking]


def errors_json(errors: dict[str, float]) -> dict[str, float]:
    return {k: float(f"{v:.3g}") for k, v in errors.items()}


def as_json(result: Discovery) -> dict:
    """The JSON object: added, gap_before_um, gap_after_um, steps, and the details."""
    return {
        "added": result.added,
        "gap_before_um": round(result.gap_before_um, 4),
        "gap_after_um": round(result.gap_after_um, 4),
        "noise_um": round(result.noise_um, 4),
        "noise_measured": result.noise_measured,
        "time_source": result.time_source,
        "steps": [{"effect": s.effect, "params": rounded(s.params), "standard_errors": errors_json(s.errors),
                   **drift_rate(s.effect, s.params), "gap_before_um": round(s.gap_before_um, 4),
                   "gap_after_um": round(s.gap_after_um, 4),
                   "ranking": ranking_json(s.ranking)} for s in result.steps],
        "remaining": ranking_json(result.remaining),
        "remaining_beside": result.remaining_beside,
        "stand_in": None if result.stand_in is None else result.stand_in.as_dict(),
        "held": [h.as_dict() for h in result.held],
        "not_excluded": [n.as_dict() for n in result.not_excluded],
        "model": {name: rounded(p) for name, p in result.params().items()},
        "model_standard_errors": {name: errors_json(e) for name, e in result.errors.items()},
        "starting_model": {name: entry.as_dict() for name, entry in result.starting.items()},
        "offset_um": round(result.final.offset_um, 4),
        "tables": [t.as_dict() for t in result.tables],
        "disagreement_before": result.disagreement_before,
        "disagreement_after": result.disagreement_after,
        "choices": [c.as_dict() for c in result.choices],
        "unresolved": [u.as_dict() for u in result.unresolved],
        "local": None if result.local is None else result.local.as_dict(),
        "local_errors": [local.as_dict() for local in result.local_errors],
        "zones": [{"sentence": z.sentence, "region_mm": [round(v, 3) for v in z.region_mm],
                   "size_um": round(z.size_um, 4)} for z in zones(result.local_errors)],
        "notes": result.notes,
        "located": {"before": None if result.located_before is None else result.located_before.as_dict(curves=True),
                    "after": None if result.located_after is None else result.located_after.as_dict(curves=True)},
    }


def outlier_notes(outliers: Outliers, kind: str) -> list[str]:
    """What the shared outlier test (campaign.outliers) found and what discovery did with it."""
    if not outliers.found:
        return []
    pos, dev = UNITS[kind][0], unit_label(UNITS[kind][1])
    listed = "; ".join(f"run {o.run} {'+' if o.direction > 0 else '-'} at {o.target:g} {pos}: {o.deviation:+.3f} {dev} "
                       f"(|t| {o.score:.1f} > {o.critical:.1f})" for o in outliers.found)
    return [(f"{len(outliers.found)} reading(s) far from the others at their target, by the outlier test at "
            f"{outliers.alpha:g} for the campaign ({listed}): left out of the fit so that a glitch is not taken for "
            f"physics; the run-to-run scatter is {outliers.s_without:.3f} {dev} without, {outliers.s_with:.3f} {dev} with "
            "them. Measure those points again if the cause is not known.")]


def incomplete_notes(path: str, table: PointTable | None = None) -> list[str]:
    """What the campaign lacks (its plan's points and runs, or its own grid's: of `table`, the file as
    read, when given), said first: what is named rests on the points measured."""
    from campaign.assess import incomplete

    problems = incomplete(path, table)
    if not problems:
        return []
    return [(f"incomplete campaign: {'; '.join(problems)}. What follows rests on the points measured: a run cut "
             "short weighs the targets it reached more than the others; resume the campaign for the whole picture.")]


CV_SAID_UP_TO = 10.0
"""A cross-validated RMS more than this many times the one before is not printed as a number: a fold
could not predict its left-out points (the effect is not determined without them)."""


def cv_text(before: float, after: float, dev: str = "µm") -> str:
    """'CV 0.789 -> 0.654 µm', or, when a fold cannot predict, 'CV 0.789 µm -> not predictable ...'."""
    if after > CV_SAID_UP_TO * max(before, 1e-12):
        return f"CV {before:.3f} {dev} -> over {CV_SAID_UP_TO:g}× (the left-out points cannot be predicted)"
    return f"CV {before:.3f} -> {after:.3f} {dev}"


def ranking_lines(ranking: list[Candidate], dev: str = "µm") -> list[str]:
    return [f"    {c.name:28s} explains {c.explained_pct:5.1f} %  ΔBIC {c.delta_bic:8.1f}  p {c.p_value:.2g}  "
            f"{cv_text(c.cv_before_um, c.cv_after_um, dev)}  {c.verdict}" for c in ranking]


NOISE_UNKNOWN = "not known: no target is read twice in a direction, so the noise is not measured (repeat runs to tell)"


def noise_verdict(result: Discovery) -> str:
    """What the gap left after the final model is: noise (within 1.3 times the run-to-run scatter),
    more than noise, or not known when the campaign repeats nothing. Of tables fitted together, each
    table's own gap must be within 1.3 times its own scatter too (`Discovery.tables`)."""
    if not result.noise_measured:
        return NOISE_UNKNOWN
    if result.gap_after_um > 1.3 * result.noise_um:
        return "more than noise"
    above = [f"table {i} ({gap:.3g} against its own noise {noise:.3g})"
             for i, (gap, noise) in enumerate(((t.gap_um, t.noise_um) for t in result.tables), start=1)
             if np.isfinite(noise) and noise > 0 and gap > 1.3 * noise]
    if above:  # the tables together weigh each by its own scatter: a fine scan can hide a coarse table's gap
        return f"more than noise in {', '.join(above)}, tables in the order given"
    return "noise"


def nothing_named(result: Discovery) -> str:
    """Why no effect is named: nothing significant, or something significant that this campaign
    cannot tell apart (the unresolved list)."""
    if not result.unresolved:
        return "no effect is named: none of the vocabulary explains the residual significantly"
    sizes = []
    for entry in result.unresolved:
        tried = [c for c in result.remaining if c.name in entry.effects]
        if tried:
            best = min(tried, key=lambda c: c.delta_bic)
            sizes.append(f"{' or '.join(entry.effects)} explains {best.explained_pct:.1f} % of it, "
                         f"ΔBIC {best.delta_bic:.1f}")
    size = "; ".join(sizes)
    return ("no effect is named, but the residual is not noise: something significant is there that this campaign "
            f"cannot tell apart or pin down ({size or 'see below'}); see unresolved below for what it could be "
            "and how to tell")


def starting_lines(result: Discovery, time_unit: str) -> list[str]:
    """The starting model's effects as fitted at the end, each parameter with its unit and error,
    and which fitted effect is not significantly different from zero."""
    lines = []
    for name, entry in result.starting.items():
        if entry.fixed:
            lines.append(f"    {name}: held as given ("
                         + ", ".join(f"{k} = {with_error(v, None, unit_of(name, k, time_unit))}"
                                     for k, v in entry.params.items()) + ")")
            continue
        lines.append(f"    {name}: {params_text(name, dict(entry.params), dict(entry.errors), entry.given, time_unit)}")
        if not entry.significant:
            lines.append(f"    [yellow]{name} is not significantly different from zero[/]: leaving it out fits as well "
                         f"(F-test p = {entry.p_value:.2g}, not below 0.05); this campaign does not show it")
    return lines


def first_clause(text: str, most: int = 70) -> str:
    """The gist of a how-to-tell sentence: up to its colon and its first comma outside
    parentheses; without the parentheses when that is still longer than `most` characters."""
    text = text.split(": ", 1)[0]
    depth = 0
    for i, c in enumerate(text):
        depth += (c == "(") - (c == ")")
        if c == "," and depth == 0:
            text = text[:i]
            break
    if len(text) > most:
        text = re.sub(r"\s*\([^()]*\)", "", text)
    return text


def zone_said(zone: Zone) -> str:
    """A zone in words: a local error with the error of its size and place, or a pair of steps."""
    return local_said(zone.members[0]) if len(zone.members) == 1 else zone.sentence


def local_said(local: LocalError) -> str:
    """A local error in words, with the error of its size and place (the axis's units)."""
    e = local.errors
    size = "amplitude_um" if "amplitude_um" in e else None
    place = () if local.between_mm else ("centre_mm", "width_mm")  # a step between targets: not resolved
    errs = ", ".join(f"{k.split('_')[0]} ± {e[k]:.2g} "
                     f"{local.deviation_unit if k.endswith('um') else local.position_unit}"
                     for k in (size, *place) if k and k in e)
    # the errors are this error's: said before its shape rival's clause, which has its own numbers
    return f"{local.shape_sentence()} ({errs}){local.rival_clause()}" if errs else local.sentence()


def summary_lines(result: Discovery, incomplete: list[str], time_unit: str = "s", kind: str = "linear") -> list[str]:
    """What a technician reads first, one short line each: an incomplete campaign, what was named
    with its size and error, the stand-in, what is unresolved and the one thing to do about it,
    the gap against the noise (in the axis's deviation unit; times in `time_unit`)."""
    dev = unit_label(UNITS[kind][1])
    lines = [f"[yellow]incomplete campaign:[/] {note.split(': ', 1)[1].split('. ', 1)[0]}" for note in incomplete]
    final, final_errors = result.params(), result.errors
    for step in result.steps:  # the final model's values (later steps refit the earlier effects)
        params, errors = final.get(step.effect, step.params), final_errors.get(step.effect, step.errors)
        sizes = ", ".join(param_text(step.effect, k, v, errors, (), time_unit, kind).split(" (")[0]
                          for k, v in list(params.items())[:2])
        lines.append(f"named: [bold]{step.effect}[/] {sizes}")
    located = located_lines(result)
    if not result.steps:
        there = result.located_before is not None and bool(result.located_before.regions)
        if there:  # the located regions say what is there, on the same line
            located[0] = located[0].replace("located: ", "; located: ", 1)
        lines.append("named: nothing" + (" (something is there: see unresolved)" if result.unresolved and not there
                                         else "")
                     + (" from the model's effects" if result.local is not None else "")
                     + (located.pop(0) if there else ""))
    lines += located
    found = sorted(zones(result.local_errors), key=lambda z: -abs(z.size_um))
    for zone in found[:SUMMARY_REGIONS]:
        lines.append(f"found outside the model: [bold]{zone_said(zone)}[/]; no effect of the model has this shape")
    if len(found) > SUMMARY_REGIONS:
        lines.append(f"found outside the model: {len(found) - SUMMARY_REGIONS} more local errors, smaller "
                     "(--verbose lists them)")
    if result.stand_in is not None:
        b = abs(result.stand_in.params["b_um"])
        lines.append(f"in the model as a stand-in: a reversal of {b:.1f} {dev} (backlash or settling)")
    for entry in result.unresolved:
        rivals = "".join(f" or a local error at {r.region_mm[0]:g}–{r.region_mm[1]:g}" for r in entry.local_rivals)
        held = "; held in the fit, not named" if any(h.rivals == entry.effects for h in result.held) else ""
        lines.append(f"[yellow]unresolved:[/] {' or '.join(entry.effects)}{rivals}; to tell: "
                     f"{first_clause(entry.how_to_tell)}{held}")
    for rival in result.not_excluded:
        lines.append(f"[yellow]not excluded:[/] {rival.rival} beside {rival.named} ({rival.size_key} "
                     f"{rival.value:.2g} ± {rival.error:.2g} {dev} beside it); to tell: {first_clause(rival.how_to_tell)}"
                     + ("" if rival.waits_s is None else f", with waits up to about {rival.waits_s:.2g} s"))
    verdict = noise_verdict(result)
    noise = f"noise {result.noise_um:.2f} {dev}" if result.noise_measured else "noise not measured"
    lines.append(f"gap {result.gap_before_um:.2f} -> {result.gap_after_um:.2f} {dev} RMS, {noise}: "
                 f"what is left is {verdict}")
    for aliased in result.aliased:  # "noise" says nothing of an effect the plan kept from being looked for
        lines.append(f"[yellow]not looked for:[/] {aliased.effect} at periods under {aliased.shortest:.4g} "
                     f"{aliased.unit} (the targets are evenly spaced {aliased.spacing:.4g} {aliased.unit} apart); to "
                     "look: plan with offsets = \"golden\" or closer targets")
    return lines


SUMMARY_REGIONS = 3
"""The most regions, and local errors found outside the model, the summary lists (the largest
first; --verbose gives all)."""


def regions_said(located: Located | None) -> str:
    """The largest regions in a few words each, and how many more there are; one-target departures
    in a row over the travel (row_of_singles) said together, as one."""
    if located is None or not located.regions:
        return "nothing beyond the noise"
    row, rest = row_of_singles(located)
    items = [(abs(r.peak_um), short(r)) for r in rest]
    if row:
        peak = max(row, key=lambda r: abs(r.peak_um))
        text = (f"{len(row)} single targets depart over {min(r.start for r in row):.4g}–{max(r.end for r in row):.4g} "
                f"{peak.unit}, up to {peak.peak_um:+.1f} {peak.deviation_unit} (structure finer than the located "
                "curve follows)")
        items.append((abs(peak.peak_um), text))
    items.sort(key=lambda item: -item[0])
    said = "; ".join(text for _, text in items[:SUMMARY_REGIONS])
    more = len(items) - SUMMARY_REGIONS
    return said + (f"; {more} more (--verbose)" if more > 0 else "")


def located_lines(result: Discovery) -> list[str]:
    """Where the campaign departs from the starting model, model-free, before anything is named; and
    what the final model leaves unexplained, with its regions (only when there is some)."""
    lines = []
    if result.located_before is not None:  # after a named line: said as what it is, the departures before naming
        said = "located before naming" if result.steps and result.located_before.regions else "located"
        lines.append(f"{said}: {regions_said(result.located_before)}")
    if result.located_after is not None and result.located_after.regions:
        lines.append(f"[yellow]left unexplained:[/] {regions_said(result.located_after)}")
    return lines


def next_command(result: Discovery, files: list[str]) -> str | None:
    """The command to run next, when something is unresolved, located outside the model or more than
    noise is left: the follow-up that would tell (within the first campaign's machine time), or a
    look at where the residual is."""
    said = " ".join(files)
    plannable = [u for u in result.unresolved if not is_drift_shape_group(u.effects)]  # one longer campaign tells
    if plannable or result.not_excluded or (result.local_errors and not loop_ends(result, files)):
        return f"next: axiscal discover {said} --follow-up -o FOLLOW.toml"
    if noise_verdict(result) != "noise":
        return f"next: axiscal discover {said} --plot residual.png"
    return None


def print_text(result: Discovery, time_unit: str, incomplete: list[str], verbose: bool, kind: str = "linear",
               files: list[str] | None = None) -> None:
    console = make_console()
    dev = unit_label(UNITS[kind][1])
    slope = "µm/m" if kind == "linear" else "arcsec per 1000 deg"  # the slope's x is taken in units of 1000
    for line in summary_lines(result, incomplete, time_unit, kind):
        console.print(line)
    following = next_command(result, files) if files else None
    if not verbose:
        if following:  # the first screen ends with what to run next
            console.print(f"{following}; [dim]--verbose for every candidate and the notes[/]")
        else:
            console.print("[dim](--verbose: every candidate with ΔBIC, p and CV, how to tell in full, the notes)[/]")
        return
    console.print()
    before = result.disagreement_before
    console.print(f"start: gap {result.gap_before_um:.3f} {dev} RMS (measured - simulated), of which by position "
                  f"{before['by_position_rms_um']:.3f} {dev} RMS, by direction "
                  + ", ".join(f"{k} {v:+.3f}" for k, v in before["by_direction_um"].items()) + f" {dev}, by run "
                  + ", ".join(f"{r}: {v['mean_um']:+.3f} {dev}, {v['slope_ppm']:+.2f} {slope}"
                              for r, v in before["by_run"].items()))
    if not result.steps:
        console.print(nothing_named(result))
    for i, step in enumerate(result.steps, 1):
        params = params_text(step.effect, step.params, step.errors, (), time_unit, kind)
        gap = f"gap {step.gap_before_um:.3f} -> {step.gap_after_um:.3f} {dev}"
        console.print(f"step {i}: add [bold]{step.effect}[/] ({params}); {gap}")
        for line in ranking_lines(step.ranking, dev):
            console.print(line)
    if result.remaining:
        where = (f" (the unresolved ones against the model, the others beside the unresolved {result.remaining_beside} "
                 "as a stand-in)" if result.remaining_beside else "")
        console.print(("then" if result.steps else "candidates") + f"{where}: none is named")
        for line in ranking_lines(result.remaining, dev):
            console.print(line)
    if result.starting:
        console.print("starting model, as fitted at the end:")
        for line in starting_lines(result, time_unit):
            console.print(line)
    for entry in result.unresolved:
        console.print(f"[yellow]unresolved:[/] {entry.why}. To tell: {entry.how_to_tell}.")
    if result.stand_in is not None:
        console.print(f"[yellow]in the model as a stand-in:[/] {result.stand_in.observable}; the model holds it "
                      f"as {result.stand_in.effect} (gap {result.stand_in.gap_without_um:.3f} {dev} without it)")
    for held in result.held:
        console.print(f"[yellow]held in the fit, not named:[/] {held.observable}; the fit holds it with "
                      f"{held.effect}'s form (gap {held.gap_without_um:.3f} {dev} without it); it stays unresolved "
                      "and is not saved with the model")
    for local in result.local_errors:
        console.print(f"[yellow]found outside the model:[/] {local_said(local)}; no effect of the model has this "
                      f"shape; {local.time_text()}. It explains {local.explained_pct:.1f} % of the residual (ΔBIC "
                      f"{local.delta_bic:.1f} with its search's look-elsewhere, p {local.p_value:.2g}, "
                      f"{cv_text(local.cv_before_um, local.cv_after_um, dev)}); the model holds it as a "
                      f"{target_term_said(local) if local.kind == 'target' else 'smooth local term'} (gap "
                      f"{local.gap_without_um:.3f} {dev} without it), not as an effect, and does not save it")
    for when, located in (("before anything is named", result.located_before),
                          ("left by the final model", result.located_after)):
        if located is None:
            continue
        # a scan's profile fitted with tables has a curve of its own (locate.kinds_of_rows): each said with its span
        several = sum(c.over == "position" for c in located.curves) > len({c.direction for c in located.curves
                                                                             if c.over == "position"})
        curves = ", ".join(f"{c.over} {c.direction if c.over == 'position' else c.what}"
                           + (f" over {c.at[0]:.4g}–{c.at[-1]:.4g} {UNITS[kind][0]}" if several and c.over == "position" else "")
                           + f": {c.dof:.1f} parameters, CV {c.cv_rms_um:.3f} {dev}" for c in located.curves)
        console.print(f"located {when} (a smoother of the residual chosen by cross-validation, its band from a "
                      f"noise of {located.noise_um:.3f} {dev}; {curves}): "
                      + ("; ".join(r.sentence() for r in located.regions) or "nothing beyond the noise"))
    if len(result.final.offsets_um) > 1:
        console.print("campaigns fitted together, each with its own datum offset: "
                      + ", ".join(f"{o:+.3f} {dev}" for o in result.final.offsets_um))
    verdict = noise_verdict(result)
    line = (f"final gap {result.gap_after_um:.3f} {dev} RMS against a noise estimate of {result.noise_um:.3f} {dev} "
            f"(run-to-run scatter): what is left is {verdict}")
    console.print(line)
    for note in result.notes:
        console.print(f"note: {note}")
    if following:
        console.print(following)


def saved_model(result: Discovery, model: ErrorModel, source: str, time_source: str) -> str:
    """The final model as TOML. The datum offset and `environment` (it follows this campaign's log)
    are left out, and said so. Without a time column the time constant of an effect in time (its
    form cross-validated by run, such as thermal_drift's) is in points, not seconds: it is not saved as `tau_s` but as a comment, so that the simulator refuses the file
    until a time constant in seconds is given, and `discover --model` refits it."""
    noise = model.effects.get("noise") if "sigma_um" in model.effects.get("noise", {}) else None
    lines = [f"# Error model found by `axiscal discover {source}`; the datum offset is left out."]
    params = result.params()
    if "environment" in params:
        found = ", ".join(f"{k} = {v:.4g}" for k, v in params["environment"].items())
        lines.append(f"# Left out: environment ({found}), which follows this campaign's air/material log.")
    for local in result.local_errors:
        lines.append(f"# Left out: {local.sentence()}, which no effect of the model has the shape of.")
    if result.stand_in is not None:
        rivals = " or ".join(result.stand_in.rivals)
        lines.append(f"# Not named: [effects.{result.stand_in.effect}] stands in for {rivals}, which this campaign "
                     "cannot tell apart (at another wait before capture they predict other deviations).")
    text = result.final_model(noise).to_toml()
    in_points = [name for name in params if time_source != "time_s" and "tau_s" in params[name]
                 and (form := registered(name).form) is not None and form.group == "run"]
    for name in in_points:  # an effect in time: its time constant was fitted on the point order
        tau = params[name]["tau_s"]
        lines.append(f"# No time column: {name}'s time constant was fitted on the point order, {tau:.4g} "
                     "points, not seconds;")
        lines.append("# tau_s is left out: give it in seconds (or fit it with `axiscal discover --model`).")
        text = "\n".join(f"# tau_s = {tau!r}  # {name} {SAVED_TAU_POINTS}, NOT seconds"
                         if line.startswith("tau_s = ") and section == f"[effects.{name}]" else line
                         for section, line in _with_sections(text.splitlines()))
    return "\n".join(lines) + "\n" + text.rstrip("\n") + "\n"


def _with_sections(lines: list[str]) -> Iterator[tuple[str, str]]:
    """(the current [table] header, line) for each line of a TOML text."""
    section = ""
    for line in lines:
        if line.startswith("["):
            section = line.strip()
        yield section, line


def plot_steps(result: Discovery, x: np.ndarray, d: np.ndarray, y: np.ndarray, out: Path) -> None:
    """One panel per step: the residual (µm) vs position (mm) before (grey) and after the step, by
    direction. Without a step, one panel with the starting model's residual."""
    import matplotlib.pyplot as plt  # campaign.plot has set the Agg backend

    start = y - result.start.prediction
    panels: list[tuple[str, np.ndarray | None, np.ndarray]] = [
        (f"add {s.effect}", s.residual_before, s.residual_after) for s in result.steps]
    panels = panels or [("nothing added: residual of the starting model", None, start)]
    fig, axes = plt.subplots(len(panels), 1, figsize=(9, 3.2 * len(panels)), squeeze=False)
    for ax, (title, before, after) in zip(axes[:, 0], panels):
        if before is not None:
            ax.plot(x, before, ".", color="grey", ms=4, alpha=0.6, label="before")
            title += f": gap {np.sqrt(np.mean(before**2)):.3f} -> {np.sqrt(np.mean(after**2)):.3f} µm"
        for direction, colour in ((1, "tab:blue"), (-1, "tab:red")):
            pick = d == direction
            ax.plot(x[pick], after[pick], ".", color=colour, ms=4, label=f"after, {'+' if direction > 0 else '-'}")
        ax.set_title(title, fontsize=10)
        ax.axhline(0, color="grey", lw=0.6)
        ax.set_xlabel("target (mm)")
        ax.set_ylabel("measured - simulated (µm)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)


def config_beside(table: str) -> Config | None:
    """The config of the campaign a table was recorded by (config.toml next to it), typed; None when
    there is none or it does not read (the table is then read without its sample period)."""
    return config_beside_said(table)[0]


def config_beside_said(table: str) -> tuple[Config | None, str | None]:
    """`config_beside`, and a note when a config.toml is there but does not read: what is wrong with
    it and what the table is read without."""
    path = Path(table).parent / "config.toml"
    if not path.is_file():
        return None, None
    try:
        return load_config(path), None
    except InputError as e:
        return None, (f"{table}: the config.toml beside it does not read ({e}); the table is read without its "
                      "sample period and capture method")  # e names the file


def read_tables(files: list[str]) -> tuple[CampaignData, list[Outliers], list[str], list[str]]:
    """The campaigns, each with its outliers left out, joined for one fit; the outliers of each;
    the notes on an incomplete campaign (named by its file when there are several); the notes on
    how a file was read: a scan's profile.csv is read as its bins' point table
    (campaign.discovery.data.read_profile)."""
    parts, found, incomplete, read = [], [], [], []
    for name in files:
        profile = is_profile(name)
        if profile:
            table, said = read_profile(name)
            read.append(said)
        elif Path(name).name == "points.csv" and (Path(name).parent / META_FILE).is_file():
            table = read_recorded_points(Path(name).parent, partial=False)  # a torn last line left out, as analyze does
        else:
            table = read_points(name)
        config, unread = config_beside_said(name)
        read += [unread] if unread else []
        data = read_campaign(name, table, config)
        outliers = find_outliers(table)
        if outliers.found:
            data = keep_rows(data, ~outliers.mask(table))
        parts.append(data)
        found.append(outliers)
        notes = [] if profile else incomplete_notes(name, table)  # a profile has no plan to be short of
        incomplete += [f"incomplete campaign: {name}: {n.split(': ', 1)[1]}" if len(files) > 1 else n for n in notes]
    return join_campaigns(parts, files), found, incomplete, read


def target_term_said(local: LocalError) -> str:
    """How the model holds one target's departure, or two neighbouring targets' together."""
    return "term at those two targets" if "last_mm" in local.params else "term at that target"


def follow_up_config(args: argparse.Namespace) -> Config:
    """The config the follow-up starts from: --config, else config.toml next to the first table."""
    path = Path(args.config) if args.config else Path(args.files[0]).parent / "config.toml"
    if not path.is_file():
        raise InputError(f"--follow-up: {path}: no such file; give the first campaign's config with --config CONFIG")
    config = load_config(path)
    kept = kept_sim_model(path.parent)
    if not args.config and config.sim.model and not is_model_name(config.sim.model) and kept is not None:
        # the model the campaign ran, kept beside its config.toml: the model file the config names lies
        # beside the config it was run from, not here (the follow-up named a file that is not there)
        config = replace(config, sim=replace(config.sim, model=str(kept.resolve())))
    return config


def reversal_um(result: Discovery) -> float | None:
    """The size of the reversal the unresolved backlash stands for, µm (the stand-in's, or the
    backlash candidate's), or of a named effect beside a rival it does not exclude, if any."""
    if result.stand_in is not None:
        return float(result.stand_in.params["b_um"])
    if result.not_excluded:
        return result.not_excluded[0].named_size
    for cand in result.remaining:
        if cand.name == "backlash" and cand.fit is not None:
            return float(cand.fit.params()["backlash"]["b_um"])
    return None


def discover_shown(data: CampaignData, model: ErrorModel, given: dict[str, set[str]]) -> Discovery:
    """discover, its stage and the time so far shown on the terminal (stderr, when it is one) while it
    works: a dense table takes tens of seconds. Nothing is shown in a pipe or a file, and the line goes
    when done."""
    if not sys.stderr.isatty():
        return discover(data, model, given)
    from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

    with Progress(SpinnerColumn(), TextColumn("discovering:"), TimeElapsedColumn(), TextColumn("{task.description}"),
                  console=make_console(stderr=True), transient=True) as shown:
        task = shown.add_task("", total=None)
        return discover(data, model, given, stage=lambda text: shown.update(task, description=text))


def run(args: argparse.Namespace) -> int:
    plot_path = check_plot_path(args.plot) if args.plot else None
    if args.save and Path(args.save).suffix.lower() != ".toml":
        raise InputError(f"--save: {args.save}: the model file must end in .toml")
    if args.follow_up and not args.output:
        raise InputError("--follow-up: give the file to write with -o FOLLOW.toml")
    if args.output and not args.follow_up:
        raise InputError(f"-o {args.output}: only with --follow-up")
    if args.budget_min is not None and (not args.follow_up or not args.budget_min > 0):
        raise InputError(f"--budget-min {args.budget_min:g}: only with --follow-up, and more than 0 minutes")
    if args.output and Path(args.output).suffix.lower() != ".toml":
        raise InputError(f"-o: {args.output}: the campaign config must end in .toml")
    config = follow_up_config(args) if args.follow_up else None
    data, outliers, incomplete, read = read_tables(args.files)
    model, given = read_start_model(args.model)
    if len(data) < 4:
        raise InputError(f"{args.files[0]}: {len(data)} points are too few to fit a model")
    kind = data.kind
    result = discover_shown(data, model, given)
    result.notes[:0] = incomplete + read + [n for o in outliers for n in outlier_notes(o, kind)]
    follow, failed = None, None
    if config is not None:
        try:  # the findings are printed even when the follow-up cannot be planned or written
            follow = plan_follow_up(to_tell(result), result.remaining, data, result.final, config,
                                    reversal_um(result), result.noise_um, Path(args.output), args.files,
                                    [] if loop_ends(result, args.files) else regions_to_measure(result),
                                    None if args.budget_min is None else 60 * args.budget_min)
            if follow is not None and follow.parts:
                for campaign in follow.campaigns:
                    write_follow_up(campaign.path, campaign.text)
        except Exception as exc:  # noqa: BLE001 - raised again once the findings are out
            failed = exc
    if plot_path:
        plot_steps(result, data.x, data.d, data.y, plot_path)
    if args.save:
        Path(args.save).write_text(saved_model(result, model, " ".join(args.files), data.time_source), encoding="utf-8")
    if args.json:
        extra = {"campaigns": args.files, "offsets_um": [round(o, 4) for o in result.final.offsets_um]}
        if args.follow_up:
            extra["follow_up"] = None if follow is None else {**follow.as_dict(),
                                                               "file": args.output if follow.parts else None}
            if failed is not None:
                extra["follow_up_error"] = str(failed)
        print_json({**as_json(result), **all_outliers_json(outliers, args.files), **extra})
    else:
        print_text(result, data.time_unit, incomplete, args.verbose, data.kind,
                   None if args.follow_up else [str(f) for f in args.files])
        console = make_console()
        if args.follow_up and failed is None:
            for line in follow_up_lines(follow, args.output, [u.effects for u in result.unresolved]):
                console.print(line)
        for path, what in ((plot_path, "plot"), (args.save, "model")):
            if path:
                console.print(f"{what} written to {path}")
    if failed is not None:
        raise failed
    return 0


def write_follow_up(path: Path, text: str) -> None:
    """Write the follow-up config; InputError (exit 2) naming the file when it cannot be written."""
    try:
        path.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise InputError(f"-o {path}: cannot write the follow-up config ({exc.strerror or exc})") from None


def loop_ends(result: Discovery, files: list[str]) -> bool:
    """Tables fitted together (a follow-up measured) leave nothing unresolved and what is left is
    noise: the loop ends there, whatever local error the model holds (it is determined)."""
    return len(files) > 1 and not result.unresolved and not result.not_excluded and noise_verdict(result) == "noise"


def to_tell(result: Discovery) -> list[Unresolved]:
    """What a follow-up should tell apart: the unresolved groups, and each named effect beside a rival
    the data do not exclude (with the longest wait that would show it, when it has a time constant)."""
    return [*result.unresolved, *(n.to_tell() for n in result.not_excluded)]


def follow_up_lines(follow: FollowUp | None, path: str, unresolved: list[tuple[str, ...]] | None = None) -> list[str]:
    """What the follow-up campaign is for, part by part, and its machine time against the first's
    (`unresolved`: the effects of each unresolved group, for when none could be planned)."""
    if follow is None and unresolved:
        said = "; ".join(" or ".join(group) for group in unresolved)
        return [(f"follow-up: no campaign planned for what stays unresolved ({said}): the tables already measure "
                 "where it would, or no part fits it (how to tell, above); no file written")]
    if follow is None:
        return [("follow-up: nothing is unresolved that another campaign could separate, and no region is left to "
                 "measure densely; no file written")]
    if not follow.parts:
        return ["follow-up: no campaign planned (why, below); no file written",
                *(f"  [yellow]not planned:[/] {u}" for u in follow.unplanned)]
    lines = []
    for campaign in follow.campaigns:
        scan = campaign.config.capture.method == "scan"  # its points are sweeps; its profile is fitted
        lines.append(f"follow-up written to {campaign.path}: {len(build_plan(campaign.config).points)} "
                     f"{'sweeps' if scan else 'points'}, {campaign.duration_s / 60:.1f} min of machine time")
        lines += [f"  for {' or '.join(p.effects)}: {p.why}" for p in campaign.parts]
    several = len(follow.campaigns) > 1
    lines.append(f"{'together ' if several else ''}{follow.duration_s / 60:.1f} min (the first campaign: "
                 f"{follow.first_duration_s / 60:.1f} min); measure {'each' if several else 'it'}, then discover the "
                 f"first table and {'theirs' if several else 'its'} together (a scan's: its profile.csv; the "
                 "command is in the file's header)")
    if follow.longer:
        lines.append(f"  [yellow]warning:[/] {follow.longer}")
    lines += [f"  [yellow]not planned:[/] {u}" for u in follow.unplanned]
    return lines
