"""exobench.perception: per-frame estimators that run on sensor frames alone (live or recorded).

One subpackage per problem (each re-exports its pipelines and configs; this package imports
nothing heavy):

- ``stairs``: RTLS staircase estimation from two ToF beams; pipelines ``rtls``, ``rtls-htvr``,
  ``batch-ransac``.
- ``lidar_filter``: ground-aware LiDAR intensity filters; pipelines ``filter-<name>``.
- ``place_recognition``: Scan Context++ and Gaussian Scan Context; pipelines ``sc++``,
  ``gsc-height``, ``gsc-huber``, ``gsc-intensity``.
- ``terrain``: AHC planes, plane tracking, terrain description, footprints (used by
  ``exobench.mapping.locomotion``).
- ``kinematics``: forward kinematics of sensor mounts (pinocchio), shared by the above.

Perception never imports ``exobench.mapping`` (mapping builds on perception, not the reverse).
"""
