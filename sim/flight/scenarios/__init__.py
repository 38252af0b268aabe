"""Flight scenarios: the paper's test scenario (PAPER.md)."""
