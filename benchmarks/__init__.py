"""exobench.benchmarks"""
