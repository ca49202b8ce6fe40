"""The loop-closure track: place recognition with SC++ and Gaussian Scan Context (seeds/003).

``track`` (the spec: office loops, scenario, references), ``metrics`` (precision-recall against
the true trajectory), ``report`` (PR curves, loop matches), ``recording`` (rerun).
"""

from .track import LoopClosureTrack

__all__ = ["LoopClosureTrack"]
