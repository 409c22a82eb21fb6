"""The store's schema migrations (Alembic). `campaign.history.store.open_store` brings a store to
the newest revision when it opens it; each revision in versions/ is frozen once released."""
