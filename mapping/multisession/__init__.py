"""Multi-session mapping with change detection: the building blocks of LT-Exosense (seeds/000 III-A/B).

- :mod:`.place_recognition`: ORB bag-of-binary-words vocabulary trained in the project, TF-IDF
  and DBoW2's L1 score, a keyframe database (III-B.1).
- :mod:`.relative_pose`: SIFT matches, PnP in RANSAC with the candidate's depth image, the
  covariance of the fit, the candidate with most inliers (III-B.2).
"""
