"""Campaigns have a purpose and the campaign they follow ([campaign] purpose, follows); the
results of A, E, B and R have their uncertainty between re-checks (campaign/history/recheck.py),
filled in here from the points each campaign holds.

A campaign recorded before has the purpose its record tells: a verification when it was measured
with a compensation table written for it, else an acceptance test.

Revision ID: r0002
Revises: r0001
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "r0002"
down_revision: str | None = "r0001"
branch_labels = None
depends_on = None


def upgrade() -> None:
    from campaign.history.recheck import k_of, recheck_u

    op.add_column("campaigns", sa.Column("purpose", sa.String(20), nullable=False, server_default="acceptance"))
    op.add_column("campaigns", sa.Column("follows", sa.Text, nullable=False, server_default=""))
    op.add_column("results", sa.Column("u_recheck", sa.Float, nullable=True))
    conn = op.get_bind()
    campaigns = sa.table("campaigns", sa.column("id", sa.Integer), sa.column("standard", sa.String),
                         sa.column("with_compensation", sa.Boolean), sa.column("purpose", sa.String))
    points = sa.table("points", sa.column("campaign_id", sa.Integer), sa.column("seq", sa.Integer),
                      sa.column("run", sa.Integer), sa.column("direction", sa.Integer),
                      sa.column("target", sa.Float), sa.column("deviation", sa.Float))
    results = sa.table("results", sa.column("campaign_id", sa.Integer), sa.column("parameter", sa.String),
                       sa.column("direction", sa.String), sa.column("u_recheck", sa.Float))
    conn.execute(campaigns.update().where(campaigns.c.with_compensation.is_(True)).values(purpose="verification"))
    for campaign_id, standard in conn.execute(sa.select(campaigns.c.id, campaigns.c.standard)).all():
        rows = conn.execute(sa.select(points.c.run, points.c.direction, points.c.target, points.c.deviation)
                            .where(points.c.campaign_id == campaign_id).order_by(points.c.seq)).all()
        if not rows:
            continue
        run, direction, target, deviation = zip(*rows)
        for parameter, u in recheck_u(run, direction, target, deviation, k_of(standard or "")).items():
            conn.execute(results.update().where(results.c.campaign_id == campaign_id,
                                                results.c.parameter == parameter,
                                                results.c.direction == "both").values(u_recheck=u))


def downgrade() -> None:
    with op.batch_alter_table("results") as batch:
        batch.drop_column("u_recheck")
    with op.batch_alter_table("campaigns") as batch:
        batch.drop_column("follows")
        batch.drop_column("purpose")
