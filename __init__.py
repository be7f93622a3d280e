"""Touchdown: what a spacecraft does in the seconds after it touches a planet's surface.

The repository root is this package (pyproject.toml maps ``touchdown`` onto it): ``touchdown.sim``
is the pure core; ``logs``, ``replay``, ``view``, ``service``, ``sweep`` and ``bench`` sit at its edges;
``touchdown.cli`` is the command line."""
