"""Benchmark inputs and runners shared by ``swarmshow bench`` and ``benchmarks/``."""
