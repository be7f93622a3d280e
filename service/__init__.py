"""Driving a world through time and handing each block to its sinks (the log, Redis, a progress
bar): what `record`, what-if replay and the benchmarks share, and later the live service."""
