"""Benchmarks for sieve-mi: ``python -m benchmarks.run``."""
