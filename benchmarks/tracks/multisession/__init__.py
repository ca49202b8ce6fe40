"""The multisession track: one office over several days, sessions merged, changes found (seeds/000).

``track`` (the spec: suites, references, summary rows), ``episodes`` (multi-session episodes and
their compact truth), ``scoring`` (Tables I-III's metrics of an estimate), ``metrics`` (the point-set
metrics), ``report`` (Tables I-III, Fig. 3 top views, rerun recording).
"""

from .track import MultisessionTrack

__all__ = ["MultisessionTrack"]
