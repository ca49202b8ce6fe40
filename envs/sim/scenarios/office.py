"""The office world: a stop-and-go walk along an office route with a trunk LiDAR, IMU, encoders
and insoles (the LiDAR tracks).

:class:`OfficeScenario` is generated from :data:`PARAMS`; :func:`simulate_office` builds the
office (:func:`exobench.models.office.build_office`), plans a walk along the office route
(:func:`exobench.envs.motion.plan_walk`) cut to ``max_distance_m``, and records the rig
(:meth:`OfficeScenario.rig`: encoders, trunk IMU, insoles, ``lidar_trunk``; ties in that order;
``extra_sensors`` or the ``rig`` argument add an RGB-D camera or other sensors). LiDAR sweeps:
see :mod:`exobench.envs.sensors.lidar.adapter` (sensor pose exact, rigid with the pelvis; the
legs and head frozen at mid-sweep).

Truth: one ``LidarTruth`` per scan (``EpisodeTruth.lidar``; compacted to labels with
``lidar_truth="labels"``), the sensor pose at each scan's true start (``trajectory_w``; the
``lidar_*`` faults may shift or repeat the scans' stamps, see
:mod:`exobench.envs.sensors.lidar.faults`), link tracks at
50 Hz (plus the ``lidar_trunk`` pose) and the deepest foot penetration; ``T_world_estimator`` is
the LiDAR pose at t = 0. A camera on the rig adds its optical-frame poses
(``body_tracks[<camera>]``, ``extra["camera_T_world"]``, ``extra["camera_stamps_s"]``), its IMU
its pose at every IMU sample (``body_tracks[<imu>]``).

Route handling: the office routes turn by 90 and 180 degrees at corners and doors; the planner
tracks its progress monotonically along the polyline (the loop passes corridors twice) and walks
up to every corner sharper than 45 deg and turns there on the spot, ``max_turn_deg`` per step.
Waypoints closer than :data:`MIN_SEGMENT_M` to the previous kept one are dropped, and the
polyline is cut at ``max_distance_m``. The walker starts facing the first segment; a closed route
(the whole ``"loop"``, not cut) ends with a turn on the spot to that heading, so the final pose
equals the start pose (up to the feet's placement, a few cm) as the thesis' TE / OE / TVE
protocol assumes (seeds/003 section 5.2.2).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from functools import lru_cache
from typing import Any

import numpy as np

from exobench.core import ConfigError, Episode, EpisodeTruth, UnknownNameError, compact_truth
from exobench.core.episode import EpisodeStream
from exobench.models.exo_spec import ExoSpec
from exobench.models.furniture_kinds import FURNISHINGS
from exobench.models.office_changes import MAX_DAY
from exobench.models.office_params import FACADE_GLASSES, FACADES
from exobench.models.vision_look import WorldLook
from exobench.models.world_params import ParamSpec

from ...motion import GaitError, Motion, Route, plan_walk
from ...sensors import (
    ContactConfig,
    EncoderConfig,
    ImuConfig,
    LidarConfig,
    LidarPattern,
    SensorsConfig,
    sample_times,
)
from ...sensors.adapter import MountedSensor
from ..calibration import build_calibration
from ..compose import CHEST_CAMERA, attached_sites, compose_rig
from ..pose import pose_rows
from ..recorder import TRACK_RATE_HZ, TRACKED_BODIES, record, stream_record
from ..rig import LIDAR_TRUNK, Rig, scalar_rig, segmentation_truths, with_presets, with_segmentation_truth
from ..scenario import scenario_base
from .common import COMMON_PARAMS

LIDAR_ID = LIDAR_TRUNK
PENETRATION_RATE_HZ = 1000.0
MIN_SEGMENT_M = 0.3  # shorter route segments are merged into the next one
LIDAR_PATTERNS = ("vlp16", "vlp32", "ouster64", "livox")
ROUTES = ("loop", "ring", "corridor")
LIDAR_TRUTHS = ("full", "labels")
LIDAR_MOUNTS = ("mast", "pelvis")
RETURN_MODES = ("sampled", "strongest", "last")

PARAMS: dict[str, ParamSpec] = {
    "office_seed": ParamSpec(0, 0, 2**31 - 1, "", "random seed of the office layout (and of its panes' shapes)",
                             feeds=("office.seed", "lidar.glass_shape_seed")),
    "n_offices": ParamSpec(3, 1, 9, "", "cellular offices along the north corridor (at most 9 fit its 24 m)",
                           feeds=("office.n_offices",)),
    "glass_fraction": ParamSpec(0.4, 0.0, 1.0, "", "share of corridor partitions that are glass (the meeting room's south one first)",
                                feeds=("office.glass_fraction",)),
    "polished_fraction": ParamSpec(0.3, 0.0, 1.0, "", "share of floor areas that are polished stone (the south corridor first)",
                                   feeds=("office.polished_fraction",)),
    "facade": ParamSpec("plain", None, None, "", "exterior walls along the corridors: plain, a row of windows "
                        "(windows) or glazing from the floor between slim mullions (curtain), against a dark outside "
                        "(models.office: a window-lined building)", choices=FACADES, feeds=("office.facade",)),
    "facade_glass": ParamSpec("glass", None, None, "", "material of the exterior windows (glass; float_glass, lowe_glass: "
                              "Fresnel reflectance rising towards grazing incidence; igu_float, igu_lowe: double-glazed "
                              "units of them and a float pane; models.materials)", choices=FACADE_GLASSES,
                              feeds=("office.facade_glass",)),
    "partition_glass": ParamSpec("glass", None, None, "", "material of the glass partitions and glass doors (as "
                                 "facade_glass)", choices=FACADE_GLASSES, feeds=("office.partition_glass",)),
    "glass_bow_mm_per_m": ParamSpec(0.0, 0.0, 20.0, "mm/m", "overall bow of every glass pane, centre deflection per metre "
                                    "of its diagonal (0: flat; EN 12150-1 allows 3 for toughened float glass, models.materials)",
                                    feeds=("lidar.glass_bow_mm_per_m",)),
    "glass_roller_wave_mm": ParamSpec(0.0, 0.0, 5.0, "mm", "roller wave of every glass pane, peak-to-valley (0: none; "
                                      "toughened glass, models.materials)", feeds=("lidar.glass_roller_wave_mm",)),
    "furniture_seed": ParamSpec(-1, -1, 2**31 - 1, "", "random seed of the furniture layer (-1: drawn from "
                                "office_seed, as always)", feeds=("office.furniture_seed",)),
    "furnish": ParamSpec("office", None, None, "", "office (desks, chairs, ...), lab (benches, stools, steel "
                         "shelving) or mixed (offices in the west half, labs in the east half; "
                         "models.furniture_kinds)", choices=FURNISHINGS, feeds=("office.furnish",)),
    "repeated_rooms": ParamSpec(0, 0, 3, "", "the first this-many offices are the same room: width, door, "
                                "partition and furniture (perceptual aliasing; 0: none, else 2..n_offices; at "
                                "most 3, which every office of the suites has)",
                                feeds=("office.repeated_rooms",)),
    "day": ParamSpec(0, 0, MAX_DAY, "", "the day the office stands as: the furniture after the changes of days "
                     "1..day of the change script (0: as furnished)"),
    "changes": ParamSpec("", None, None, "", "change script of the furniture (models.office_changes): JSON, or "
                         "'DAY move ID X Y TURN; DAY remove ID; DAY add CLASS/VARIANT ID X Y TURN; DAY obstacle "
                         "CLASS/VARIANT ID X Y TURN'; validated before anything runs"),
    "change_seed": ParamSpec(-1, -1, 2**31 - 1, "", "draw a change script of `day` days from this seed (-1: none; "
                             "not with changes)"),
    "route": ParamSpec("corridor", None, None, "", "office route walked (loop: every office and two laps, "
                       "~130 m; ring: once round the corridor ring back to the start; corridor: the south corridor; "
                       "not used when route_regions is given)", choices=ROUTES),
    "route_regions": ParamSpec("", None, None, "", "regions to walk through in turn instead of route, comma-separated "
                               "(corridor_n, corridor_s, corridor_w, corridor_e, meeting, office0, ...), planned on the "
                               "day's floor round whatever stands there (models.office_routes)"),
    "lidar_truth": ParamSpec("full", None, None, "", "per-point LiDAR truth kept: full, or labels only "
                             "(kind, surface, range; ~8x smaller, for long walks)", choices=LIDAR_TRUTHS),
    "max_distance_m": ParamSpec(20.0, 0.5, 500.0, "m", "the route is cut after this length (keeps quick runs short)"),
    "start_x_m": ParamSpec(-1.0, -1.0, 23.1, "m", "where the walk starts along the north corridor's centre line (-1: "
                           "its west end, as always; else, with route_regions, from half a corridor width to the "
                           "corridor's length less that, at most 23.1 m: the default office's east end), so a short "
                           "walk can reach the rooms further east"),
    "step_length_m": ParamSpec(0.35, 0.1, 0.8, "m", "nominal step length"),
    "swing_s": ParamSpec(0.8, 0.3, 5.0, "s", "duration of one swing"),
    "max_turn_deg": ParamSpec(30.0, 5.0, 60.0, "deg", "largest heading change per step (sharper corners are turned on the spot over several steps)"),
    "start_lean_deg": ParamSpec(0.0, -5.0, 10.0, "deg", "forward trunk lean while standing at the start (0: upright, the walking "
                                "lean of 2 deg taken up during the first step)"),
    "lidar": ParamSpec("vlp16", None, None, "", "LiDAR scan pattern", choices=LIDAR_PATTERNS),
    "lidar_mount": ParamSpec("mast", None, None, "", "where the LiDAR sits: mast (on a backpack mast above the head) "
                             "or pelvis (on the front of the pelvis frame at lidar_height_m)", choices=LIDAR_MOUNTS),
    "lidar_height_m": ParamSpec(0.68, 0.4, 1.2, "m", "height above the floor of the pelvis-mounted LiDAR, standing "
                                "(lidar_mount=pelvis; 0.68 m: a VLP-16 on a Unitree B1, the thesis' robot)"),
    "lidar_rate_hz": ParamSpec(10.0, 5.0, 20.0, "Hz", "LiDAR sweeps per second"),
    "lidar_return": ParamSpec("sampled", None, None, "", "echo reported where a pulse splits at glass: sampled "
                              "(one path drawn per beam), strongest (the VLP-16 default) or last", choices=RETURN_MODES,
                              feeds=("lidar.return_mode",)),
    "lidar_noise_m": ParamSpec(0.015, 0.0, 0.1, "m", "LiDAR range noise, standard deviation", feeds=("lidar.range_noise_m",)),
    "lidar_resolution_m": ParamSpec(0.002, 0.0, 0.1, "m", "LiDAR range quantisation (0 = off)", feeds=("lidar.resolution_m",)),
    "lidar_scan_dropout": ParamSpec(0.0, 0.0, 0.9, "", "probability a LiDAR sweep is lost", feeds=("lidar.dropout_prob",)),
    "lidar_point_dropout": ParamSpec(0.0, 0.0, 0.9, "", "probability a LiDAR return is lost", feeds=("lidar.point_dropout_prob",)),
    "lidar_nan_points": ParamSpec(0.0, 0.0, 1.0, "", "probability a LiDAR return is reported as NaN (its truth kept, kind NAN)",
                                  feeds=("lidar.nan_point_prob",)),
    "lidar_duplicate_scans": ParamSpec(0.0, 0.0, 1.0, "", "probability a LiDAR sweep is delivered twice (same stamp)",
                                       feeds=("lidar.duplicate_prob",)),
    "lidar_out_of_order": ParamSpec(0.0, 0.0, 1.0, "", "probability a LiDAR sweep is delivered after the next one",
                                    feeds=("lidar.out_of_order_prob",)),
    "lidar_time_jump_prob": ParamSpec(0.0, 0.0, 1.0, "", "probability the LiDAR clock steps by lidar_time_jump_s at a sweep "
                                      "(and stays stepped)", feeds=("lidar.time_jump_prob",)),
    "lidar_time_jump_s": ParamSpec(1.0, -10.0, 10.0, "s", "size of one LiDAR clock step (negative: back in time)",
                                   feeds=("lidar.time_jump_s",)),
    "user_height_m": COMMON_PARAMS["user_height_m"],
    "user_mass_kg": COMMON_PARAMS["user_mass_kg"],
    "imu_noise_scale": COMMON_PARAMS["imu_noise_scale"],
    "heel_strike_scale": COMMON_PARAMS["heel_strike_scale"],
    "surfaces": COMMON_PARAMS["surfaces"],
    "light_level": COMMON_PARAMS["light_level"],
    "encoder_noise_rad": COMMON_PARAMS["encoder_noise_rad"],
    "extra_sensors": COMMON_PARAMS["extra_sensors"],
    "segmentation_truth": COMMON_PARAMS["segmentation_truth"],
}  # fmt: skip


class OfficeScenario(scenario_base("OfficeScenario", "office", PARAMS)):  # type: ignore[misc]
    """One office-walk episode; see :data:`PARAMS` for units, ranges and meaning."""

    def exo_spec(self) -> ExoSpec:
        lidar_height_m = self.lidar_height_m if self.lidar_mount == "pelvis" else None
        return ExoSpec(user_height_m=self.user_height_m, user_mass_kg=self.user_mass_kg, lidar_height_m=lidar_height_m)

    def office_params(self) -> object:
        from exobench.models.office import OfficeParams

        return self.configured("office", OfficeParams)

    def lidar_config(self) -> LidarConfig:
        r = self.lidar_rate_hz
        pattern = {
            "vlp16": lambda: LidarPattern.vlp16(r),
            "vlp32": lambda: LidarPattern.vlp32(r),
            "ouster64": lambda: LidarPattern.ouster(64, 1024, r),
            "livox": lambda: LidarPattern.livox_like(rate_hz=r),
        }[self.lidar]()
        return self.configured("lidar", LidarConfig, pattern=pattern)

    def check_composition(self) -> None:
        """The rig (see the base class), the office's parameters, its change script (applied and
        validated) and the route's regions, without building it."""
        super().check_composition()
        self.office_params()
        self.change_script()
        self.start_w()
        for r in self.regions():
            names = _region_names(self.office_params())
            if r not in names:
                raise UnknownNameError("office region (route_regions)", r, names)

    def start_w(self) -> list[float] | None:
        """Where the walk starts when ``start_x_m`` moves it (None: the office's own start);
        ConfigError off the north corridor's centre line."""
        if self.start_x_m < 0:
            return None
        if not self.regions():  # the fixed routes are drawn from the office's own start
            raise ConfigError("start_x_m", self.start_x_m, "-1 unless route_regions is given")
        from exobench.models.office_layout import build_layout

        layout = build_layout(self.office_params())  # type: ignore[arg-type]
        lo, hi = self.office_params().corridor_width_m / 2, layout.routes["ring"][1][0]  # type: ignore[attr-defined]
        if not lo - 1e-9 <= self.start_x_m <= hi + 1e-9:  # the default office's 24 - 0.9 is 23.099999...
            raise ConfigError("start_x_m", self.start_x_m, f"-1 or in [{lo:.2f}, {hi:.2f}] m (the north corridor)")
        return [float(self.start_x_m), *layout.start_w[1:]]

    def regions(self) -> tuple[str, ...]:
        return tuple(r.strip() for r in self.route_regions.split(",") if r.strip())

    def change_script(self) -> object:
        """The furniture's change script (``models.office_changes.ChangeScript``), validated on
        the office; None for the office as furnished (no script, day 0)."""
        if self.change_seed >= 0 and self.day == 0:  # it would draw nothing
            raise ConfigError("change_seed", self.change_seed, "-1 when day is 0 (a script of `day` days is drawn)")
        if not self.changes.strip() and self.change_seed < 0 and self.day == 0:
            return None
        return _change_script(self.office_params(), self.changes, self.change_seed, self.day)

    def rig(self) -> Rig:
        """Encoders, trunk IMU, insoles and the trunk LiDAR, plus ``extra_sensors``."""
        cfg = SensorsConfig(imu=self.configured("imu", ImuConfig), encoders=self.configured("encoders", EncoderConfig),
                            contact=ContactConfig())  # fmt: skip
        base = (*scalar_rig(cfg, tof=False), MountedSensor(LIDAR_ID, "lidar", self.lidar_config()))
        return with_presets(base, self.extra_sensors)

    def route_polyline(self, waypoints: list[tuple[float, float]]) -> tuple[tuple[float, float], ...]:
        """The waypoints walked: the route's, cut at ``max_distance_m`` (:func:`route_waypoints`)."""
        return route_waypoints(waypoints, self.max_distance_m)

    def step_factors(self) -> tuple[float, ...]:
        """Step lengths to plan with, as factors of ``step_length_m``, tried in turn while the
        walker finds no foothold (a doorway at some steps and heights): the step asked for only."""
        return (1.0,)

    def moves_cameras(self) -> bool:
        """Whether the chest camera sits on its turning rig (``chest_yaw``/``chest_pitch``) and
        :meth:`recording_hooks` turn the cameras: not for the LiDAR tracks' office walks, whose
        cameras (``extra_sensors``) stay fixed as before (:mod:`.office_camera` turns them)."""
        return False

    def recording_hooks(self, exo: ExoSpec, motion: Motion, seed: int) -> tuple[Any, ...]:
        """Extra motion of the recording (:class:`~exobench.envs.sim.recorder.Hook`): none here."""
        return ()


@lru_cache(maxsize=8)
def compiled_office(params: object, exo: ExoSpec, sites: tuple[tuple[str, Any], ...] = (), look: WorldLook | None = None,
                    changes: Any = None, day: int = 0, chest_rig: bool = False, start_w: tuple[float, ...] | None = None) -> Any:
    """The composed office world (``models.worlds.CompiledScene``), compiled once per key; ``look``
    (textures drawn from the office's seed, light level) when not the default; with a change
    script, the office of ``day``; the chest camera on its turning rig with ``chest_rig``; the
    walker standing at ``start_w`` instead of the office's start when given (the routes planned
    through regions start there too: they read the truth's ``start_w``)."""
    import dataclasses

    from exobench.models.office import build_office

    built = build_office(params, changes, day)
    if start_w is not None:
        truth = dataclasses.replace(built.truth, params={**built.truth.params, "start_w": list(start_w)})
        built = dataclasses.replace(built, truth=truth)
    return compose_rig(built, exo, sites, look=look, look_seed=params.seed,  # type: ignore[arg-type, attr-defined]
                       chest_rig=chest_rig)  # fmt: skip


@lru_cache(maxsize=8)
def _region_names(params: object) -> tuple[str, ...]:
    from exobench.models.office_layout import build_layout

    return tuple(r["name"] for r in build_layout(params).regions)  # type: ignore[arg-type]


@lru_cache(maxsize=8)
def _change_script(params: object, changes: str, change_seed: int, day: int) -> Any:
    from exobench.models.office_changes import apply_changes, script_from
    from exobench.models.office_layout import build_layout

    layout = build_layout(params)  # type: ignore[arg-type]
    script = script_from(layout, changes, change_seed, day)
    apply_changes(layout, script, day)  # refused here, before anything runs, if it cannot be applied
    return script


def route_waypoints(waypoints: list[tuple[float, float]], max_distance_m: float) -> tuple[tuple[float, float], ...]:
    """The route's waypoints without stubs shorter than :data:`MIN_SEGMENT_M`, cut at ``max_distance_m``."""
    pts = [np.asarray(waypoints[0], dtype=float)]
    for p in waypoints[1:]:
        q = np.asarray(p, dtype=float)
        if np.linalg.norm(q - pts[-1]) >= MIN_SEGMENT_M:
            pts.append(q)
    if len(pts) < 2:
        raise ConfigError("route", waypoints, f"a route with a segment of at least {MIN_SEGMENT_M} m")
    out, left = [pts[0]], float(max_distance_m)
    for q in pts[1:]:
        d = float(np.linalg.norm(q - out[-1]))
        if d >= left:
            out.append(out[-1] + (q - out[-1]) * (left / d))
            break
        out.append(q)
        left -= d
    return tuple((float(p[0]), float(p[1])) for p in out)


def region_waypoints(scenario: OfficeScenario) -> tuple[tuple[float, float], ...]:
    """The waypoints a scenario with ``route_regions`` walks (:func:`plan_office_walk`'s), planned
    on its day's layout (``models.office_routes.layout_route``) without compiling the office: for
    the walks a draw or a check plans and never simulates."""
    from exobench.models.office_changes import apply_changes
    from exobench.models.office_layout import build_layout
    from exobench.models.office_routes import layout_route

    layout = build_layout(scenario.office_params())  # type: ignore[arg-type]
    script = scenario.change_script()
    if script is not None:
        layout = layout.with_furniture(apply_changes(layout, script, scenario.day)[scenario.day])  # type: ignore[arg-type]
    return scenario.route_polyline(layout_route(layout, scenario.regions(), scenario.start_w()))


def plan_office_walk(scenario: OfficeScenario, rig: Sequence[MountedSensor] = ()) -> tuple[Any, Motion]:
    """(compiled office scene, walking motion) of a scenario, without sensing."""
    from exobench.models.office import office_route

    exo = scenario.exo_spec()
    look = WorldLook(scenario.surfaces, scenario.light_level)
    script = scenario.change_script()
    world: dict[str, Any] = {} if script is None else {"changes": script, "day": scenario.day}
    if scenario.moves_cameras() and any(s.sensor_id == CHEST_CAMERA for s in rig):
        world["chest_rig"] = True
    if scenario.start_w() is not None:
        world["start_w"] = tuple(scenario.start_w())
    scene = compiled_office(scenario.office_params(), exo, attached_sites(rig), None if look.is_default else look, **world)
    if scenario.regions():
        from exobench.models.office_routes import region_route

        wps = scenario.route_polyline(region_route(scene.truth, scenario.regions()))
    else:
        wps = scenario.route_polyline(office_route(scene.truth, scenario.route))
    pts = np.asarray(wps)
    length = float(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1)))
    d0 = pts[1] - pts[0]
    start_yaw = float(np.degrees(np.arctan2(d0[1], d0[0])))
    closed = bool(np.linalg.norm(pts[-1] - pts[0]) < 1e-9)
    turns = np.arctan2(np.diff(pts, axis=0)[:, 1], np.diff(pts, axis=0)[:, 0])
    turning_steps = int(np.sum(np.abs((np.diff(turns) + np.pi) % (2 * np.pi) - np.pi)) / np.radians(scenario.max_turn_deg))
    factors = scenario.step_factors()
    for k, f in enumerate(factors):
        step = scenario.step_length_m * f
        route = Route(
            wps, step_length_m=step, swing_s=scenario.swing_s, max_turn_deg=scenario.max_turn_deg,
            start_yaw_deg=start_yaw, end_yaw_deg=start_yaw if closed else None, start_lean_deg=scenario.start_lean_deg,
            max_steps=min(10000, int(3.0 * length / step) + 2 * turning_steps + 100),
        )  # fmt: skip
        try:
            return scene, plan_walk(exo, scene.truth, route)
        except GaitError:
            if k == len(factors) - 1:
                raise
    raise AssertionError("unreachable: step_factors() is never empty")


def simulate_office(scenario: OfficeScenario, seed: int, rig: Sequence[MountedSensor] | None = None) -> Episode:
    """A walk along the scenario's office route with every sensor of ``rig`` (default
    :meth:`OfficeScenario.rig`; a trunk LiDAR ``lidar_trunk`` is what the LiDAR truth follows)."""
    rig, exo, scene, motion = _office_setup(scenario, rig)
    hooks = scenario.recording_hooks(exo, motion, seed)
    rec = record(scene.model, scene.truth, exo, motion, rig, seed, track_bodies=TRACKED_BODIES, hooks=hooks)
    lidar_truth = rec.frame_truth([s.sensor_id for s in rig if s.kind == "lidar"])
    if scenario.lidar_truth != "full":
        lidar_truth = tuple(compact_truth(t) for t in lidar_truth)
    return _office_episode(scenario, seed, rig, exo, motion, scene.truth, rec, rec.frames, lidar_truth, segmentation_truths(rec, rig))


def stream_office(
    scenario: OfficeScenario, seed: int, rig: Sequence[MountedSensor] | None = None, *, lidar_truth: bool = True,
    lidar_sink: Callable[[Any, Any], None] | None = None,
) -> EpisodeStream:
    """:func:`simulate_office` as a stream (:func:`~exobench.envs.sim.recorder.stream_record`):
    the same frames in the same order, and the same episode at the end without its frames, and
    without the per-point LiDAR truth unless ``lidar_truth`` (it is most of a walk's memory).
    With ``lidar_sink``, each LiDAR scan's truth (compacted as ``scenario.lidar_truth`` says)
    goes to ``lidar_sink(scan, truth)`` just before the scan is handed out, and not into the
    episode: the caller keeps of it what it needs (the harness spools it to disk).
    A LiDAR whose clock may step back cannot stream: then the walk is recorded whole first
    (its episode holds its frames and LiDAR truth, and ``lidar_sink`` is never called)."""
    rig, exo, scene, motion = _office_setup(scenario, rig)
    cal = build_calibration(exo, rig)
    if any(s.kind == "lidar" and s.config.time_jump_prob > 0 and s.config.time_jump_s < 0 for s in rig):
        whole = simulate_office(scenario, seed, rig)
        return EpisodeStream(scenario.as_dict(), int(seed), whole.calibration, iter(whole.frames), lambda: whole)
    hooks = scenario.recording_hooks(exo, motion, seed)
    srec = stream_record(scene.model, scene.truth, exo, motion, rig, seed, track_bodies=TRACKED_BODIES, hooks=hooks)
    lidars = {s.sensor_id for s in rig if s.kind == "lidar"} if lidar_truth or lidar_sink is not None else set()
    cams = {s.sensor_id for s in rig if s.kind == "rgbd" and s.config.segmentation_truth}
    kept_lidar: list[Any] = []
    kept_seg: list[Any] = []
    compact = scenario.lidar_truth != "full"

    def frames() -> Iterator[Any]:
        for f, tr in srec.items():
            if f.sensor_id in lidars:
                t = compact_truth(tr) if compact else tr
                if lidar_sink is not None:
                    lidar_sink(f, t)
                else:
                    kept_lidar.append(t)
            elif f.sensor_id in cams:
                kept_seg.append(tr)
            yield f

    def finish() -> Episode:
        return _office_episode(scenario, seed, rig, exo, motion, scene.truth, srec, (), tuple(kept_lidar), tuple(kept_seg))

    return EpisodeStream(scenario.as_dict(), int(seed), cal, frames(), finish)


def _office_setup(scenario: OfficeScenario, rig: Sequence[MountedSensor] | None) -> tuple[tuple[MountedSensor, ...], ExoSpec, Any, Motion]:
    rig = tuple(scenario.rig() if rig is None else rig)
    if scenario.segmentation_truth:
        rig = with_segmentation_truth(rig)
    exo = scenario.exo_spec()
    scene, motion = plan_office_walk(scenario, rig)
    return rig, exo, scene, motion


def _office_episode(
    scenario: OfficeScenario, seed: int, rig: Sequence[MountedSensor], exo: ExoSpec, motion: Motion, truth: Any, rec: Any,
    frames: Sequence[Any], lidar_truth: Sequence[Any], segmentation: Sequence[Any],
) -> Episode:  # fmt: skip
    """The episode of a recording (``rec``: its ``outputs``' truth, ``body_tracks``, ``context``)."""
    dur = motion.duration_s
    body_tracks = dict(rec.body_tracks)
    t_trk = sample_times(TRACK_RATE_HZ, dur)
    lidars = [s.sensor_id for s in rig if s.kind == "lidar"]
    extra: dict[str, Any] = {}
    T_world_est = np.eye(4)
    trajectory = np.zeros((0, 8))
    if LIDAR_ID in lidars:
        pose_at = rec.context.pose_fn(LIDAR_ID)
        body_tracks[LIDAR_ID] = pose_rows(t_trk, pose_at(t_trk))
        T_world_est = pose_at(np.array([0.0]))[0]
        starts = np.unique(rec.outputs[LIDAR_ID].truth["sweep_start_s"])  # true starts (the stamps may be faulty)
        trajectory = pose_rows(starts, pose_at(starts)) if len(starts) else np.zeros((0, 8))
    for s in rig:
        if s.kind == "rgbd":
            cam = rec.outputs[s.sensor_id].truth
            body_tracks[s.sensor_id] = pose_rows(cam["t_s"], cam["T_world_sensor"])
            extra.setdefault("camera_T_world", cam["T_world_sensor"])
            extra.setdefault("camera_stamps_s", cam["t_s"])
        elif s.kind == "imu" and s.attached_to is not None:  # a camera's IMU: its pose at its own rate
            body_tracks[s.sensor_id] = rec.outputs[s.sensor_id].truth["pose_rows"]
    ep_truth = EpisodeTruth(
        scene=truth,
        T_world_estimator=T_world_est,
        body_tracks=body_tracks,
        max_penetration_m=motion.max_penetration_m(truth, sample_times(PENETRATION_RATE_HZ, dur)),
        events=dict(motion.events),
        lidar=tuple(lidar_truth),
        trajectory_w=trajectory,
        segmentation=tuple(segmentation),
        extra=extra,
    )
    cal = build_calibration(exo, rig)
    return Episode(scenario=scenario.as_dict(), seed=int(seed), calibration=cal, frames=tuple(frames), truth=ep_truth)
