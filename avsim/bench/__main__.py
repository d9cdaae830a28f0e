"""`python -m avsim.bench` is `avsim bench`'s default table (`avsim.bench.speed`)."""

from avsim.bench.speed import run_benchmarks

run_benchmarks()
