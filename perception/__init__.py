"""exobench.perception"""
