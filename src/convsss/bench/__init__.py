"""Benchmarks that print tables (never part of the tests' pass/fail): one module per benchmark.

- :mod:`.transport`: the layered convolution transport per stage against the bare FFT floor;
- :mod:`.accuracy`: error against the exact sum vs time, convolution and hierarchical transports, Pareto fronts.
"""
