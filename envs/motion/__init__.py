"""How the exoskeleton moves: leg kinematics, then swings, then climbing and walking.

The modules import in one direction only (a test checks it, tests/envs/test_envs_motion_layers.py):

1. :mod:`.kinematics` (leg IK/FK within the joint limits, the sole footprint, double-stance
   pelvis poses) and :mod:`.route` (what the walker is asked to walk);
2. :mod:`.motion` (:class:`Motion`: segments sampled as MuJoCo ``qpos``/``qvel``/``qacc``) and
   :mod:`.footholds` (where a foot can stand);
3. :mod:`.swing` (swing trajectories and their apex);
4. :mod:`.step` (:func:`plan_step`, the walker's public one-step planner, also used by the
   gymnasium environment);
5. :mod:`.climb` (the staircase paper's climbing step, :func:`climb_step`) and :mod:`.walk`
   (:func:`plan_walk` along a :class:`Route`);
6. the locomotion track's additions to a planned walk: :mod:`.view` (head and chest camera
   motion, gaze at transitions), :mod:`.pedestrians`, :mod:`.odometry` (drifting odometry).

Terrain queries over the scene truth live one level down, in :mod:`exobench.envs.terrain`.
"""

from .climb import climb_step
from .footholds import Foot, Footholds
from .kinematics import (
    CLIMB_LEAN_RAD,
    LEVEL_LEAN_RAD,
    STANCE_KNEE_MAX_RAD,
    STAND_KNEE_RAD,
    GaitError,
    end_pelvis,
    end_pelvis_options,
    foot_width_m,
    leg_fk,
    leg_ik,
    leg_length_for_knee,
    rot_yaw_pitch,
    sole_grid_f,
    toe_pivot,
)
from .motion import Footstep, Motion, MotionSample, MotionState, Segment, check_feasible, min_jerk
from .odometry import drift_odometry, gravity_aligned
from .pedestrians import PedestrianPath, pedestrian_paths
from .route import Route
from .step import StepPlan, StepStart, heel_rises, plan_step
from .swing import (
    SWING_SHAPES,
    SWING_SHAPES_DEEP_DIP,
    SwingPlan,
    heel_drop_segment,
    still_segment,
    swing_apex_m,
)
from .view import GazeDown, ViewMotion, gaze_looks, view_motion
from .walk import plan_walk

__all__ = [
    "CLIMB_LEAN_RAD",
    "LEVEL_LEAN_RAD",
    "STANCE_KNEE_MAX_RAD",
    "STAND_KNEE_RAD",
    "SWING_SHAPES",
    "SWING_SHAPES_DEEP_DIP",
    "Foot",
    "Footholds",
    "Footstep",
    "GaitError",
    "GazeDown",
    "Motion",
    "MotionSample",
    "MotionState",
    "PedestrianPath",
    "Route",
    "Segment",
    "StepPlan",
    "StepStart",
    "SwingPlan",
    "ViewMotion",
    "check_feasible",
    "climb_step",
    "drift_odometry",
    "end_pelvis",
    "end_pelvis_options",
    "foot_width_m",
    "gaze_looks",
    "gravity_aligned",
    "heel_drop_segment",
    "heel_rises",
    "leg_fk",
    "leg_ik",
    "leg_length_for_knee",
    "min_jerk",
    "pedestrian_paths",
    "plan_step",
    "plan_walk",
    "rot_yaw_pitch",
    "sole_grid_f",
    "still_segment",
    "swing_apex_m",
    "toe_pivot",
    "view_motion",
]
