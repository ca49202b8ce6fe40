"""The odometry track: LiDAR trajectory estimation on office walks (seeds/003).

``track`` is its spec. Its metrics, figure data and report section (:mod:`..lidar_trajectory`)
and its rerun recording (:mod:`..office_recording`) are shared with the lidar-filter track,
which scores KISS-ICP on each filter's kept points the same way.
"""

from .track import OdometryTrack

__all__ = ["OdometryTrack"]
