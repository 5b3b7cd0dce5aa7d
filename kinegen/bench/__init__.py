"""Benchmarks (``make bench``): the chain-N mechanism and the contenders run on it."""
