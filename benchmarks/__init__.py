"""Throughput benchmarks for polyenvs against peer environments."""
