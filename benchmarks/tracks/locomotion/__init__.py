"""The locomotion track: locomotion-mode prediction from terrain reconstruction (seeds/002).

``track`` (the spec: suites and cases, scenario, scorer), ``paper`` (the published figures and
the grid they index), ``metrics`` (scoring per step), ``report`` (Tables II/III beside ours,
confusion, anticipation, timelines), ``recording`` (rerun).
"""

from .track import LocomotionTrack

__all__ = ["LocomotionTrack"]
