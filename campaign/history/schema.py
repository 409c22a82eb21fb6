"""The store's tables (SQLAlchemy Core). The migrations in `migrations/versions/` create and change
them; this module describes the newest revision for the code that reads and writes.

| table | one row per | holds |
|---|---|---|
| campaigns | campaign directory or point table recorded | machine, axis, date (UTC), operator, instrument and its calibration, the plan, the verdict and its reasons, the uncertainty budget, where it lives, its purpose ([campaign] purpose) and the campaign it follows |
| results | campaign × ISO 230-2 parameter × direction | the value and its expanded uncertainty U (k = 2), deviation unit; for the bidirectional A, E, B, R the standard uncertainty between re-checks (campaign/history/recheck.py) |
| points | campaign × point | the point table: run, direction, target, deviation, time |
| comp_tables | compensation table written | its format, text and provenance, the campaign it came from |
| verifications | verification campaign | the campaign before (its baseline) and the table written to the controller |

`source` is "directory" (a campaign directory), "table" (a point table recorded as a measurement of
its own: `history import FILE`) or "converted" (a table read by `axiscal convert`: a copy in
another format, not a campaign of its own).

Units: targets in the axis unit (mm or deg), deviations and U in the deviation unit (µm or
arcsec), dates in UTC (stored without a zone).
"""

from __future__ import annotations

import sqlalchemy as sa

metadata = sa.MetaData()

campaigns = sa.Table(
    "campaigns", metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("key", sa.String(64), nullable=False, unique=True),
    sa.Column("state", sa.String(64), nullable=False),
    sa.Column("source", sa.String(16), nullable=False),
    sa.Column("command", sa.String(16), nullable=False),
    sa.Column("machine", sa.String(200), nullable=False),
    sa.Column("axis", sa.String(100), nullable=False),
    sa.Column("axis_kind", sa.String(10), nullable=False),
    sa.Column("unit", sa.String(10), nullable=False),
    sa.Column("position_unit", sa.String(10), nullable=False),
    sa.Column("measured_utc", sa.DateTime, nullable=True),
    sa.Column("operator", sa.String(200), nullable=False),
    sa.Column("status", sa.String(20), nullable=False),
    sa.Column("points", sa.Integer, nullable=False),
    sa.Column("points_planned", sa.Integer, nullable=True),
    sa.Column("runs", sa.Integer, nullable=False),
    sa.Column("simulated", sa.Boolean, nullable=False),
    sa.Column("with_compensation", sa.Boolean, nullable=False),
    sa.Column("location", sa.Text, nullable=False),
    sa.Column("label", sa.String(300), nullable=False),
    sa.Column("standard", sa.String(40), nullable=False),
    sa.Column("verdict", sa.String(20), nullable=False),
    sa.Column("reasons", sa.JSON, nullable=False),
    sa.Column("checks", sa.JSON, nullable=False),
    sa.Column("tolerances", sa.JSON, nullable=False),
    sa.Column("uncertainty", sa.JSON, nullable=False),
    sa.Column("instrument", sa.JSON, nullable=False),
    sa.Column("plan", sa.JSON, nullable=False),
    sa.Column("fingerprint", sa.String(64), nullable=False),
    sa.Column("software", sa.String(100), nullable=False),
    sa.Column("recorded_utc", sa.DateTime, nullable=False),
    sa.Column("purpose", sa.String(20), nullable=False, server_default="acceptance"),
    sa.Column("follows", sa.Text, nullable=False, server_default=""),
    sa.Index("ix_campaigns_axis_date", "machine", "axis", "measured_utc"),
)

results = sa.Table(
    "results", metadata,
    sa.Column("campaign_id", sa.Integer, sa.ForeignKey("campaigns.id", ondelete="CASCADE"), primary_key=True),
    sa.Column("parameter", sa.String(10), primary_key=True),
    sa.Column("direction", sa.String(5), primary_key=True),
    sa.Column("value", sa.Float, nullable=True),
    sa.Column("expanded_u", sa.Float, nullable=True),
    sa.Column("u_recheck", sa.Float, nullable=True),
)

points = sa.Table(
    "points", metadata,
    sa.Column("campaign_id", sa.Integer, sa.ForeignKey("campaigns.id", ondelete="CASCADE"), primary_key=True),
    sa.Column("seq", sa.Integer, primary_key=True),
    sa.Column("run", sa.Integer, nullable=False),
    sa.Column("direction", sa.Integer, nullable=False),
    sa.Column("target", sa.Float, nullable=False),
    sa.Column("deviation", sa.Float, nullable=False),
    sa.Column("time_s", sa.Float, nullable=True),
)

comp_tables = sa.Table(
    "comp_tables", metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("key", sa.String(64), nullable=False, unique=True),
    sa.Column("campaign_id", sa.Integer, sa.ForeignKey("campaigns.id", ondelete="SET NULL"), nullable=True),
    sa.Column("format", sa.String(20), nullable=False),
    sa.Column("location", sa.Text, nullable=False),
    sa.Column("text", sa.Text, nullable=False),
    sa.Column("provenance", sa.JSON, nullable=False),
    sa.Column("machine", sa.String(200), nullable=False),
    sa.Column("axis", sa.String(100), nullable=False),
    sa.Column("written_utc", sa.DateTime, nullable=False),
)

verifications = sa.Table(
    "verifications", metadata,
    sa.Column("campaign_id", sa.Integer, sa.ForeignKey("campaigns.id", ondelete="CASCADE"), primary_key=True),
    sa.Column("before_id", sa.Integer, sa.ForeignKey("campaigns.id", ondelete="SET NULL"), nullable=True),
    sa.Column("before_location", sa.Text, nullable=True),
    sa.Column("compensation", sa.JSON, nullable=False),
)
