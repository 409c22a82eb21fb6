"""The campaign's typed, frozen specs: each parameter has one owner, with its unit in its doc.

A spec is what the rooms below the command line read (never the raw TOML): `AxisSpec` for the
limits every motion is checked against, `PlanSpec` for the test cycle, `CaptureSpec` for how a
point is captured (carried by each capture step of a plan), `FaultPolicy`, `ControllerSpec`,
`InstrumentSpec`, `EnvironmentSpec`, `SimSpec`, and `DriverSpec` for what the drivers open. Every
field of a section spec is a config key: its `Key` (type, default, meaning with unit, bounds,
whether it may change before a resume) is the field's metadata, and `campaign.config` builds its
schema, its validation and docs/config.md from these classes. Specs are made by
`campaign.config` only (validated); a changed copy is made with `campaign.config.config_with`,
which validates again. Nothing writes into a spec.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Literal, get_args

from campaign import capture_methods
from protocols import plc_contract
from protocols.serial_line import LineFormat

REQUIRED: Any = object()
"""The default of a key the config must give."""


@dataclass(frozen=True)
class Key:
    """One config key: its type, default (REQUIRED if none), meaning with unit, bounds, and whether
    it may change before a resume."""

    type: type
    default: Any
    doc: str
    min: float | None = None
    max: float | None = None
    choices: tuple[Any, ...] = ()
    resume: bool = False
    """True when the key may change between a campaign's start and its resume (a connection, a
    limit, a name); any other change would mix two measurements in one table."""
    choices_of: Callable[[], tuple[Any, ...]] | None = None
    """The choices read from a registry each time they are asked for (`options`), instead of `choices`."""

    def options(self) -> tuple[Any, ...]:
        """The values the key may take (empty: any of its type)."""
        return self.choices_of() if self.choices_of is not None else self.choices


def key(type_: type, default: Any, doc: str, *, min: float | None = None,
        max: float | None = None, choices: tuple[Any, ...] = (), resume: bool = False,
        choices_of: Callable[[], tuple[Any, ...]] | None = None) -> Any:
    """A spec field that is a config key (see `Key`)."""
    meta = {"key": Key(type_, default, doc, min, max, choices, resume, choices_of)}
    if default is REQUIRED:
        return field(metadata=meta)
    return field(default=default, metadata=meta)


EMPTY: Mapping[str, Any] = MappingProxyType({})


def frozen(value: Any) -> Any:
    """`value` with every table made read-only and every list a tuple, at any depth (`plain` makes
    them dicts and lists again, to merge, to validate, to write as JSON)."""
    if isinstance(value, Mapping):
        return MappingProxyType({k: frozen(v) for k, v in value.items()})
    if isinstance(value, list | tuple):
        return tuple(frozen(v) for v in value)
    return value


def plain(value: Any) -> Any:
    """A frozen table as plain dicts and lists again (to merge, to validate, to write as JSON)."""
    if isinstance(value, Mapping):
        return {k: plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [plain(v) for v in value]
    return value


Purpose = Literal["acceptance", "verification", "follow-up", "diagnostic"]
PURPOSES: tuple[Purpose, ...] = get_args(Purpose)
"""What a campaign is for ([campaign] purpose): only acceptance and verification campaigns are judged
pass/fail and enter an axis's trend; a follow-up and a diagnostic are recorded and listed only."""
JUDGED_PURPOSES: tuple[Purpose, ...] = ("acceptance", "verification")

# The choices of the config's keys, each a Literal: the spec's field has the type, and the key's
# `choices` (validation, docs/config.md) are its arguments.
OnFault = Literal["retry", "skip", "abort"]
AxisKind = Literal["linear", "rotary"]
AxisUnit = Literal["mm", "deg"]
Cycle = Literal["linear", "pilgrim"]
Offsets = Literal["none", "random", "golden"]
ControllerType = Literal["sim", "ads", "linuxcnc", "epics"]
STREAMING_CONTROLLERS: frozenset[ControllerType] = frozenset({"sim", "ads"})
"""The controllers whose driver's axis streams its actual position with the controller's time
stamps (a `protocols.hardware.StreamingAxis`: drivers/ads_axis.py's ADS device notifications, on a
real PLC or the simulated one), which a scan needs; the LinuxCNC and EPICS axes do not. The
drivers hold the fact; tests/test_capture_methods.py checks this set against them."""
InstrumentType = Literal["sim", "serial"]
InstrumentMode = Literal["stream", "query"]
AirCorrection = Literal["none", "edlen"]
CaptureMethod = str
"""A name of `campaign.capture_methods.METHODS` (the registry decides the choices)."""


@dataclass(frozen=True, kw_only=True)
class CampaignSpec:
    """What the campaign is and the tolerances its verdict uses ([campaign])."""

    machine: str = key(str, "machine", "machine id, recorded in the metadata", resume=True)
    operator: str = key(str, "", "operator name, recorded in the metadata", resume=True)
    description: str = key(str, "", "free text, recorded in the metadata", resume=True)
    tolerance: float = key(float, 0.0,
        "pass/fail tolerance on the accuracy A, deviation unit (µm or arcsec); 0 = none", min=0, resume=True)
    tolerance_e: float = key(float, 0.0,
        "tolerance on the systematic deviation E, deviation unit; 0 = none", min=0, resume=True)
    tolerance_b: float = key(float, 0.0,
        "tolerance on the reversal value B, deviation unit; 0 = none", min=0, resume=True)
    tolerance_r: float = key(float, 0.0,
        "tolerance on the repeatability R, deviation unit; 0 = none", min=0, resume=True)
    purpose: Purpose = key(str, "acceptance",
        "what the campaign is for: acceptance (an ISO 230-2 test with a verdict), verification (a "
        "re-measurement after a compensation), follow-up (written by discover --follow-up) or diagnostic "
        "(any other measurement); a follow-up or a diagnostic gets no pass/fail and is never trended",
        choices=PURPOSES)
    follows: str = key(str, "",
        "the campaign this one follows up or verifies (its directory or campaign id); empty = none",
        resume=True)


@dataclass(frozen=True, kw_only=True)
class FaultPolicy:
    """What the executor does after a fault when no operator answers ([campaign])."""

    on_fault: OnFault = key(str, "retry",
        "without an operator: retry a point after a fault (up to fault_retries times), skip it (resume "
        "measures it later), or abort at once", choices=get_args(OnFault), resume=True)
    fault_retries: int = key(int, 3,
        "faults retried at one point before the campaign stops", min=0, max=20, resume=True)


@dataclass(frozen=True, kw_only=True)
class AxisSpec:
    """The axis and its limits ([axis]): every motion is checked against them."""

    name: str = key(str, "X", "axis name")
    kind: AxisKind = key(str, "linear", "linear or rotary", choices=get_args(AxisKind))
    unit: AxisUnit = key(str, "mm", "position unit: mm (linear) or deg (rotary)", choices=get_args(AxisUnit))
    soft_limit_min: float = key(float, REQUIRED,
        "lowest position any motion may command, axis unit", resume=True)
    soft_limit_max: float = key(float, REQUIRED,
        "highest position any motion may command, axis unit", resume=True)
    max_velocity: float = key(float, REQUIRED,
        "highest velocity any motion may command, axis unit/s", min=1e-06, resume=True)
    max_acceleration: float = key(float, 500.0,
        "axis acceleration (simulated machine), axis unit/s²", min=1e-06)
    in_position_window: float = key(float, 0.01,
        "|actual - target| allowed when a move is done, axis unit", min=0, resume=True)


@dataclass(frozen=True, kw_only=True)
class PlanSpec:
    """The test cycle ([plan]): targets, runs, dwell, velocity (the plan is built from it)."""

    targets: tuple[float, ...] | None = key(list, None,
        "explicit target list, axis unit (instead of start/length/count)")
    start: float = key(float, 0.0, "first target, axis unit")
    length: float | None = key(float, None,
        "distance from the first to the last target, axis unit", min=1e-09)
    count: int | None = key(int, None, "number of targets (>= 2)", min=2, max=10000)
    overrun: float = key(float, 2.0, "overrun L1 beyond both ends, axis unit", min=0)
    cycles: int = key(int, 5, "number of runs (cycles); ISO 230-2 asks for 5", min=1, max=1000)
    dwell_s: float = key(float, 4.0, "dwell at each target, s", min=0.1, max=600)
    dwell_jitter: float = key(float, 0.0,
        "vary each point's dwell by up to this fraction (seeded): settling is only told from backlash when "
        "the dwell varies", min=0, max=0.9)
    velocity: float = key(float, REQUIRED, "positioning velocity, axis unit/s", min=1e-09)
    cycle: Cycle = key(str, "linear",
        "linear (ISO 230-2) or pilgrim (step cycle, annex)", choices=get_args(Cycle))
    offsets: Offsets = key(str, "none",
        "per-target offsets to sample periodic errors: none, random, golden",
        choices=get_args(Offsets))
    offset_fraction: float = key(float, 0.1,
        "largest offset as a fraction of the target spacing", min=0, max=0.45)
    seed: int = key(int, 1, "seed of the random offsets (recorded)", min=0)


@dataclass(frozen=True, kw_only=True)
class ControllerSpec:
    """The connection to the axis controller ([axis_driver])."""

    type: ControllerType = key(str, "sim",
        "sim (simulated machine over loopback ADS), ads (a real PLC), linuxcnc (a headless LinuxCNC with "
        "a simulated laser, docs/linuxcnc.md) or epics (an EPICS motor record over Channel Access; with "
        "instrument.type sim, the simulated IOC on loopback, docs/epics.md)",
        choices=get_args(ControllerType), resume=True)
    pv: str = key(str, "", "epics: the motor record's name (prefix of its fields .VAL, .RBV, ...), ASCII "
                  "letters, digits and _-:;<>[], at most 60 characters; required for a real IOC; empty with "
                  "instrument.type sim: SIM:M1 on the simulated IOC", resume=True)
    comp_file: str = key(str, "",
        "linuxcnc: the COMP_FILE (type 0) LinuxCNC loads at start; empty: none", resume=True)
    ams_net_id: str = key(str, "127.0.0.1.1.1", "the PLC's AMS net id", resume=True)
    ams_port: int = key(int, 851, "the PLC runtime's ADS port", min=1, max=65535, resume=True)
    ip: str = key(str, "127.0.0.1", "the PLC's IP address", resume=True)
    axis_index: int = key(int, 1, "index n of GVL_Axiscal.astAxes[n]", min=1, max=plc_contract.MAX_AXES,
                          resume=True)
    timeout_s: float = key(float, 2.0, "ADS call timeout, s", min=0.01, max=60, resume=True)
    move_timeout_s: float = key(float, 300.0, "longest a single move may take, s", min=0.1, resume=True)
    reconnect_s: float = key(float, 30.0,
        "how long to wait for a lost ADS connection to come back, s", min=0, resume=True)
    read_only: bool = key(bool, False, "dry run: talk to the PLC read-only, command nothing", resume=True)

    @property
    def streams_position(self) -> bool:
        """This controller streams its actual position with its own time stamps (a scan needs it)."""
        return self.type in STREAMING_CONTROLLERS


@dataclass(frozen=True, kw_only=True)
class InstrumentSpec:
    """The laser interferometer: its connection, its rate and its traceability ([instrument])."""

    type: InstrumentType = key(str, "sim",
        "sim (simulated interferometer over a pty) or serial", choices=get_args(InstrumentType))
    port: str = key(str, "", "serial port, e.g. /dev/ttyUSB0", resume=True)
    baudrate: int = key(int, 115200, "serial baud rate", min=50, max=4000000, resume=True)
    mode: InstrumentMode = key(str, "stream",
        "stream (instrument sends continuously) or query", choices=get_args(InstrumentMode))
    rate_hz: float = key(float, 10.0,
        "how often axiscal takes the readings (its tick), Hz; set the instrument to stream at least this "
        "fast; the simulated instrument streams at this rate", min=0.1, max=1000)
    timeout_s: float = key(float, 1.0, "serial read timeout, s", min=0.01, max=60, resume=True)
    model: str = key(str, "",
        "the laser's model, for the report's traceability (e.g. Renishaw XL-80)", resume=True)
    serial: str = key(str, "", "the laser's serial number", resume=True)
    certificate: str = key(str, "",
        "the laser's calibration certificate: number, laboratory, date", resume=True)
    wavelength_uncertainty_ppm: float | None = key(float, None,
        "expanded uncertainty (k = 2) of the laser's length measurement from its calibration certificate, "
        "µm/m; absent: 0.5 µm/m, a typical specification, named as such in the budget",
        min=0, max=100, resume=True)
    angle_uncertainty_arcsec: float | None = key(float, None,
        "rotary axis: expanded uncertainty (k = 2) of the angular measurement from the certificate, arcsec;"
        " absent: 1 arcsec (typical specification)", min=0, max=100, resume=True)
    resolution: float = key(float, 0.001,
        "the reading's resolution, deviation unit (µm or arcsec)", min=0, resume=True)
    misalignment_mm: float = key(float, 0.5,
        "largest lateral walk of the beam over the travel seen when aligning, mm (the cosine error)",
        min=0, resume=True)
    dead_path_mm: float = key(float, 0.0,
        "distance from the interferometer optic to the laser's datum, mm (dead path)", min=0, resume=True)
    line: LineFormat = field(default_factory=LineFormat, metadata={"table": "the serial line format"})
    """[instrument.line]: how a reading is written on the serial line (docs/serial-line.md)."""


@dataclass(frozen=True, kw_only=True)
class EnvironmentSpec:
    """Air and material corrections and the sensors' uncertainties ([environment])."""

    air_correction: AirCorrection = key(str, "none",
        "none (instrument corrects for air) or edlen (axiscal corrects vacuum readings with the updated "
        "Edlén equation)", choices=get_args(AirCorrection))
    wavelength_nm: float = key(float, 633.0, "laser vacuum wavelength, nm", min=100, max=2000)
    co2_ppm: float = key(float, 450.0, "CO2 content of the air, ppm", min=0, max=10000)
    air_temp_c: float | None = key(float, None,
        "air temperature when the instrument gives none, °C", min=-20, max=60)
    air_pressure_hpa: float | None = key(float, None,
        "air pressure when the instrument gives none, hPa", min=500, max=1200)
    humidity_pct: float | None = key(float, None,
        "relative humidity when the instrument gives none, %", min=0, max=100)
    normalise_to_20c: bool = key(bool, False, "normalise readings to 20 °C with the material temperature")
    expansion_ppm_per_k: float = key(float, 11.5,
        "material expansion coefficient, µm/m per K", min=0, max=100)
    air_temp_uncertainty_c: float = key(float, 0.2,
        "expanded uncertainty (k = 2) of the air temperature sensor, °C", min=0, resume=True)
    air_pressure_uncertainty_hpa: float = key(float, 1.0,
        "expanded uncertainty (k = 2) of the air pressure sensor, hPa", min=0, resume=True)
    humidity_uncertainty_pct: float = key(float, 6.0,
        "expanded uncertainty (k = 2) of the humidity sensor, % RH", min=0, resume=True)
    material_temp_uncertainty_c: float = key(float, 0.1,
        "expanded uncertainty (k = 2) of the material temperature sensor, °C", min=0, resume=True)
    expansion_uncertainty_ppm_per_k: float = key(float, 1.0,
        "half-width of the range the expansion coefficient may lie in, µm/m per K", min=0, resume=True)


@dataclass(frozen=True, kw_only=True)
class CaptureSpec:
    """How a point is captured at its target ([capture]); each capture step of a plan carries it."""

    method: CaptureMethod = key(str, "dwell",
        "how points are captured (the registry campaign/capture_methods.py): dwell (average the end of a fixed "
        "dwell), stable (capture when the reading is stable), scan (on the move at scan_velocity, a diagnostic: "
        "docs/scan.md); stream is the stream import's own", choices_of=capture_methods.names)
    average_s: float = key(float, 1.0, "dwell method: averaging window at the end of the dwell, s", min=0.01)
    stable_tolerance: float = key(float, 0.5,
        "stable method: band the reading must stay in, deviation unit", min=0)
    stable_drift: float = key(float, 0.08,
        "stable method: largest difference between the means of the window's two halves, deviation unit "
        "(raised to the noise's own uncertainty when that is larger)", min=0)
    stable_window_s: float = key(float, 0.7,
        "stable method: how long the reading must stay in the band, s", min=0.01)
    stable_timeout_s: float = key(float, 10.0, "stable method: longest wait after arrival, s", min=0.1)
    retries: int = key(int, 2,
        "captures retried at a point after beam loss before the campaign stops", min=0, max=20)
    scan_velocity: float | None = key(float, None,
        "scan method: the constant velocity of every sweep, axis unit/s (mm/s or deg/s; at most "
        "axis.max_velocity); required with method = scan", min=1e-06)
    scan_window: float = key(float, 1.0,
        "scan method: the stretch about each target a line is fitted through, axis unit; at least the "
        "samples' spacing (scan_velocity / instrument.rate_hz), at most the targets' spacing", min=1e-06)
    scan_wanted_u: float = key(float, 0.2,
        "scan method: the deviation uncertainty per target and pass the timing may cost, deviation unit "
        "(µm or arcsec); a faster scan is warned about", min=1e-06)


@dataclass(frozen=True, kw_only=True)
class SimSpec:
    """The simulated machine ([sim]): pace, noise seed, error model and injected faults."""

    speed: float | None = key(float, None,
        "run N times faster than real time; absent = as fast as possible", min=0.001, resume=True)
    instrument_offset_s: float = key(float, 0.0,
        "the simulated instrument's own clock: its reading when the controller's reads 0, s (a scan "
        "must find it, docs/scan.md)", min=-1e6, max=1e6)
    instrument_rate_ppm: float = key(float, 0.0,
        "the simulated instrument's clock runs this much fast (negative: slow), ppm", min=-1000, max=1000)
    instrument_jitter_s: float = key(float, 0.0,
        "RMS of the instant a simulated sample is really taken about its stamp, s", min=0, max=0.01)
    instrument_latency_s: float = key(float, 0.0,
        "the simulated instrument's transport latency: a sample reaches the PC this much later, s",
        min=0, max=1)
    seed: int = key(int, 1, "seed of the simulated noise", min=0)
    model: str = key(str, "", "error model: a shipped one by name (seed000-horizontal, seed000-vertical: data/models), a TOML file (relative to this config), or [sim.effects.NAME]")
    effects: Mapping[str, Any] | None = field(default=None, metadata={"table": "the error model"})
    """[sim.effects]: the inline error model, one table per effect (docs/error-model.md); None: none."""
    faults: Mapping[str, Any] = field(default_factory=lambda: EMPTY, metadata={"table": "faults to inject"})
    """[sim.faults]: faults injected into the simulated machine (docs/faults.md), as given."""
    base_dir: str = field(default=".", metadata={"table": ""})
    """The directory `model` is relative to (the config file's)."""
    source: str = field(default="<config>", metadata={"table": ""})
    """Where the [sim] table was read, for messages."""


@dataclass(frozen=True)
class DriverSpec:
    """What the drivers open for a campaign (drivers.factory): the axis and its limits, the
    controller connection, the instrument, the simulated machine, whether the instrument must
    report vacuum lengths (axiscal corrects for air itself), and where a simulated axis starts
    (axis unit). `source`: the config file, named in messages."""

    axis: AxisSpec
    controller: ControllerSpec
    instrument: InstrumentSpec
    sim: SimSpec
    vacuum_readings: bool
    start_position: float
    source: str
