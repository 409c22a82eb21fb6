"""The campaign directory: writing it (recorder), reading it back (directory), the event stream
(events). Code outside this room imports these names from `campaign.record`, never its modules
(an import-linter contract in pyproject.toml)."""

from campaign.record.directory import (
    COMP_FILE,
    CONFIG_FILE,
    META_FILE,
    PLAN_FILE,
    POINTS_FILE,
    RUNS_FILE,
    CampaignDir,
    last_raw_state,
    last_reading_offset,
    load_raw,
    open_campaign,
    read_events,
    read_json_lines,
    recorded_point_indices,
)
from campaign.record.events import Event
from campaign.record.recorder import Recorder, RecordingError

__all__ = ["COMP_FILE", "CONFIG_FILE", "META_FILE", "PLAN_FILE", "POINTS_FILE", "RUNS_FILE", "CampaignDir", "Event",
           "Recorder", "RecordingError", "last_raw_state", "last_reading_offset", "load_raw", "open_campaign", "read_events",
           "read_json_lines", "recorded_point_indices"]
