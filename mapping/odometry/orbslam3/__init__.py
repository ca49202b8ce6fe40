"""ORB-SLAM3 (GPL-3.0) as the ``orb-slam3`` pipeline, behind a process boundary.

- :mod:`.adapter`: the pipeline :class:`OrbSlam3Pipeline` (RGB-D-inertial).
- :mod:`.settings`: its config and the ORB-SLAM3 settings file written from the calibration.
- :mod:`.worker_client`: the worker process and its protocol; ``orbslam3-worker.py`` is the
  worker, the only file that imports ``pyorbslam3`` (the optional extra ``orbslam3``), run as a
  script and never imported.
- :mod:`.vocabulary`: an ORB vocabulary in DBoW2's text format built from images.
"""

from .adapter import OrbSlam3Pipeline
from .settings import OrbSlam3Config

__all__ = ["OrbSlam3Config", "OrbSlam3Pipeline"]
