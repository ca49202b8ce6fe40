"""exobench.perception: per-frame estimators that run on sensor frames alone (live or recorded).

Modules (import them directly; this package imports nothing heavy):

- ``rtls``: recursive total least squares planes of the staircase paper (general and HTVR).
- ``staircase``: the paper's Algorithm 1 (Assign / SurfUpdate / Shift) over surfaces S0..S4.
- ``tof_kinematics``: ToF beam hit points by forward kinematics (pinocchio) in ``stance_ground``.
- ``readout``: riser height and tread depth from estimated planes.
- ``pipelines``: the stairs-track pipelines ``rtls``, ``rtls-htvr`` and ``batch-ransac``.
- ``intensity_filter``: LiDAR intensity filters (none, threshold, naive and normal ground-aware).
- ``scan_context`` / ``gaussian_scan_context``: Scan Context++ and Gaussian Scan Context place
  recognition on scans and submaps.
- ``footprint``: gait division by heel strikes and next-footprint prediction (seeds/002 eq. 16-18).
- ``plane_tracking``: plane set update by IoU with scores (seeds/002 eq. 23).
- ``plane_extraction``: agglomerative hierarchical clustering of depth-image cells into planes.
- ``terrain_description``: level ground, ramps and stairs from the plane set; the next step's mode.
- ``filter_pipelines``: the lidar-filter pipelines (footprint transform from kinematics and tilt).
- ``place_recognition``: the loop-closure pipelines ``sc++``, ``gsc-height``, ``gsc-huber``,
  ``gsc-intensity``.

Perception never imports ``exobench.mapping`` (mapping builds on perception, not the reverse).
"""
