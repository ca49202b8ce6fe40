"""The lidar-filter track: ground-aware intensity filtering of office LiDAR scans (seeds/003).

``track`` (the spec), ``paper`` (Table 5.4), ``metrics`` (point-by-point scoring and KISS-ICP on
the kept points), ``report`` (Table 5.4 layout). Its trajectory scoring, figures and rerun
recording are shared with the odometry track (:mod:`..lidar_trajectory`, :mod:`..office_recording`).
"""

from .track import LidarFilterTrack

__all__ = ["LidarFilterTrack"]
