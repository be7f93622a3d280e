"""The edges that persist and publish: MCAP logs, JSON Lines export, the Redis stream."""


class LogError(Exception):
    """The one root exception for a log that cannot be read or written; one line, names the file."""
