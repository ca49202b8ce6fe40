"""exobench.models"""
