"""Locomotion-mode pipelines (seeds/002) on synthetic streams: analytic depth images of a known
staircase / ramp seen from a camera walking along x, odometry and heel-strike frames."""

from dataclasses import dataclass, replace

import numpy as np
import pytest

from exobench.core import (
    LOCOMOTION_MODES,
    Calibration,
    ConfigError,
    ContactSample,
    LocomotionEstimate,
    OdometrySample,
    RgbdFrame,
    SensorMount,
    UnknownNameError,
)
from exobench.mapping.locomotion import SingleFramePipeline, TerrainReconstructionPipeline
from exobench.perception.terrain.plane_extraction import AhcConfig

pytestmark = pytest.mark.long(seconds=8)  # the workers take it first (tests/conftest.py); 8: the file at -n 0 in one run at load 12-15, scaled to that run's CPU

W, H = 160, 120  # small images keep the test fast; the pipelines are resolution-agnostic
FOVY = np.radians(58.0)
F = 0.5 * H / np.tan(0.5 * FOVY)
K = np.array([[F, 0, 0.5 * (W - 1)], [0, F, 0.5 * (H - 1)], [0, 0, 1.0]])
RATE_HZ = 5.0
STEP_M, STEP_S = 0.30, 0.6  # step length (foot to foot) and duration
CAM_H, PITCH = 1.25, np.radians(55.0)  # chest camera height above the feet, pitch down
HALF_WIDTH = 0.08  # feet beside the path
RISER, TREAD = 0.17, 0.30
RAMP_DEG = 15.8
EDGE = 1.5  # x of the first riser / the foot of the first ramp; feet land at x = 0.15 + 0.3 k


@dataclass(frozen=True)
class Rect:
    """A planar patch for the renderer: normal n through point q, inside the box [lo, hi]."""

    n: np.ndarray
    q: np.ndarray
    lo: np.ndarray
    hi: np.ndarray


def _box(n, q, lo, hi):
    return Rect(np.asarray(n, float) / np.linalg.norm(n), np.asarray(q, float), np.asarray(lo, float),
                np.asarray(hi, float))


@dataclass(frozen=True)
class Segment:
    """A walkable strip x0 <= x <= x1 (2 m wide) of height z0 at x0 rising ``slope_deg`` along +x."""

    x0: float
    x1: float
    z0: float
    slope_deg: float = 0.0

    def z(self, x):
        return self.z0 + np.tan(np.radians(self.slope_deg)) * (x - self.x0)


def stairs_course():
    """LG -> SA -> LG -> SD -> LG: four treads up, a 0.9 m landing, four treads down."""
    segs = [Segment(-3.0, EDGE, 0.0)]
    x = EDGE
    for z in [RISER * k for k in (1, 2, 3, 4)]:
        segs.append(Segment(x, x + TREAD, z))
        x += TREAD
    segs.append(Segment(x, x + 0.9, 5 * RISER))
    x += 0.9
    for z in [RISER * k for k in (4, 3, 2, 1)]:
        segs.append(Segment(x, x + TREAD, z))
        x += TREAD
    segs.append(Segment(x, 9.0, 0.0))
    return segs


def ramp_course():
    """LG -> RA -> LG -> RD -> LG: 1.2 m up at RAMP_DEG, a 0.9 m landing, 1.2 m down."""
    top = 1.2 * np.tan(np.radians(RAMP_DEG))
    return [Segment(-3.0, EDGE, 0.0), Segment(EDGE, EDGE + 1.2, 0.0, RAMP_DEG), Segment(EDGE + 1.2, EDGE + 2.1, top),
            Segment(EDGE + 2.1, EDGE + 3.3, top, -RAMP_DEG), Segment(EDGE + 3.3, 9.0, 0.0)]


def segment_at(segs, x):
    return next(s for s in segs if s.x0 <= x < s.x1)


def height(segs, x):
    return segment_at(segs, x).z(x)


def patches(segs):
    """The course's surfaces: one plane patch per segment, a riser where the height jumps."""
    out = []
    for i, s in enumerate(segs):
        th = np.radians(s.slope_deg)
        z1 = s.z(s.x1)
        out.append(_box([-np.sin(th), 0, np.cos(th)], [s.x0, 0, s.z0], [s.x0, -1, min(s.z0, z1) - 1e-9],
                        [s.x1, 1, max(s.z0, z1) + 1e-9]))
        if i + 1 < len(segs) and abs(segs[i + 1].z0 - z1) > 1e-9:
            lo, hi = sorted((z1, segs[i + 1].z0))
            out.append(_box([-1, 0, 0], [s.x1, 0, 0], [s.x1 - 1e-9, -1, lo], [s.x1 + 1e-9, 1, hi]))
    return out


def true_mode(segs, f_from, f_to):
    """Mode of the step landing at x = f_to: its terrain relative to the one under f_from."""
    land = segment_at(segs, f_to)
    if land.slope_deg != 0.0:
        return "RA" if land.z(f_to) > land.z(f_from) else "RD"
    if segment_at(segs, f_from).slope_deg != 0.0:  # leaving a ramp (as in step_truths)
        return "LG"
    dz = land.z(f_to) - height(segs, f_from)
    return "SA" if dz >= 0.1 else "SD" if dz <= -0.1 else "LG"


def camera_R(heading):
    """R_world_cam of a camera looking along ``heading`` (+1 or -1 along x), pitched down."""
    z = np.array([heading * np.cos(PITCH), 0.0, -np.sin(PITCH)])
    x = np.array([0.0, -heading, 0.0])
    return np.column_stack([x, np.cross(z, x), z])


def render(rects, T_world_cam, rng, noise_m=0.002):
    """Analytic z-depth image (H, W) float32 of the patches; 0 where no surface."""
    u, v = np.meshgrid(np.arange(W), np.arange(H))
    d_cam = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u, float)], axis=-1)
    d = d_cam.reshape(-1, 3) @ T_world_cam[:3, :3].T
    o = T_world_cam[:3, 3]
    best = np.full(d.shape[0], np.inf)
    for r in rects:
        den = d @ r.n
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((r.q - o) @ r.n) / den
        p = o + t[:, None] * d
        ok = (t > 0) & np.all((p >= r.lo - 1e-6) & (p <= r.hi + 1e-6), axis=1)
        best = np.where(ok & (t < best), t, best)
    depth = np.where(np.isfinite(best), best, 0.0)
    depth = depth + (depth > 0) * rng.normal(0.0, noise_m, depth.shape)
    depth[(depth < 0.3) | (depth > 6.0)] = 0.0
    return depth.reshape(H, W).astype(np.float32)


def calibration(sensor="rgbd_chest"):
    mounts = [SensorMount(sensor, "rgbd", "pelvis", np.eye(4), {"rate_hz": RATE_HZ})]
    mounts += [SensorMount(f"contact_{s}_{w}", "contact", f"foot_{s}", np.eye(4), {"side": s, "pad": w})
               for s in "lr" for w in ("heel", "toe")]
    return Calibration("", "pelvis", (), tuple(mounts), 0.1, 0.26, 0.05)


def walk(segs, n_steps, x_start=0.3, heading=1.0, seed=0, odom_id="odom_chest"):
    """Frames of a walk along x: foot k (left for even k) strikes at k * STEP_S at x =
    x_start + heading * STEP_M * (k - 0.5); the camera moves at constant speed between heel
    strikes, midway between the feet at each, CAM_H above their mean height. Odometry and heel
    contacts at 50 Hz, depth at RATE_HZ. Returns (frames, [(strike time, foot x)])."""
    rng = np.random.default_rng(seed)
    rects = patches(segs)

    def foot(k):
        return x_start + heading * STEP_M * (k - 0.5)

    pts = np.array([(STEP_S * k, 0.5 * (foot(k - 1) + foot(k)),
                     CAM_H + 0.5 * (height(segs, foot(k - 1)) + height(segs, foot(k)))) for k in range(n_steps + 1)])
    # the first foot is lifted before it strikes at t = 0
    frames = [ContactSample(-0.02, f"contact_{side}_heel", 0.0, False) for side in "lr"]
    for i in range(int(round(pts[-1, 0] / 0.02)) + 1):
        t = 0.02 * i
        x, z = np.interp(t, pts[:, 0], pts[:, 1]), np.interp(t, pts[:, 0], pts[:, 2])
        j = min(int(t / STEP_S), n_steps - 1)
        v = (pts[j + 1, 1:] - pts[j, 1:]) / STEP_S
        T = np.eye(4)
        T[:3, :3] = camera_R(heading)
        T[:3, 3] = (x, 0.0, z)
        frames.append(OdometrySample(t, odom_id, T, np.array([v[0], 0.0, v[1]])))
        for parity, side in enumerate("lr"):
            phase = t / STEP_S - parity
            in_c = phase >= -1e-9 and (phase - 2 * np.floor(phase / 2 + 1e-9)) < 1.2
            frames.append(ContactSample(t, f"contact_{side}_heel", 300.0 * in_c, bool(in_c)))
        if i % int(round(1 / (0.02 * RATE_HZ))) == 0:
            depth = render(rects, T, rng)
            frames.append(RgbdFrame(t, "rgbd_chest", np.zeros((H, W, 3), np.uint8), depth, K.copy()))
    return frames, [(STEP_S * k, foot(k)) for k in range(n_steps + 1)]


def run(pipe, frames, cal=None):
    pipe.reset(cal or calibration())
    for f in frames:
        pipe.process(f)
    return pipe.finalize()


def expected(est: LocomotionEstimate, strikes, segs):
    """(prediction, true mode of the next step) for each prediction with a footprint: after
    strike n-1 (strike_index n) the next foot lands at strikes[n], coming from its own last
    footprint strikes[n-2] (the mode of a step is the swinging foot's change of terrain, as in
    the track's truth, envs/sim/scenarios/course_world.step_truths)."""
    out = []
    for p in est.predictions:
        n = p.strike_index
        if 3 <= n < len(strikes):
            out.append((p, true_mode(segs, strikes[n - 2][1], strikes[n][1])))
    return out


def last_before_strike(pairs):
    """The last prediction before each heel strike (the paper's prediction of that step)."""
    by_n = {}
    for p, m in pairs:
        by_n[p.strike_index] = (p, m)
    return [by_n[n] for n in sorted(by_n)]


AHC = AhcConfig(min_support_px=150)  # [34]'s 800 px is for 640x480; these images are 160x120
# the synthetic walker's camera is midway between the feet at each heel strike (walk()): the foot
# that strikes is half a step ahead of it
GAIT = dict(lead_fraction=0.5, foot_lead_m=0.0)
TR_CFG = TerrainReconstructionPipeline.Config(ahc=AHC, **GAIT)
SF_CFG = SingleFramePipeline.Config(ahc=AHC, **GAIT)
N_STEPS = 18


@pytest.fixture(scope="module")
def stairs_walk():
    segs = stairs_course()
    return segs, *walk(segs, N_STEPS)


@pytest.fixture(scope="module")
def ramp_walk():
    segs = ramp_course()
    return segs, *walk(segs, N_STEPS)


def check_modes(est, strikes, segs, wanted):
    pairs = expected(est, strikes, segs)
    steps = last_before_strike(pairs)
    assert len(steps) == N_STEPS - 2  # predictions after strikes 3 .. N_STEPS-1 (strike_index 3 .. 17)
    assert {m for _, m in steps} == wanted  # the course exercises these modes
    assert [p.mode for p, _ in steps] == [m for _, m in steps]
    assert all(p.status == "ok" for p, _ in steps)
    # every prediction, not only the last of each step, once the course is in view
    assert np.mean([p.mode == m for p, m in pairs]) >= 0.95
    look = est.stats["lookup_m"]  # the terrain is looked up under the foot's middle (walking along +x)
    z = np.array([p.footprint_odom[2] for p, _ in pairs])
    assert np.mean(np.isfinite(z)) >= 0.9  # a plane under the foot (else the mode was extrapolated)
    for p, _ in pairs:  # the footprint lands on the true terrain
        if np.isfinite(p.footprint_odom[2]):
            assert abs(p.footprint_odom[2] - height(segs, p.footprint_odom[0] + look)) < 0.05


@pytest.mark.parametrize("cls,cfg", [(TerrainReconstructionPipeline, TR_CFG), (SingleFramePipeline, SF_CFG)])
def test_stairs_course_modes(stairs_walk, cls, cfg):
    segs, frames, strikes = stairs_walk
    est = run(cls(cfg), frames)
    assert est.counts["rgbd"].used == len([f for f in frames if isinstance(f, RgbdFrame)])
    assert len(est.predictions) == est.counts["rgbd"].used
    assert all(p.mode in LOCOMOTION_MODES + ("",) for p in est.predictions)
    assert est.stats["n_heel_strikes"] == N_STEPS + 1
    check_modes(est, strikes, segs, {"LG", "SA", "SD"})
    if cls is TerrainReconstructionPipeline:  # the map keeps the treads: stairs in the final plane set
        assert sum(p["kind"] == "stairs" for p in est.planes) >= 8


@pytest.mark.parametrize("cls,cfg", [(TerrainReconstructionPipeline, TR_CFG), (SingleFramePipeline, SF_CFG)])
def test_ramp_course_modes(ramp_walk, cls, cfg):
    segs, frames, strikes = ramp_walk
    est = run(cls(cfg), frames)
    check_modes(est, strikes, segs, {"LG", "RA", "RD"})


def test_predictions_are_deterministic(stairs_walk):
    segs, frames, strikes = stairs_walk
    short = [f for f in frames if f.stamp_s <= 4.2]
    a = run(TerrainReconstructionPipeline(TR_CFG), short)
    b = run(TerrainReconstructionPipeline(TR_CFG), short)
    key = [(p.stamp_s, p.mode, p.strike_index, p.status) for p in a.predictions]
    assert key == [(p.stamp_s, p.mode, p.strike_index, p.status) for p in b.predictions]
    assert {m for _, m, _, _ in key} >= {"LG", "SA"}
    np.testing.assert_array_equal([p.footprint_odom for p in a.predictions], [p.footprint_odom for p in b.predictions])
    assert [(d["id"], d["kind"], d["score"], tuple(d["centroid"])) for d in a.planes] == \
        [(d["id"], d["kind"], d["score"], tuple(d["centroid"])) for d in b.planes]
    assert all(np.isfinite(p.latency_s) and p.latency_s >= 0 for p in a.predictions)


def _replace(frame, **kw):
    return RgbdFrame(frame.stamp_s, frame.sensor_id, frame.rgb, kw.get("depth_m", frame.depth_m), kw.get("K", frame.K))


@pytest.mark.parametrize("cls,cfg", [(TerrainReconstructionPipeline, TR_CFG), (SingleFramePipeline, SF_CFG)])
def test_faulty_frames_keep_the_state_and_are_reported(stairs_walk, cls, cfg):
    segs, frames, strikes = stairs_walk
    rgbd_t = [f.stamp_s for f in frames if isinstance(f, RgbdFrame)]
    sky = set(rgbd_t[20:23])  # all-invalid depth (the sky, a covered lens)
    nan_t = rgbd_t[25]  # NaN depth
    bad_t = rgbd_t[27]  # malformed: 1-D depth
    no_k_t = rgbd_t[28]  # malformed: no intrinsics
    wall_t = rgbd_t[29]  # a wall 0.6 m in front of the lens: a plane, no walkable terrain
    dropped = set(rgbd_t[31:33]) | {rgbd_t[36]}  # three frames lost
    no_odo = (rgbd_t[40] - 0.3, rgbd_t[41] + 0.05)  # odometry lost for 0.55 s between two heel strikes
    faulty = []
    for f in frames:
        if isinstance(f, RgbdFrame):
            if f.stamp_s in dropped:
                continue
            if f.stamp_s in sky:
                f = _replace(f, depth_m=np.zeros_like(f.depth_m))
            elif f.stamp_s == nan_t:
                f = _replace(f, depth_m=np.full_like(f.depth_m, np.nan))
            elif f.stamp_s == bad_t:
                f = _replace(f, depth_m=f.depth_m[0])
            elif f.stamp_s == no_k_t:
                f = RgbdFrame(f.stamp_s, f.sensor_id, f.rgb, f.depth_m, None)
            elif f.stamp_s == wall_t:
                f = _replace(f, depth_m=np.full_like(f.depth_m, 0.6))
        elif isinstance(f, OdometrySample) and no_odo[0] <= f.stamp_s <= no_odo[1]:
            continue
        faulty.append(f)
        if isinstance(f, OdometrySample) and f.stamp_s == rgbd_t[10]:  # a corrupt pose after a good one
            faulty.append(OdometrySample(f.stamp_s + 1e-3, f.sensor_id, np.full((4, 4), np.nan), f.v_odom_m_s))
    est = run(cls(cfg), faulty)
    by_t = {p.stamp_s: p for p in est.predictions}
    assert len(est.predictions) == len(rgbd_t) - len(dropped)
    assert [by_t[t].status for t in sorted(sky)] == ["no_depth"] * 3
    assert by_t[nan_t].status == "no_depth" and by_t[bad_t].status == by_t[no_k_t].status == "bad_frame"
    assert by_t[rgbd_t[40]].status == by_t[rgbd_t[41]].status == "no_odometry"
    st = est.stats
    assert (st["n_no_depth"], st["n_bad_frame"], st["n_no_odometry"], est.counts["rgbd"].dropped) == (4, 2, 2, 3)
    assert est.counts["odometry"].nan == 1 and st["n_errors"] == 0
    assert st["n_strikes_without_odometry"] == 0  # no heel strike fell in the gap
    # the kept state still predicts: every step decided on a good frame is right, and most overall
    steps = last_before_strike(expected(est, strikes, segs))
    assert all(p.mode == m for p, m in steps if p.status == "ok")
    assert np.mean([p.mode == m for p, m in steps]) >= 0.8


def test_missing_odometry_everywhere_never_crashes(stairs_walk):
    segs, frames, strikes = stairs_walk
    short = [f for f in frames if f.stamp_s <= 3.0 and not isinstance(f, OdometrySample)]
    for cls, cfg in ((TerrainReconstructionPipeline, TR_CFG), (SingleFramePipeline, SF_CFG)):
        est = run(cls(cfg), short)
        assert est.predictions and all(p.status == "no_odometry" and p.mode == "" for p in est.predictions)
        assert all(np.all(np.isnan(p.footprint_odom)) for p in est.predictions)
        assert est.stats["n_heel_strikes"] == 0 and est.stats["n_strikes_without_odometry"] == 6  # 0, 0.6, ..., 3 s
        assert est.stats["n_initial_contacts"] == 0
        assert est.planes == ()


def test_odometry_of_a_calibrated_body_and_sensor_selection(stairs_walk):
    """An odometry body mounted on the camera's link: the camera pose is composed with the mounts;
    frames of other cameras and unknown sensors are ignored; the result equals the camera-tracking run."""
    segs, frames, strikes = stairs_walk
    short = [f for f in frames if f.stamp_s <= 6.0]
    T_pelvis_cam = np.eye(4)
    T_pelvis_cam[:3, 3] = (0.14, 0.0, 0.4)
    T_pelvis_odom = T_pelvis_cam.copy()  # an IMU in the camera's housing, axes turned
    T_pelvis_odom[:3, :3] = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    T_body_cam = np.linalg.inv(T_pelvis_odom) @ T_pelvis_cam
    cal = calibration()
    mounts = (SensorMount("rgbd_head", "rgbd", "head", np.eye(4), {"rate_hz": RATE_HZ}),
              SensorMount("rgbd_chest", "rgbd", "pelvis", T_pelvis_cam, {"rate_hz": RATE_HZ}),
              SensorMount("odom_chest", "odometry", "pelvis", T_pelvis_odom, {}), *cal.mounts[1:])
    cal2 = Calibration("", "pelvis", (), mounts, 0.1, 0.26, 0.05)
    moved = []
    for f in short:
        if isinstance(f, OdometrySample):
            T_body = f.T_odom_body @ np.linalg.inv(T_body_cam)  # same origin: same velocity
            f = OdometrySample(f.stamp_s, f.sensor_id, T_body, f.v_odom_m_s)
            moved.append(OdometrySample(f.stamp_s, "odom_head", np.eye(4), np.zeros(3)))  # another tracker
        elif isinstance(f, RgbdFrame):
            moved.append(RgbdFrame(f.stamp_s, "rgbd_head", f.rgb, np.zeros_like(f.depth_m), f.K))  # other camera
        moved.append(f)
    ref = run(SingleFramePipeline(SF_CFG), short)
    est = run(SingleFramePipeline(SingleFramePipeline.Config(ahc=AHC, rgbd_sensor_id="rgbd_chest", **GAIT)), moved, cal2)
    assert est.stats["odometry_mount"] == "calibrated"
    assert [p.mode for p in est.predictions] == [p.mode for p in ref.predictions]
    np.testing.assert_allclose([p.footprint_odom for p in est.predictions], [p.footprint_odom for p in ref.predictions],
                               atol=1e-9)
    # the default camera is the calibration's first RGB-D mount (rgbd_head here)
    pipe = SingleFramePipeline(SF_CFG)
    pipe.reset(cal2)
    assert pipe.process(moved[0]) is None
    assert pipe.finalize().stats["rgbd_sensor_id"] == "rgbd_head"


def test_processing_rate_and_config_errors(stairs_walk):
    segs, frames, strikes = stairs_walk
    short = [f for f in frames if f.stamp_s <= 3.0]
    n_rgbd = sum(isinstance(f, RgbdFrame) for f in short)
    est = run(SingleFramePipeline(SingleFramePipeline.Config(ahc=AHC, every_k=3, **GAIT)), short)
    assert len(est.predictions) == est.counts["rgbd"].used == -(-n_rgbd // 3)
    assert est.stats["n_skipped_rate"] == n_rgbd - est.counts["rgbd"].used
    assert est.counts["rgbd"].dropped == 0  # skipping by rate is not dropping
    with pytest.raises(ConfigError):
        SingleFramePipeline.Config(every_k=0)
    with pytest.raises(ConfigError):
        TerrainReconstructionPipeline.Config(raycast_downsample=0)
    with pytest.raises(ConfigError):
        SingleFramePipeline.Config(lead_fraction=1.5)
    with pytest.raises(ConfigError):
        SingleFramePipeline.Config(mode_reference="left")
    with pytest.raises(ConfigError):
        SingleFramePipeline.Config(pause_s=0.0)
    with pytest.raises(ConfigError):
        TerrainReconstructionPipeline.Config(upsample_jump_m=-1.0)
    with pytest.raises(UnknownNameError):
        SingleFramePipeline(SingleFramePipeline.Config(rgbd_sensor_id="rgbd_knee")).reset(calibration())


def test_registered():
    from exobench.benchmarks.registry import build_registry

    reg = build_registry(entry_points=False)
    assert reg.load("terrain-recon") is TerrainReconstructionPipeline
    assert reg.load("single-frame") is SingleFramePipeline
    assert {"terrain-recon", "single-frame"} <= set(reg.names("locomotion"))


def test_stop_and_go_walker_direction_from_positions(stairs_walk):
    """Zero velocity at every heel strike (a walker pausing): eq. 18's direction comes from the
    last two heel-strike positions, and the modes stay right."""
    segs, frames, strikes = stairs_walk
    still = [OdometrySample(f.stamp_s, f.sensor_id, f.T_odom_body, np.zeros(3)) if isinstance(f, OdometrySample) else f
             for f in frames]
    est = run(SingleFramePipeline(replace(SF_CFG, direction="velocity")), still)
    assert est.stats["n_direction_from_positions"] > 0
    steps = last_before_strike(expected(est, strikes, segs))
    assert [p.mode for p, _ in steps] == [m for _, m in steps]
    # the default direction (the last stride) never needs the velocity
    est = run(SingleFramePipeline(replace(SF_CFG, direction="stride")), still)
    assert est.stats["n_direction_from_positions"] == 0
    steps = last_before_strike(expected(est, strikes, segs))
    assert [p.mode for p, _ in steps] == [m for _, m in steps]


def test_exoskeleton_calibration():
    """The device's calibration: the head camera by default, its rate, the insole pads (heel and
    toe: a forefoot landing's initial contact is on the toe pad; ``strike_pads="heel"`` ignores it)."""
    from exobench.models.exo import exo_calibration
    from exobench.models.exo_spec import ExoSpec

    pipe = TerrainReconstructionPipeline()
    pipe.reset(exo_calibration(ExoSpec()))
    st = pipe.finalize().stats
    # the bare device has no odometry mount: any odometry stream is taken (no name is guessed from ids)
    assert (st["rgbd_sensor_id"], st["odometry_sensor_id"], st["odometry_mount"]) == ("rgbd_head", "*", "camera")
    assert pipe.process(ContactSample(0.0, "contact_l_heel", 300.0, True)) is None
    assert pipe.process(ContactSample(0.0, "contact_l_toe", 300.0, True)) is None
    est = pipe.finalize()  # standing at the start is not a heel strike
    st, contact = est.stats, est.counts["contact"]
    assert (contact.used, st["n_initial_contacts"], st["n_strikes_without_odometry"], contact.ignored) == (2, 1, 0, 0)
    heel_only = TerrainReconstructionPipeline(replace(TerrainReconstructionPipeline.Config(), strike_pads="heel"))
    heel_only.reset(exo_calibration(ExoSpec()))
    heel_only.process(ContactSample(0.0, "contact_l_toe", 300.0, True))
    assert heel_only.finalize().counts["contact"].ignored == 1
    pipe.process(ContactSample(0.005, "contact_l_toe", 0.0, False))
    pipe.process(ContactSample(0.01, "contact_l_heel", 0.0, False))  # the whole foot off ...
    pipe.process(ContactSample(0.02, "contact_l_heel", 300.0, True))  # ... for 10 ms: chatter, not a strike
    assert (pipe.finalize().stats["n_strikes_without_odometry"], pipe.finalize().stats["n_contact_chatter"]) == (0, 1)
    pipe.process(ContactSample(0.03, "contact_l_heel", 0.0, False))
    pipe.process(ContactSample(0.50, "contact_l_heel", 300.0, True))
    assert pipe.finalize().stats["n_strikes_without_odometry"] == 1


def test_camera_latency_and_named_camera(stairs_walk):
    """Images delivered 0.1 s after capture are posed with the odometry of their capture time; the
    calibration's ``extra["camera"]`` picks the camera among several RGB-D mounts."""
    segs, frames, strikes = stairs_walk
    short = [f for f in frames if f.stamp_s <= 4.2]
    late = sorted((_shift(f, 0.1) if isinstance(f, RgbdFrame) else f for f in short), key=lambda f: f.stamp_s)
    cal = calibration()
    mounts = (SensorMount("rgbd_head", "rgbd", "head", np.eye(4), {"rate_hz": RATE_HZ}),
              SensorMount("rgbd_chest", "rgbd", "pelvis", np.eye(4), {"rate_hz": RATE_HZ, "latency_s": 0.1}),
              *cal.mounts[1:])
    cal_late = Calibration("", "pelvis", (), mounts, 0.1, 0.26, 0.05, extra={"camera": "rgbd_chest"})
    ref = run(SingleFramePipeline(SF_CFG), short)
    est = run(SingleFramePipeline(SF_CFG), late, cal_late)
    assert est.stats["rgbd_sensor_id"] == "rgbd_chest"
    assert [p.stamp_s for p in est.predictions] == [p.stamp_s + 0.1 for p in ref.predictions]
    assert [p.mode for p in est.predictions] == [p.mode for p in ref.predictions]
    np.testing.assert_allclose([p.footprint_odom for p in est.predictions], [p.footprint_odom for p in ref.predictions])


def _shift(f, dt):
    return RgbdFrame(f.stamp_s + dt, f.sensor_id, f.rgb, f.depth_m, f.K)


def test_upsampled_raycast_is_exact_on_planes():
    """upsample_depth: bilinear in 1/z reproduces a plane's full-resolution depth (1/z is affine
    in the pixel coordinates of a plane); across a depth jump it takes the nearest sample."""
    from exobench.mapping.locomotion.depth import scale_intrinsics, upsample_depth

    def plane_depth(Km, w, h, n, d0):
        u, v = np.meshgrid(np.arange(w), np.arange(h))
        ray = np.stack([(u - Km[0, 2]) / Km[0, 0], (v - Km[1, 2]) / Km[1, 1], np.ones((h, w))], axis=-1)
        return (d0 / (ray @ n)).astype(np.float32)  # z-depth of n . p = d0

    n = np.array([0.0, 0.8, 0.6])
    full = plane_depth(K, W, H, n, 1.5)
    half = plane_depth(scale_intrinsics(K, 0.5), W // 2, H // 2, n, 1.5)
    up = upsample_depth(half, 2, (H, W), jump_m=1.0)
    inner = (slice(1, H - 1), slice(1, W - 1))  # the border pixels lie outside the small image's grid
    np.testing.assert_allclose(up[inner], full[inner], rtol=1e-4)
    step = half.copy()
    step[:, W // 4:] += 0.5  # a depth jump: no blend of the two sides
    up = upsample_depth(step, 2, (H, W), jump_m=0.05)
    close = np.zeros_like(full, bool)
    close[inner] = full[inner] < 3.0  # farther, one pixel spans more depth than jump_m: nearest there
    near, far = up[close], full[close]
    assert np.all(np.isclose(near, far, rtol=2e-2) | np.isclose(near, far + 0.5, rtol=2e-2))
    assert np.any(np.isclose(near, far + 0.5, rtol=2e-2)) and np.any(np.isclose(near, far, rtol=2e-2))


def test_mode_refers_to_the_swinging_foot(stairs_walk):
    """At the top of a flight the foot that left the last tread lands on the landing next to the
    other foot: SA relative to its own last footprint (``swing``, the track's definition), LG
    relative to the standing foot (``stance``)."""
    segs, frames, strikes = stairs_walk
    swing = run(TerrainReconstructionPipeline(TR_CFG), frames)
    stance = run(TerrainReconstructionPipeline(TerrainReconstructionPipeline.Config(ahc=AHC, mode_reference="stance",
                                                                                    **GAIT)), frames)
    by_n = {n: (p.mode, q.mode) for (p, _), (q, _) in zip(last_before_strike(expected(swing, strikes, segs)),
                                                           last_before_strike(expected(stance, strikes, segs)))
            for n in [p.strike_index]}
    top = next(n for n in range(3, len(strikes)) if height(segs, strikes[n][1]) == height(segs, strikes[n - 1][1])
               and height(segs, strikes[n][1]) > height(segs, strikes[n - 2][1]) + 0.1)
    assert by_n[top] == ("SA", "LG")


@pytest.mark.parametrize("m_width", [(2, 640), (2, 848), (4, 1280), (1, 424)])
def test_decimated_image_projects_points_where_the_full_one_does(m_width):
    """decimate(): the kept pixel (i, j) of the small image is pixel (m i + off, m j + off) of the
    full one, and the adjusted K projects 3-D points onto it (independent check by projection)."""
    from exobench.mapping.locomotion.depth import decimate

    m, width = m_width
    h = 480
    Kf = np.array([[390.0 * width / 640, 0.0, 0.5 * width - 0.3], [0.0, 390.0 * width / 640, 0.5 * h + 0.7], [0.0, 0.0, 1.0]])
    depth = np.arange(h * width, dtype=np.float32).reshape(h, width)
    small, Ks = decimate(depth, Kf, 424)
    assert small.shape == (len(range(off_ := (m - 1) // 2, h, m)), len(range(off_, width, m)))
    off = (m - 1) // 2
    rng = np.random.default_rng(0)
    for _ in range(20):
        i, j = rng.integers(0, small.shape[0] - 1), rng.integers(0, small.shape[1] - 1)
        v, u = m * i + off, m * j + off
        assert small[i, j] == depth[v, u]
        # a point on the ray of full-image pixel (u, v) projects onto (j, i) with the small K
        p = np.linalg.solve(Kf, [u, v, 1.0]) * 2.3
        q = Ks @ p
        np.testing.assert_allclose(q[:2] / q[2], [j, i], atol=1e-9)


def _nodding_head(frames, rng):
    """``frames`` of walk() with the camera on a head that pitches about the neck: the walk's
    camera position becomes the neck's, the camera sits 0.10 m ahead of and 0.12 m above it
    (looking as walk()'s camera at zero pitch) and the head pitches by 0.35 rad * sin(2 pi t /
    1.3 s) (not in step with the 0.6 s steps); odometry and depth follow the camera. Returns
    (frames, calibration)."""
    T_head_cam = np.eye(4)
    T_head_cam[:3, :3] = camera_R(1.0)
    T_head_cam[:3, 3] = (0.10, 0.0, 0.12)
    rects = patches([Segment(-3.0, 9.0, 0.0)])

    def T_cam(t, neck):
        a = 0.35 * np.sin(2.0 * np.pi * t / 1.3)
        T = np.eye(4)
        T[:3, :3] = [[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]]  # + looks down
        T[:3, 3] = neck
        return T @ T_head_cam

    out, neck = [], {}
    for f in frames:
        if isinstance(f, OdometrySample):
            neck[f.stamp_s] = np.asarray(f.T_odom_body)[:3, 3]
            f = OdometrySample(f.stamp_s, "odom_head", T_cam(f.stamp_s, neck[f.stamp_s]), f.v_odom_m_s)
        elif isinstance(f, RgbdFrame):
            f = RgbdFrame(f.stamp_s, "rgbd_head", f.rgb, render(rects, T_cam(f.stamp_s, neck[f.stamp_s]), rng), f.K)
        out.append(f)
    cal = calibration()
    mounts = (SensorMount("rgbd_head", "rgbd", "head", T_head_cam, {"rate_hz": RATE_HZ}), *cal.mounts[1:])
    return out, Calibration("", "pelvis", (), mounts, 0.1, 0.26, 0.05)


def test_steps_are_measured_at_the_joint_the_camera_turns_about():
    """A nodding head camera (level floor): with ``track_point="joint"`` the steps are measured at
    the neck, the camera's link origin, and each predicted footprint lands where the next foot
    does; measured at the camera itself (``"camera"``) the nods move them by centimetres."""
    segs = [Segment(-3.0, 9.0, 0.0)]
    frames, strikes = walk(segs, 14)
    frames, cal = _nodding_head(frames, np.random.default_rng(3))

    def x_errors(track_point):
        est = run(SingleFramePipeline(SingleFramePipeline.Config(ahc=AHC, track_point=track_point, **GAIT)), frames, cal)
        assert est.stats["tracked_point"] == track_point
        errs = [p.footprint_odom[0] - strikes[p.strike_index][1] for p in est.predictions
                if 6 <= p.strike_index < len(strikes) and np.isfinite(p.footprint_odom[0])]
        assert len(errs) > 20
        return np.abs(errs)

    joint, camera = x_errors("joint"), x_errors("camera")
    assert joint.max() < 0.01
    assert camera.max() > 0.03


def test_tracked_point_and_standing_height_of_the_exoskeleton():
    """On the device's description: a head camera is tracked at its link's origin (the neck, which
    the head pitches about) and a chest camera, on the pelvis (the base link), at itself; the
    tracked point's offset ahead of the pelvis differs between the two choices by the mount's
    forward offset on its link; the standing height of the neck above the soles is the sum of
    the leg's and the trunk's segments of the URDF."""
    import re

    from exobench.models.exo import exo_calibration
    from exobench.models.exo_spec import ExoSpec

    cal = exo_calibration(ExoSpec())

    def stats(**kw):
        pipe = TerrainReconstructionPipeline(TerrainReconstructionPipeline.Config(**kw))
        pipe.reset(cal)
        return pipe.finalize().stats, pipe

    head, pipe = stats()
    cam, _ = stats(track_point="camera")
    chest, _ = stats(rgbd_sensor_id="rgbd_chest")
    assert (head["tracked_point"], cam["tracked_point"], chest["tracked_point"]) == ("joint", "camera", "camera")
    T = np.asarray(cal.mount("rgbd_head").T_parent_sensor)
    assert cam["camera_ahead_m"] - head["camera_ahead_m"] == pytest.approx(T[0, 3], abs=1e-9)
    # neck above the hip + thigh + shank (the URDF's joint origins) + ankle above the sole
    z = {name: float(xyz.split()[2]) for name, xyz in
         re.findall(r'<joint name="([^"]+)"[^>]*>.*?<origin xyz="([^"]+)"', cal.robot_urdf, flags=re.S)}
    want = z["neck_yaw"] + z["neck_pitch"] - z["hip_l"] - z["knee_l"] - z["ankle_l"] + cal.sole_height_m
    assert pipe._standing_h == pytest.approx(want, abs=1e-6)


def test_insole_pads_are_known_by_their_calibration_not_their_ids():
    """A pad is used when its mount says its foot and pad; ids carry no meaning."""
    mounts = (SensorMount("rgbd_chest", "rgbd", "pelvis", np.eye(4), {"rate_hz": RATE_HZ}),
              SensorMount("insole_a", "contact", "foot_l", np.eye(4), {"side": "l", "pad": "heel"}),
              SensorMount("insole_b", "contact", "foot_r", np.eye(4), {"side": "r", "pad": "toe"}))  # fmt: skip
    pipe = TerrainReconstructionPipeline()
    pipe.reset(Calibration("", "pelvis", (), mounts, 0.1, 0.26, 0.05))
    pipe.process(ContactSample(0.0, "insole_a", 300.0, True))
    pipe.process(ContactSample(0.0, "insole_b", 300.0, True))
    pipe.process(ContactSample(0.0, "contact_l_heel", 300.0, True))  # not a pad of this calibration
    contact = pipe.finalize().counts["contact"]
    assert (contact.used, contact.ignored) == (2, 1)
