"""Measuring a campaign: the executor and its capture, the session (start, resume, dry run), replay,
verification, the progress display. Code outside this room imports these names from
`campaign.measure`, never its modules (an import-linter contract in pyproject.toml)."""

from campaign.measure.capture import BeamLost, Captured, NotStable, capture_point
from campaign.measure.deviation import point_deviation
from campaign.measure.env_guard import EnvironmentGuard
from campaign.measure.executor import (
    FAULT_ANSWERS,
    CampaignStopped,
    Control,
    Executor,
    FaultAnswer,
    Observer,
    move_and_wait,
)
from campaign.measure.live import live_text
from campaign.measure.progress import RichProgress
from campaign.measure.replay import ReplayedPoint
from campaign.measure.replay import replay as replay_campaign  # not `replay`: that names the module
from campaign.measure.scan import RecordedScan, ScanSettings, analyse_recorded_scan, settings_of
from campaign.measure.session import (
    MachineParts,
    Opened,
    Opener,
    Outcome,
    Resumption,
    continue_campaign,
    default_out_dir,
    dry_run,
    execute,
    open_with_comp,
    prepare_resume,
    resume_campaign,
    start_campaign,
)
from campaign.measure.verify import (
    SUMMARY_KEYS,
    baseline_points,
    corrected_within_limits,
    correction_limits,
    run_verification,
    table_fits,
    write_report,
)

__all__ = [
    "FAULT_ANSWERS",
    "SUMMARY_KEYS",
    "BeamLost",
    "CampaignStopped",
    "Captured",
    "Control",
    "EnvironmentGuard",
    "Executor",
    "FaultAnswer",
    "MachineParts",
    "NotStable",
    "Observer",
    "Opened",
    "Opener",
    "Outcome",
    "RecordedScan",
    "ReplayedPoint",
    "Resumption",
    "RichProgress",
    "ScanSettings",
    "analyse_recorded_scan",
    "baseline_points",
    "capture_point",
    "continue_campaign",
    "corrected_within_limits",
    "correction_limits",
    "default_out_dir",
    "dry_run",
    "execute",
    "live_text",
    "move_and_wait",
    "open_with_comp",
    "point_deviation",
    "prepare_resume",
    "replay_campaign",
    "resume_campaign",
    "run_verification",
    "settings_of",
    "start_campaign",
    "table_fits",
    "write_report",
]
