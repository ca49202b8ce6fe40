"""Ground-aware LiDAR intensity filters (the ``lidar-filter`` track), also a stage of odometry."""
