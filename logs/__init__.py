"""The edges that persist and publish: MCAP logs, JSON Lines export, the Redis stream."""


from touchdown.sim.errors import TouchdownError


class LogError(TouchdownError):
    """The one root exception for a log that cannot be read or written; one line, names the file
    (exit 2: a bad log; a log that cannot be written is the command's WorkFailed)."""
