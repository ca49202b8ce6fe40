"""The worlds of exobench as scenario definitions over the simulation core: each a world builder,
a route and gait, a default rig and its parameter table.

- :mod:`.stairs`: one climbing step in front of a staircase (the stairs track).
- :mod:`.office`: a walk along an office route (the LiDAR tracks); :mod:`.office_camera` the same
  walk with a worn RGB-D camera and its IMU, turning as on the courses (the vio track).
- :mod:`.course`: a walk along a course of stairs and ramps (the locomotion track), its worlds in
  :mod:`.course_world`.
"""
