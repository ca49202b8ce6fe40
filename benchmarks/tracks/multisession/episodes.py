"""Episodes of several sessions: one office walked on several days, streamed as one episode.

A scenario is the office walk's table (:data:`exobench.envs.sim.scenarios.office.PARAMS`: the
building, its furniture layer and change script, the walk) plus :data:`EXTRA`:

- ``sessions``: the sessions in order, ``DAY:REGION,REGION,...`` separated by ``;`` (each a walk
  through those regions, ``route_regions``, in the office of that day); days never go back.
- ``camera``: where the RGB-D camera sits (``thigh``, the paper's; ``head`` or ``chest``), with
  its IMU (200 Hz) and the ``odometry`` sensor kind's drift model; camera (424 x 240 pixels) and
  odometry at ``frame_rate_hz``.
- ``odom_drift_pct`` / ``odom_yaw_drift_deg_per_m``: the odometry's drift model (1 % of the
  distance, 0.02 deg/m of heading; see :data:`ODOM_YAW_DRIFT_DEG_PER_M`).
- ``place_label_error_fraction``: that fraction of each session's place labels is wrong, each
  replaced by another region kind of the building (seeded,
  :func:`exobench.core.faults.swap_place_labels`).

The stream (:func:`stream_sessions`): per session a :class:`~exobench.core.frames.SessionStart`,
then the session's frames with their stamps moved after the previous session's (a gap of
:data:`GAP_S`), and before each RGB-D frame a :class:`~exobench.core.frames.PlaceLabel`: the
kind of the layout region (``corridor``, ``office``, ``meeting``) the camera stands in, ``""``
outside every region (a doorway). Each session is simulated when the previous one is used up,
so memory stays that of one session. Every session's odometry starts in a frame of its own
(gravity-aligned, at its first camera pose): sessions know nothing of each other.

Truth (``EpisodeTruth.extra``), kept compactly: ``sessions``, one dict per session (``session``,
``day``, ``camera_w``: (N, 8) rows ``[t, x, y, z, qw, qx, qy, qz]`` of the true optical-frame
pose at each camera frame, stamps as streamed, and ``T_world_odom``); ``changes``: per day
1..last the change truth's appeared and disappeared samples (1 cm), changed objects, and per
sample whether it lies on a changed object (``appeared_on_object``, ``disappeared_on_object``;
the others are static surfaces the object covered or uncovered: the floor under a box);
``surface_last_day``: the true surfaces of the last day at :data:`SURFACE_SPACING_M` as far
around the walks as the camera reaches (Table III; ``surfaces_by_day``: those of every day
walked). ``T_world_estimator`` is session 0's odometry frame: the merged map's frame.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator, Mapping, Sequence
from functools import lru_cache
from typing import Any

import numpy as np

from exobench.core.episode import Episode, EpisodeStream, EpisodeTruth
from exobench.core.errors import ConfigError
from exobench.core.faults import swap_place_labels
from exobench.core.frames import PlaceLabel, RgbdFrame, SessionStart
from exobench.models.world_params import ParamSpec

GAP_S = 1.0  # between one session's last frame and the next one's mark
SURFACE_SPACING_M = 0.01  # the change truth's grid
CAMERAS = ("thigh", "head", "chest")
# The paper's sessions come from Exosense: OpenVINS visual-inertial odometry in a LEXIS pose graph
# (seeds/000 IV). The odometry kind's default heading drift, 0.5 deg/m, turns a 12-14 m session by
# 6-7 deg, far more than the paper's figures allow: its single-session maps are within 0.024 m of the
# laser scans (Table III) and its OpenVINS front end merges EuRoC's 37-86 m flights to an ATE of
# 0.04-0.086 m (Table I). The locomotion track's source, D-VIO's 0.26 m loop drift (seeds/002
# Table V), is met by the 1 % translation drift alone, with a heading drift of 0.02 deg/m beside it
# (docs/tracks/locomotion.md): the same figure here, as for its multi-direction walks.
ODOM_DRIFT_PCT = 1.0
ODOM_YAW_DRIFT_DEG_PER_M = 0.02

EXTRA: dict[str, ParamSpec] = {
    "sessions": ParamSpec("0:corridor_s;1:corridor_s", None, None, "", "sessions in order, DAY:REGION,REGION,... "
                          "separated by ';' (each walks through those regions in the office of that day)"),
    "camera": ParamSpec("thigh", None, None, "", "where the RGB-D camera with its IMU and odometry sits",
                        choices=CAMERAS),
    "frame_rate_hz": ParamSpec(10.0, 1.0, 30.0, "Hz", "camera and odometry rate"),
    "odom_drift_pct": ParamSpec(ODOM_DRIFT_PCT, 0.0, 20.0, "%", "odometry translation drift, percent of the "
                                "distance travelled"),
    "odom_yaw_drift_deg_per_m": ParamSpec(ODOM_YAW_DRIFT_DEG_PER_M, 0.0, 20.0, "deg/m",
                                          "odometry heading drift per metre travelled"),
    "place_label_error_fraction": ParamSpec(0.0, 0.0, 1.0, "", "fraction of place labels that are wrong (seeded)"),
}  # fmt: skip


@dataclasses.dataclass(frozen=True)
class SessionPlan:
    """One session of a scenario: its id, day and the regions its walk goes through."""

    session: int
    day: int
    regions: tuple[str, ...]


def parse_sessions(text: str) -> tuple[SessionPlan, ...]:
    """The ``sessions`` row as plans; ConfigError naming the row for a malformed or empty one,
    or days that go back."""
    allowed = "DAY:REGION,REGION,... separated by ';', days in order (e.g. '0:corridor_s;1:corridor_s,office0')"
    out = []
    for k, part in enumerate(p.strip() for p in str(text).split(";") if p.strip()):
        day, sep, regions = part.partition(":")
        names = tuple(r.strip() for r in regions.split(",") if r.strip())
        if not sep or not day.strip().isdigit() or not names:
            raise ConfigError("sessions", text, allowed)
        if out and int(day) < out[-1].day:
            raise ConfigError("sessions", text, allowed)
        out.append(SessionPlan(k, int(day), names))
    if not out:
        raise ConfigError("sessions", text, allowed)
    return tuple(out)


def office_values(scenario: Mapping[str, Any]) -> dict[str, Any]:
    """The office part of a validated scenario (the track's own rows dropped)."""
    return {k: v for k, v in scenario.items() if k not in EXTRA}


def session_scenario(scenario: Mapping[str, Any], plan: SessionPlan) -> Any:
    """The office walk of one session: the office of its day, walked through its regions. A
    drawn script (``change_seed``) of day 0 is the office as furnished (it draws nothing)."""
    values = {**office_values(scenario), "day": plan.day, "route_regions": ",".join(plan.regions)}
    if plan.day == 0 and int(values.get("change_seed", -1)) >= 0:
        values["change_seed"] = -1
    return scenario_class().from_dict(values)


def scenario_class() -> type:
    """The office walk's scenario with the office's size as rows (the loop-closure track's:
    ``n_offices``, ``corridor_length_m``, ``room_depth_m``, ``meeting_room_m``)."""
    from ..loop_closure.track import _scenario_class

    return _scenario_class()


def check_sessions(scenario: Mapping[str, Any]) -> None:
    """Every session's walk planned (regions known and reachable that day) and the change script
    of the last day validated, before anything runs."""
    from exobench.envs.sim.scenario import check_scenario

    for plan in parse_sessions(scenario["sessions"]):
        check_scenario(session_scenario(scenario, plan))


def session_rig(scenario: Mapping[str, Any]) -> tuple[Any, ...]:
    """The camera rig of every session: IMU, odometry (its drift rows), RGB-D at 424 x 240 (ties in
    that order)."""
    from exobench.envs.sensors import RgbdConfig
    from exobench.envs.sensors.odometry.config import OdometryConfig
    from exobench.envs.sim.rig import camera_rig

    rate = float(scenario["frame_rate_hz"])
    return camera_rig(str(scenario["camera"]), RgbdConfig(width_px=424, height_px=240, rate_hz=rate),
                      odometry=OdometryConfig(rate_hz=rate, drift_pct=float(scenario["odom_drift_pct"]),
                                              yaw_drift_deg_per_m=float(scenario["odom_yaw_drift_deg_per_m"])))  # fmt: skip


@lru_cache(maxsize=4)
def _regions(office: Any) -> tuple[tuple[str, tuple[float, float, float, float]], ...]:
    from exobench.models.office_layout import build_layout

    return tuple((r["kind"], tuple(r["rect"])) for r in build_layout(office).regions)


def place_kind(office: Any, x: float, y: float) -> str:
    """The kind of the region holding (x, y), ``""`` in none (a doorway)."""
    for kind, (x0, x1, y0, y1) in _regions(office):
        if x0 <= x <= x1 and y0 <= y <= y1:
            return kind
    return ""


def _shifted(frame: Any, dt: float) -> Any:
    return dataclasses.replace(frame, stamp_s=float(frame.stamp_s) + dt)


def stream_sessions(scenario: Mapping[str, Any], seed: int, *, whole: bool = False) -> EpisodeStream:
    """The episode of a validated scenario as a stream (module docstring); with ``whole`` each
    session is recorded whole before its frames are handed out (``simulate``: the office's
    ``record``, as every world's ``simulate_*`` does)."""
    from exobench.envs.sim import scenarios
    from exobench.envs.sim.calibration import build_calibration
    from exobench.envs.sim.pose import pose_rows
    from exobench.envs.sim.recorder import TRACKED_BODIES, stream_record
    from exobench.envs.sim.scenarios.office import plan_office_walk

    plans = parse_sessions(scenario["sessions"])
    rig = session_rig(scenario)
    cam = next(s.sensor_id for s in rig if s.kind == "rgbd")
    odom = next(s.sensor_id for s in rig if s.kind == "odometry")
    first = session_scenario(scenario, plans[0])
    calibration = build_calibration(first.exo_spec(), rig)
    kept: list[dict[str, Any]] = []
    last: dict[str, Any] = {}

    def session_frames(plan: SessionPlan, offset: float) -> Iterator[Any]:
        office = session_scenario(scenario, plan)
        scene, motion = plan_office_walk(office, rig)
        args = (scene.model, scene.truth, office.exo_spec(), motion, rig, int(seed) * 1000 + plan.session)
        if whole:
            rec = scenarios.office.record(*args, track_bodies=TRACKED_BODIES)
            items: Iterator[tuple[Any, Any]] = ((f, None) for f in rec.frames)
            truth = rec.outputs[odom].truth
        else:
            srec = stream_record(*args, track_bodies=TRACKED_BODIES)
            items = srec.items()
            truth = srec.small.outputs[odom].truth  # the odometry's instants are the camera's
        t_cam, T_cam = np.asarray(truth["t_s"], dtype=float), np.asarray(truth["T_world_tracked"], dtype=float)
        kept.append({"session": plan.session, "day": plan.day, "camera_w": pose_rows(t_cam + offset, T_cam),
                     "T_world_odom": np.asarray(truth["T_world_odom"], dtype=float)})  # fmt: skip
        labels = _labels(scenario, office.office_params(), T_cam, seed, plan.session)
        yield SessionStart(offset, "session", plan.session, plan.day)
        for f, _ in items:
            if isinstance(f, RgbdFrame):  # the label of the camera instant nearest in time
                k = int(np.argmin(np.abs(t_cam - float(f.stamp_s))))
                yield PlaceLabel(float(f.stamp_s) + offset, "place_label", labels[k])
            yield _shifted(f, offset)
        last.update(office=office, duration=float(motion.duration_s), scene=scene.truth)

    def frames() -> Iterator[Any]:
        offset = 0.0
        for plan in plans:
            yield from session_frames(plan, offset)
            offset += last["duration"] + GAP_S

    def finish() -> Episode:
        sessions = tuple(kept)
        T_world_est = sessions[0]["T_world_odom"] if sessions else np.eye(4)
        extra = {"sessions": sessions, "camera": cam, "odometry": odom,
                 **world_truth(scenario, sessions, camera_reach_m(calibration, cam))}
        ep_truth = EpisodeTruth(scene=last["scene"], T_world_estimator=T_world_est, extra=extra)
        return Episode(dict(scenario), int(seed), calibration, (), ep_truth)

    return EpisodeStream(dict(scenario), int(seed), calibration, frames(), finish)


def _labels(scenario: Mapping[str, Any], office: Any, T_cam: np.ndarray, seed: int, session: int) -> list[str]:
    """The place label of each camera instant, ``place_label_error_fraction`` of them wrong
    (another region kind of the building, drawn with the run seed and the session)."""
    true = [PlaceLabel(0.0, "place_label", place_kind(office, float(T[0, 3]), float(T[1, 3]))) for T in T_cam]
    fraction = float(scenario.get("place_label_error_fraction", 0.0))
    kinds = sorted({k for k, _ in _regions(office)})
    given = swap_place_labels(true, fraction, int(seed) * 1009 + session, kinds) if fraction > 0 else true
    return [f.label for f in given]  # type: ignore[union-attr]


def on_objects(geoms: Sequence[str], objects: Sequence[Any]) -> np.ndarray:
    """Whether each change sample lies on one of the changed objects (its geoms are
    ``<object id>_<part>``), not on a static surface whose exposure the object changed."""
    prefixes = tuple(f"{o.object_id}_" for o in objects)
    return np.array([bool(prefixes) and g.startswith(prefixes) for g in geoms], dtype=bool)


def camera_reach_m(calibration: Any, camera: str) -> float:
    """The farthest a point of ``camera`` (its mount in ``calibration``) can lie from the camera:
    the largest depth it can report (:func:`exobench.core.limits.max_depth_m`) along the ray
    through the outer corner of its image, the longest. 9.1 m for the 424 x 240 thigh camera
    (6 m depth, 90 x 59 deg). The true surfaces are sampled this far around the walks: a map
    point's error is its distance to the nearest true sample, so a surface the camera saw and
    the truth left out would charge every point on it with the distance to the sampled part
    (docs/tracks/multisession.md)."""
    from exobench.core.limits import max_depth_m

    mount = next(m for m in calibration.mounts_of_kind("rgbd") if m.sensor_id == camera)
    p = mount.params
    w, h = float(p["width_px"]), float(p["height_px"])
    fx, fy, cx, cy = (float(p[k]) for k in ("fx_px", "fy_px", "cx_px", "cy_px"))
    du = max(cx + 0.5, w - 0.5 - cx) / fx  # pixel edges, not centres
    dv = max(cy + 0.5, h - 0.5 - cy) / fy
    return max_depth_m(mount) * float(np.sqrt(1.0 + du * du + dv * dv))


def world_truth(scenario: Mapping[str, Any], sessions: tuple[dict[str, Any], ...], reach_m: float) -> dict[str, Any]:
    """Change truth of every day after the first session's and the true surfaces of the days
    walked within ``reach_m`` (:func:`camera_reach_m`) of every camera position of the walks
    (the bounding box of the positions grown by it)."""
    from exobench.envs.sim.scenarios.office import _change_script
    from exobench.models.office_change_truth import change_truth, surface_samples

    plans = parse_sessions(scenario["sessions"])
    office = session_scenario(scenario, plans[-1])
    params = office.office_params()
    last_day = plans[-1].day
    script = None if last_day == 0 else _change_script(params, office.changes, office.change_seed, last_day)
    changes: dict[int, dict[str, Any]] = {}
    if script is not None:
        for d in change_truth(params, script, last_day).days:
            changes[d.day] = {"appeared": d.appeared, "disappeared": d.disappeared,
                              "appeared_on_object": on_objects(d.appeared_geoms, d.objects),
                              "disappeared_on_object": on_objects(d.disappeared_geoms, d.objects),
                              "objects": [(o.object_id, o.cls, o.kind) for o in d.objects]}  # fmt: skip
    pos = np.concatenate([s["camera_w"][:, 1:4] for s in sessions]) if sessions else np.zeros((1, 3))
    region = np.array([pos.min(axis=0) - reach_m, pos.max(axis=0) + reach_m])
    surface = surface_samples(params, script, last_day, SURFACE_SPACING_M, region)
    surfaces_by_day = {last_day: surface}
    for d in {p.day for p in plans} - {last_day}:
        surfaces_by_day[d] = surface_samples(params, script, d, SURFACE_SPACING_M, region)
    return {"changes": changes, "surface_last_day": surface, "surfaces_by_day": surfaces_by_day}
