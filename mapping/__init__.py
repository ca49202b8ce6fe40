"""exobench.mapping: estimators that integrate over time (may use ``exobench.perception``).

One subpackage per problem (each re-exports its pipelines and configs; this package imports
nothing heavy):

- ``tsdf``: TSDF volume on Open3D's voxel block grid (seeds/002 eq. 19-22) and its ray cast.
- ``locomotion``: pipelines ``terrain-recon`` (``terrain-recon-dvio`` on D-VIO's poses) and ``single-frame``
  (locomotion mode of the next step).
- ``odometry``: pipelines ``kiss-icp`` (with an optional filter stage) and ``leo-slam``.
"""
