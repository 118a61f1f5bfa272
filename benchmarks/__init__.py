"""Benchmarks of closure_nlp: `python -m benchmarks.bench WHAT` prints JSON."""
