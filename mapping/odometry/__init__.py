"""LiDAR odometry and SLAM (the ``odometry`` track)."""
