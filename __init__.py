"""exobench: a MuJoCo benchmark for exoskeleton perception.

Packages: ``exobench.core`` (contracts), ``exobench.models`` (robot and worlds),
``exobench.envs`` (motion, sensing, sessions, gymnasium), ``exobench.perception`` and
``exobench.mapping`` (estimators), ``exobench.benchmarks`` (tracks, harness, CLI).
"""

__version__ = "0.1.0"
