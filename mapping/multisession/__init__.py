"""Multi-session mapping with change detection: the building blocks of LT-Exosense (seeds/000 III-A/B).

- :mod:`.place_recognition`: ORB bag-of-binary-words vocabulary trained in the project, TF-IDF
  and DBoW2's L1 score, a keyframe database (III-B.1).
- :mod:`.relative_pose`: SIFT matches, PnP in RANSAC with the candidate's depth image, the
  covariance of the fit, the candidate with most inliers (III-B.2).
- :mod:`.keyframes`: keyframe images, depth and features on disk in a temporary folder of the
  pipeline's own; only pose graphs stay in memory.
- :mod:`.matching`: place recognition + PnP verification over the stored keyframes, giving
  inter-session edges and intra-session loops.
- :mod:`.merge`: per-session keyframe pose graphs merged by Levenberg-Marquardt with a Cauchy
  loss, session 1 anchoring; a session joined to no other stays its own map (eq. 1).
- :mod:`.change`: change detection between the prior map and a new session, ``kind`` octree
  (OctoMap differencing at 5 cm: removed and added octrees, eq. 2-3) or dufomap (DUFOMap).
"""
