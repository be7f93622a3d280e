"""Replaying logs: re-run a recording from its own scenario and inputs, bit for bit (a fold of
``sim.step`` over the recorded inputs), compare it with what was recorded, or ask "what if"."""
