"""The results store: validations recorded in a database (SQLite by default, any SQLAlchemy URL)."""
