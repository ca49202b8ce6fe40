"""Estimators that integrate over time (TSDF, odometry, SLAM, maps). Empty in this release:
the tracks that need them (locomotion, odometry, multisession, navigation) come later."""
