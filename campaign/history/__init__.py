"""The campaign store and what it tells: every campaign of every axis in one database (SQLite by
default, PostgreSQL for a plant), its trend, change points, and when the axis will leave its
tolerance (docs/history.md).

The modules are imported where they are used, never here: the store needs SQLAlchemy, which only
the commands that use the store load (`axiscal --help` stays fast).

| module | what it holds |
|---|---|
| `location` | where the store is (--db, AXISCAL_DB, the default file), its URL shown without credentials |
| `schema`, `migrations/` | the tables (SQLAlchemy Core) and their migrations (Alembic) |
| `store` | opening, migrating, writing and reading the store |
| `entry` | what is recorded of a campaign directory or a point table (via campaign.assess) |
| `recording`, `pending` | recording after a command; the queue while the store is unreachable |
| `trend`, `axis` | drift rates, change points, the crossing date; which campaigns count |
| `compare`, `plots` | two campaigns compared; the plots |
| `simulated` | a simulated history of the demo axis |
"""
