"""Alembic migrations of the server's database (run by `store.db.migrate`)."""
