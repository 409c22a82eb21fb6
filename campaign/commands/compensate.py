"""`axiscal compensate POINTS.csv --format FMT -o FILE ...`: write a controller's compensation
table from a point table, and print the mode chosen, the inverse-vs-simple difference and the
predicted accuracy next to the floor the repeatability allows."""

from __future__ import annotations

import argparse
import itertools
from datetime import UTC, datetime
from pathlib import Path

from rich.console import Console

from campaign.commands import (
    SUMMARY,
    finite_number,
    non_negative_integer,
    non_negative_number,
    positive_integer,
    positive_number,
)
from campaign.compensation.corrections import MODES, corrections
from campaign.compensation.grid import POINT_LIMITS, ControllerTable, resample
from campaign.compensation.predict import predict
from campaign.compensation.smooth import SMOOTHING
from campaign.errors import InputError
from campaign.pointtable import read_points
from campaign.views import fmt, make_console
from protocols.tables import FORMATS, FormatOptions, render
from protocols.units import DEVIATION_SCALE, UNITS, unit_label

DEFAULT_METHOD = {"pmac": "simple"}
"""Formats whose default is the simple -error table: PMAC practice and Han et al. 2012's published table
(the inverse method moves its 80° entry across a rounding boundary, 40 -> 41)."""


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("compensate", help=SUMMARY["compensate"],
                       description="Turn a point table into a controller's compensation table "
                                   "(docs/compensation-formats.md).")
    p.add_argument("file", help="point table CSV")
    p.add_argument("--format", required=True, choices=FORMATS, help="controller table format")
    p.add_argument("-o", "--output", required=True, help="the table file to write")
    p.add_argument("--mode", default="auto", choices=MODES, help="uni, bi or auto (default)")
    p.add_argument("--method", choices=("inverse", "simple"),
                   help="inverse interpolation (default) or simple -error (default for pmac: its table "
                        "is the published, simple one of Han et al. 2012)")
    p.add_argument("--smooth", default="auto", choices=SMOOTHING,
                   help="auto (default): fit the means with the lowest polynomial that agrees with their "
                        "scatter, where one does; none: the raw means")
    p.add_argument("--overrun", type=non_negative_number, default=0.0, help="end-zone length L1, mm or deg (default 0)")
    p.add_argument("--max-points", type=positive_integer, help="point limit (default: the controller's)")
    p.add_argument("--spacing", type=positive_number, help="table spacing, mm or deg (default: from the targets)")
    p.add_argument("--reference", type=finite_number, help="reference position where the table is 0, mm or deg")
    p.add_argument("--counts-per-unit", type=positive_number,
                   help="counts (pmac) or detection units (fanuc) per mm or deg")
    p.add_argument("--axis-name", default=None, help="controller axis name (default X; siemens AX1)")
    p.add_argument("--joint", type=non_negative_integer, default=0, help="LinuxCNC joint number")
    p.add_argument("--units", choices=("mm", "inch"), default="mm",
                   help="linuxcnc: the machine's units (an inch machine needs an inch table; default mm)")
    p.add_argument("--axis-number", type=positive_integer,
                   help="twincat_cnc: the axis' logical number, kopf.achs_nr (1..65534; required)")
    p.add_argument("--control", choices=("840d", "828d", "808d", "tnc640", "tnc426"), type=str.lower,
                   help="siemens: 840d (default), 828d or 808d (sets the point limit: 808D 200); "
                        "heidenhain: tnc640 (default) or tnc426 (power-of-two spacing)")
    p.add_argument("--partial", action="store_true",
                   help="write the table of an incomplete campaign (refused with exit 2 otherwise); "
                        "says which part of the travel it covers")
    p.add_argument("--write-plc", metavar="CONFIG",
                   help="TwinCAT: also write the tables into the PLC of CONFIG over ADS "
                        "(GVL_Axiscal.astComp[n]), read them back, compare, then enable them")
    p.add_argument("--max-rate", type=positive_number, metavar="UM_PER_S",
                   help="with --write-plc: correction rate limit, µm/s (arcsec/s on a rotary axis)")
    p.add_argument("--max-accel", type=positive_number, metavar="UM_PER_S2",
                   help="with --write-plc: correction acceleration limit, µm/s² (arcsec/s²)")
    p.set_defaults(func=run)


def control_point_limit(fmt: str, control: str | None) -> int:
    """The default point limit of a format, for the control where it depends on it (siemens)."""
    if fmt == "siemens":
        from protocols.tables.siemens import DEFAULT_CONTROL, MAX_POINTS

        return min(POINT_LIMITS[fmt], MAX_POINTS.get(control or DEFAULT_CONTROL, POINT_LIMITS[fmt]))
    return POINT_LIMITS[fmt]


def campaign_of(path: str) -> tuple[str, str]:
    """The campaign a point table comes from: its directory's name and when it was started
    (meta.json `created`, ISO 8601); for a bare table, the file's name and ""."""
    from campaign.assess import campaign_dir_of
    from campaign.record import open_campaign

    directory = campaign_dir_of(path)
    if directory is None:
        return Path(path).name, ""
    try:
        created = str(open_campaign(directory).meta.get("created", ""))
    except (InputError, OSError, ValueError):
        created = ""
    return directory.resolve().name, created


def missing_options(args: argparse.Namespace, mode: str, start: float) -> list[str]:
    """Every option the format still needs, each with why, so that they are all said at once (not
    one error per try): counts per unit (pmac, fanuc), one table (pmac, siemens: `mode` is what was
    chosen), the reference (fanuc; pmac's table starts at motor zero), the axis number (twincat_cnc)."""
    fmt, needed = args.format, []
    if fmt in ("pmac", "fanuc") and args.counts_per_unit is None:
        what = "encoder counts" if fmt == "pmac" else "detection units"
        needed.append(f"--counts-per-unit ({what} per mm or degree)")
    if fmt in ("pmac", "siemens") and mode != "uni":
        needed.append(f"--mode uni (it holds one table per axis; the {args.mode} mode gave {mode})")
    if fmt == "fanuc" and args.reference is None:
        needed.append("--reference (fanuc counts its points from the reference position)")
    if fmt == "pmac" and args.reference is None and abs(start) > 1e-9:
        needed.append(f"--reference 0 (a pmac table starts at motor zero; the grid starts at {start:g})")
    if fmt == "twincat_cnc" and args.axis_number is None:
        needed.append("--axis-number (the axis' logical number, kopf.achs_nr, P-AXIS-00016 in its axis parameters)")
    return needed


def nominal_grid(path: str) -> tuple[float, float, str] | None:
    """(spacing, origin, what to say) of the nominal grid of a campaign measured with target offsets
    (random or golden): its targets are off the grid a controller wants, so the table defaults to
    the plan's nominal spacing from its first nominal target. None for a bare table, a campaign
    without offsets, or nominal targets that are not equidistant."""
    from campaign.assess import campaign_dir_of
    from campaign.plan import nominal_targets
    from campaign.record import open_campaign

    directory = campaign_dir_of(path)
    if directory is None:
        return None
    try:
        plan = open_campaign(directory).config().plan
    except (InputError, OSError, ValueError):
        return None
    if plan.offsets == "none":
        return None
    nominal = nominal_targets(plan)
    steps = [b - a for a, b in itertools.pairwise(nominal)]
    if not steps or max(steps) - min(steps) > 1e-9 * max(1.0, abs(nominal[-1])):
        return None
    return steps[0], nominal[0], (f"the plan's nominal grid: its targets carry {plan.offsets} offsets; "
                                  "--spacing sets another")


def partial_coverage(path: str, ctable: ControllerTable, unit: str) -> str:
    """Which part of the planned travel a table of an incomplete campaign covers: "the table covers
    0 to 480 mm of the planned 0 to 600 mm" (the plan's targets from meta.json; for a bare table, the
    table's own span)."""
    from campaign.assess import campaign_dir_of
    from campaign.record import open_campaign

    end = ctable.start + ctable.spacing * (len(ctable.forward) - 1)
    covers = f"the table covers {ctable.start:g} to {end:g} {unit}"
    directory = campaign_dir_of(path)
    targets = open_campaign(directory).meta.get("targets") if directory is not None else None
    if isinstance(targets, list) and targets and all(isinstance(t, (int, float)) for t in targets):
        return f"{covers} of the planned {min(targets):g} to {max(targets):g} {unit}"
    return covers


def run(args: argparse.Namespace) -> int:
    from campaign import __version__
    from campaign.assess import incomplete

    try:
        table = read_points(args.file)
    except InputError as exc:  # a campaign stopped in its first run: say that first, and what to do
        if not (missing := incomplete(args.file)):
            raise
        from campaign.assess import campaign_dir_of

        directory = campaign_dir_of(args.file)
        then = f"resume it first: axiscal resume {directory}" if directory else "measure the rest first"
        raise InputError(f"incomplete campaign ({'; '.join(missing)}): {exc}; {then}") from None
    console = make_console()
    missing = incomplete(args.file)
    if missing and not args.partial:
        from campaign.assess import campaign_dir_of

        directory = campaign_dir_of(args.file)
        then = f"resume it first (axiscal resume {directory})" if directory else "measure the rest first"
        raise InputError(f"{args.file}: incomplete campaign ({'; '.join(missing)}): {then}, or give --partial "
                         "for a table of the travel measured so far")
    method = args.method or DEFAULT_METHOD.get(args.format, "inverse")
    corr = corrections(table, args.mode, method, args.smooth)
    max_points = args.max_points or control_point_limit(args.format, args.control)
    spacing, origin, nominal_note = args.spacing, None, None
    if spacing is None and (nominal := nominal_grid(args.file)) is not None:
        spacing, origin, nominal_note = nominal
    ctable = resample(corr, max_points, spacing, args.reference, args.overrun, origin)
    if needed := missing_options(args, corr.mode, ctable.start):
        raise InputError(f"--format {args.format} needs {'; '.join(needed)}")
    axis = args.axis_name or ("AX1" if args.format == "siemens" else "X")
    name, created = campaign_of(args.file)
    provenance = (("campaign", name), ("measured", created),
                  ("written", datetime.now(UTC).isoformat(timespec="seconds")),
                  ("points", str(Path(args.file).resolve())), ("machine", table.meta.get("machine", "")),
                  ("axis", table.meta.get("axis", "")), ("software", f"axiscal {__version__}"))
    options = FormatOptions(axis, args.joint, 1, args.counts_per_unit, provenance, args.units, args.axis_number,
                            args.control)
    rendered = render(args.format, ctable, options)
    out = Path(args.output)
    try:
        out.write_text(rendered.text, encoding="utf-8")
    except OSError as exc:
        raise InputError(f"-o: {out}: cannot write ({exc.strerror})") from None
    from campaign.commands.history import record_comp_after

    record_comp_after(rendered.text, out, args.format, args.file, dict(provenance), table.meta.get("machine", ""),
                      table.meta.get("axis", ""))
    pred = predict(table, ctable)
    unit = unit_label(table.deviation_unit)
    console.print(f"mode: [bold]{corr.mode}[/] ({corr.reason})")
    if corr.backlash is not None:
        console.print(f"backlash B̄ (mean reversal): {corr.backlash:.3f} {unit}")
    for d, sm in corr.smoothing.items():
        label = {1: "forward", -1: "reverse", 0: "mean of both directions"}[d]
        console.print(f"smoothing, {label}: {sm.reason}")
        if sm.degree is not None:
            console.print(f"  the means move by at most {sm.max_change:.3f} {unit}")
    console.print(f"table: {len(ctable.forward)} points from {ctable.start:g} every {ctable.spacing:g} "
                  f"{table.position_unit}, overrun {ctable.overrun:g}" + (f" ({nominal_note})" if nominal_note else ""))
    if missing:
        console.print(f"[yellow]warning:[/] --partial: {partial_coverage(args.file, ctable, table.position_unit)} "
                      f"({'; '.join(missing)}): no correction beyond it")
    console.print(f"inverse interpolation - simple (-error): max {corr.max_inverse_minus_simple:.3f} {unit} "
                  f"(method used: {corr.method})")
    console.print(f"predicted accuracy A: {fmt(pred.accuracy_before)} -> {fmt(pred.accuracy_after)} {unit}; "
                  f"floor 4·s_max = {fmt(pred.floor)} {unit}")
    for note in rendered.notes:
        console.print(f"  {note}")
    console.print(f"{args.format} table written to {out}")
    if args.write_plc:
        write_plc(args, ctable, console)
    return 0


def write_plc(args: argparse.Namespace, ctable: ControllerTable, console: Console) -> None:
    """TwinCAT (a): the tables into the PLC's compensation variables over ADS, read back, compared."""
    from campaign.commands import hardware_opener
    from campaign.config import load_config
    from campaign.measure import corrected_within_limits, correction_limits
    from campaign.plan import build_plan

    config = load_config(args.write_plc)
    if ctable.kind != config.axis.kind:
        raise InputError(f"--write-plc: a {ctable.kind} table does not fit the {config.axis.kind} axis")
    corrected_within_limits(ctable, build_plan(config), config, "--write-plc")
    rate, accel = correction_limits(config, args.max_rate, args.max_accel)
    hardware, _ = hardware_opener()(config.driver)
    try:
        hardware.axis.write_comp_table(ctable.to_plc(rate, accel, enabled=True))
        back = hardware.axis.read_comp_table()
    finally:
        hardware.close()
    if back is None:
        raise InputError("--write-plc: the PLC holds no compensation table after the write")
    scale, dev = DEVIATION_SCALE[config.axis.unit], unit_label(UNITS[ctable.kind][1])
    console.print(f"PLC tables written over ADS ({back.points} points), read back equal, enabled; "
                  f"correction limits {rate * scale:g} {dev}/s, {accel * scale:g} {dev}/s²")
