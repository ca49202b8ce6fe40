"""exobench.mapping: estimators that integrate over time (may use ``exobench.perception``).

Modules (import them directly; this package imports nothing heavy):

- ``tsdf``: TSDF volume on Open3D's voxel block grid with the weighting of seeds/002 eq. 19-22,
  and ray casting into a smoothed depth image.
- ``locomotion``: the locomotion-track pipelines ``terrain-recon`` (TSDF, AHC planes, eq. 23,
  terrain description, eq. 16-18 footprint, next-step mode) and ``single-frame`` (ablation).
- ``preprocess``, ``gicp``, ``submaps``, ``loop_closure``, ``pose_graph``, ``leo_slam``: LEO-SLAM
  (seeds/003 section 4.2.1), pipeline ``leo-slam``.
- ``kiss_icp_pipeline``: the ``kiss-icp`` package as the peer odometry pipeline ``kiss-icp``.
"""
