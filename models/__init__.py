"""exobench.models: what the exoskeleton and the worlds *are*.

- :mod:`exobench.models.exo_spec`: every length, mass and sensor mount of the device and its user.
- :mod:`exobench.models.exo`: the exoskeleton as MuJoCo bodies (``add_exo``), a URDF
  (``exo_urdf``) and a pipeline's Calibration (``exo_calibration``).
- :mod:`exobench.models.worlds`: staircase, ramp, course and level builders with exact ground
  truth, and ``compose`` (world + exoskeleton -> compiled model).

Submodules import MuJoCo lazily, so importing this package is cheap. See ``models/README.md``.
"""
