"""The technician's guided session: the setup checklist, the live dashboard, the operator's keys.
Code outside this room imports these names from `campaign.guide`, never its modules (an
import-linter contract in pyproject.toml)."""

from campaign.guide.checklist import (
    CheckItem,
    alignment_item,
    checklist_table,
    datum_item,
    environment_items,
    failures,
    hardware_items,
    plan_preview,
    reapproach_item,
    record_item,
    soft_limit_item,
)
from campaign.guide.dashboard import Dashboard
from campaign.guide.keys import CtrlC, Keys

__all__ = ["CheckItem", "CtrlC", "Dashboard", "Keys", "alignment_item", "checklist_table", "datum_item",
           "environment_items", "failures", "hardware_items", "plan_preview", "reapproach_item", "record_item",
           "soft_limit_item"]
