"""The stairs track: staircase identification from calf ToF rays (seeds/004).

``track`` (the spec: suites, scenario, scorer, published figures), ``metrics`` (scoring),
``report`` (side views and error distributions), ``recording`` (rerun).
"""

from .track import StairsTrack

__all__ = ["StairsTrack"]
