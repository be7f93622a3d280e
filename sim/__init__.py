"""Touchdown's pure core: post-touchdown rigid-body physics as a batched, deterministic tick step.

No I/O, no wall clock: ``step(params, state, inputs) -> (state, outputs, events)``.
"""
__version__ = "0.8.0"
