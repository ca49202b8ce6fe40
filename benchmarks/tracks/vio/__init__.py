"""The vio track: RGB-D-inertial odometry of a worn camera (seeds/002 II-C, IV).

``track`` is its spec; ``scenario`` its sequences (office and course walks with a head, chest or
thigh camera and its IMU), ``paper`` the published figures and the paper suite, ``general`` the
seeded draws, ``metrics`` the scorer, ``report`` and ``recording`` what a user sees.
"""

from .track import VioTrack

__all__ = ["VioTrack"]
