"""The vio track's published figures (seeds/002 Tables IV and V) and its suites' cases.

Table IV (seeds/002, EuRoC MAV): RMSE of the APE per sequence, m, and the mean time per frame, for
D-VIO ("Ours"), VINS-Mono, VINS-RGBD and VINS-Fusion; D-VIO's mean over the ten sequences is
0.091 m, VINS-Mono's 0.167 m. Table V: the loop drift of the closed-loop test (one real loop walked
with the paper's head/chest hardware), x/y/z. exobench's ``dvio`` is the paper's D-VIO and
``dvio-no-depth`` the same without its depth factors (the paper's ablation: VINS-Mono). The
paper has no ORB-SLAM3 figure.

The ``paper`` suite is shaped like Table IV's sequences and Table V's loop, in the simulated
office: one office walk per EuRoC sequence, as long as it (clipped to 35-90 m) and as fast as the
walker allows (:data:`PACES`: wander below 0.5 m/s, walk to 0.8 m/s, jog above), mounts head,
chest and thigh in turn, users of 1.65-1.88 m (the paper's subjects); then closed loops that end
where they start (the whole corridor ring; a walk there and back), and the stair and ramp courses
(locomotion's worlds). EuRoC's lengths and speeds (Burri et al., IJRR 2016, the dataset's
overview; seeds/002 ref. [35]) are a guide only: the sequences are a flying MAV's, ours a walker's.
They were checked against the dataset itself (:data:`EUROC_LENGTH_SPEED`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..spec import Case, Reference

EUROC = ("MH01", "MH02", "MH03", "MH04", "MH05", "V101", "V102", "V103", "V201", "V202")
TABLE_IV = {  # pipeline -> APE RMSE per EuRoC sequence (m), seeds/002 Table IV
    "dvio": (0.05, 0.06, 0.09, 0.19, 0.17, 0.05, 0.06, 0.09, 0.07, 0.08),
    "dvio-no-depth": (0.10, 0.18, 0.24, 0.30, 0.31, 0.10, 0.08, 0.18, 0.08, 0.10),  # VINS-Mono
}
TABLE_IV_OTHERS = {  # peers of the paper exobench does not run
    "VINS-RGBD": (0.09, 0.16, 0.20, 0.29, 0.32, 0.05, 0.06, 0.15, 0.07, 0.09),
    "VINS-Fusion": (0.12, 0.23, 0.28, 0.22, 0.19, 0.10, 0.11, 0.10, 0.09, 0.09),
}
TIME_MS = {"dvio": 31.0, "dvio-no-depth": 63.0}  # VINS-RGBD 56, VINS-Fusion 71
TIME_MS_OTHERS = {"VINS-RGBD": 56.0, "VINS-Fusion": 71.0}
TABLE_V = {  # loop drift x / y / z, m, seeds/002 Table V (VINS-Mono: > 10 m each)
    "dvio": (-0.216, 0.023, 0.136),
    "VINS-RGBD": (-0.485, 0.148, 0.226),
}
# EuRoC (Burri et al. 2016): length (m), mean speed (m/s) of each sequence. Verified against the
# dataset's ground truth (state_groundtruth_estimate0 of each sequence, as OpenVINS redistributes it
# in github.com/rpng/open_vins ov_data/euroc_mav/<sequence>.txt, commit 69488123): path length over
# the 200 Hz poses and length / duration give these figures to the digit (MH03: 130.9 m in 131.5 s,
# 0.995 m/s, which the overview rounds to 0.99); OpenVINS's docs/gs-datasets.dox lists the same
# lengths to the metre. V101: the original ground truth (V1_01_easy_original.txt; OpenVINS's re-estimated
# one gives 58.4 m). Durations, s: MH01-05 181.9, 150.0, 131.5, 98.8, 111.1; V101-103 143.6, 83.5,
# 104.7; V201-202 112.0, 115.5.
EUROC_LENGTH_SPEED = {
    "MH01": (80.6, 0.44), "MH02": (73.5, 0.49), "MH03": (130.9, 0.99), "MH04": (91.7, 0.93), "MH05": (97.6, 0.88),
    "V101": (58.6, 0.41), "V102": (75.9, 0.91), "V103": (79.0, 0.75), "V201": (36.5, 0.33), "V202": (83.2, 0.72),
}  # fmt: skip
LENGTH_RANGE_M = (35.0, 90.0)
# office paces: (step length m, swing s) as the course's patterns (envs.sim.scenarios.course.PATTERNS)
PACES = {"wander": (0.35, 0.55), "walk": (0.40, 0.42), "jog": (0.45, 0.30)}
MOUNTS = ("head", "chest", "thigh")
USERS_M = (1.65, 1.70, 1.75, 1.79, 1.84, 1.88)  # the paper's subjects span 1.65-1.88 m
TEXTURED = {"surfaces": "textured"}
# the course walks are indoor stairs and ramps: in a stairwell (end walls and a ceiling,
# envs.sim.scenarios.course_enclosure), as the locomotion track's indoor protocols (``auto``: a
# parallel course or one without walls, set on the command line, stays open instead of refused)
STAIRWELL = {"enclosure": "auto"}


def pace_of(speed_m_s: float) -> str:
    return "wander" if speed_m_s < 0.5 else "walk" if speed_m_s < 0.8 else "jog"


def office_case_values(mount: str, length_m: float, pace: str, user_m: float) -> dict[str, Any]:
    step, swing = PACES[pace]
    return {"world": "office", "route": "loop", "max_distance_m": float(length_m), "mount": mount,
            "step_length_m": step, "swing_s": swing, "user_height_m": user_m, **TEXTURED}  # fmt: skip


def quick_cases() -> list[Case]:
    """One short office walk per mount and one short closed loop (there and back)."""
    walks = [Case(f"office-{m}", "quick", {"world": "office", "mount": m, "max_distance_m": 0.8, **TEXTURED},
                  figure=True) for m in MOUNTS]  # fmt: skip
    loop = Case("loop-chest", "quick loop", {"world": "office", "mount": "chest", "max_distance_m": 1.2,
                                             "out_and_back": True, "max_turn_deg": 60.0, **TEXTURED}, figure=True)  # fmt: skip
    return [*walks, loop]


def paper_cases() -> list[Case]:
    """Table IV's sequences in the office, Table V's loops, and the courses (module docstring)."""
    out = []
    for i, seq in enumerate(EUROC):
        length, speed = EUROC_LENGTH_SPEED[seq]
        length = float(np.clip(length, *LENGTH_RANGE_M))
        mount, pace, user = MOUNTS[i % 3], pace_of(speed), USERS_M[i % len(USERS_M)]
        out.append(Case(f"{seq}-like", seq, office_case_values(mount, length, pace, user), figure=True))
    out += [
        Case("loop-ring-head", "loop", {"world": "office", "route": "ring", "max_distance_m": 500.0, "mount": "head",
                                        "user_height_m": 1.75, **TEXTURED}, figure=True),
        Case("loop-back-chest", "loop", {"world": "office", "route": "loop", "max_distance_m": 40.0,
                                         "out_and_back": True, "mount": "chest", "user_height_m": 1.84, **TEXTURED},
             figure=True),
        Case("stairs-head-walk", "course", {"world": "course", "terrain": "stairs", "riser_m": 0.15, "mount": "head",
                                            "pattern": "walk", "user_height_m": 1.70, **TEXTURED, **STAIRWELL}, figure=True),
        Case("ramp-chest-wander", "course", {"world": "course", "terrain": "ramp", "slope_deg": 15.8, "mount": "chest",
                                             "pattern": "wander", "user_height_m": 1.79, **TEXTURED, **STAIRWELL}, figure=True),
        Case("stairs-thigh-jog", "course", {"world": "course", "terrain": "stairs", "riser_m": 0.20, "mount": "thigh",
                                            "pattern": "jog", "user_height_m": 1.88, **TEXTURED, **STAIRWELL}, figure=True),
    ]  # fmt: skip
    return out


def course_cases() -> list[Case]:
    """The paper suite's course walks alone (a short suite of the second world)."""
    return [c for c in paper_cases() if c.scenario["world"] == "course"]


def references() -> list[Reference]:
    refs = []
    for pipe, values in TABLE_IV.items():
        for seq, v in zip(EUROC, values, strict=True):
            refs.append(Reference("ate_m", f"{v:.2f} (EuRoC {seq})", "Tab. IV", (seq,), (pipe,), value=v))
        mean = float(np.mean(values))
        refs.append(Reference("ate_m", f"{mean:.3f} (EuRoC mean)", "Tab. IV", (), (pipe,), value=mean))
        refs.append(Reference("time_per_frame_ms", f"{TIME_MS[pipe]:.0f}", "Tab. IV", (), (pipe,), value=TIME_MS[pipe]))
    x, y, z = TABLE_V["dvio"]
    te = float(np.sqrt(x * x + y * y + z * z))
    loops = ("loop", "quick loop")
    refs += [
        Reference("te_m", f"{te:.3f} (|(-0.216, 0.023, 0.136)|)", "Tab. V", loops, ("dvio",), value=te),
        Reference("tve_x_m", "-0.216", "Tab. V", loops, ("dvio",), value=x),
        Reference("tve_y_m", "0.023", "Tab. V", loops, ("dvio",), value=y),
        Reference("tve_z_m", "0.136", "Tab. V", loops, ("dvio",), value=z),
        Reference("te_m", "> 10 each axis (VINS-Mono)", "Tab. V", loops, ("dvio-no-depth",)),
    ]  # fmt: skip
    return refs
