"""Alembic migrations of the server's database (run by `server.db.migrate`)."""
