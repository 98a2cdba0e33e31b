"""Benchmarks runnable as `jointtrack bench NAME`; peers are optional (the `bench` extra)."""
