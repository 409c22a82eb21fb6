"""The first schema: campaigns, their results and points, compensation tables, verifications.

Revision ID: r0001
Revises:
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "r0001"
down_revision: str | None = None
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "campaigns",
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
    )
    op.create_index("ix_campaigns_axis_date", "campaigns", ["machine", "axis", "measured_utc"])
    op.create_table(
        "results",
        sa.Column("campaign_id", sa.Integer, sa.ForeignKey("campaigns.id", ondelete="CASCADE"), primary_key=True),
        sa.Column("parameter", sa.String(10), primary_key=True),
        sa.Column("direction", sa.String(5), primary_key=True),
        sa.Column("value", sa.Float, nullable=True),
        sa.Column("expanded_u", sa.Float, nullable=True),
    )
    op.create_table(
        "points",
        sa.Column("campaign_id", sa.Integer, sa.ForeignKey("campaigns.id", ondelete="CASCADE"), primary_key=True),
        sa.Column("seq", sa.Integer, primary_key=True),
        sa.Column("run", sa.Integer, nullable=False),
        sa.Column("direction", sa.Integer, nullable=False),
        sa.Column("target", sa.Float, nullable=False),
        sa.Column("deviation", sa.Float, nullable=False),
        sa.Column("time_s", sa.Float, nullable=True),
    )
    op.create_table(
        "comp_tables",
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
    op.create_table(
        "verifications",
        sa.Column("campaign_id", sa.Integer, sa.ForeignKey("campaigns.id", ondelete="CASCADE"), primary_key=True),
        sa.Column("before_id", sa.Integer, sa.ForeignKey("campaigns.id", ondelete="SET NULL"), nullable=True),
        sa.Column("before_location", sa.Text, nullable=True),
        sa.Column("compensation", sa.JSON, nullable=False),
    )


def downgrade() -> None:
    for table in ("verifications", "comp_tables", "points", "results", "campaigns"):
        op.drop_table(table)
