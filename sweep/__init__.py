"""``touchdown sweep``: the touchdown envelope, many touchdowns in one command (SPEC.md 2, 6)."""
