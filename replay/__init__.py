"""Replaying logs (issue 3). Nothing here yet: `touchdown replay` is not implemented."""
