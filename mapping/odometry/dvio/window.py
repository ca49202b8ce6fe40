"""D-VIO's sliding-window estimator (seeds/002 eq. 6-15) on gtsam's batch fixed-lag smoother.

States per keyframe k (gtsam keys ``x``, ``v``, ``b`` with the keyframe's serial number): the
IMU's pose ``T_GI`` in the gravity-aligned frame G, its velocity and the IMU biases. Factors:

- eq. (7, 9): :func:`.imu.combined_factor` between consecutive keyframes (the bias random walk
  inside it), preintegrated from the raw samples kept for each interval, so a new bias estimate
  re-integrates them (VINS-Mono's ``repropagate``);
- eq. (8, 10): the reprojection of every landmark (an inverse depth ``l``, hosted in the first
  window keyframe that saw it) in every other window keyframe that saw it;
- eq. (11-14): the host and projection depth factors, weighted by the stereo depth noise
  (:class:`.factors.DepthNoise`); off with ``depth_factors=False`` (the ``dvio-no-depth``
  ablation: landmarks are then started by two-view triangulation, not from the depth image);
- both as one factor per host keyframe (:func:`.grouped.host_group_factor`: the residuals of
  :mod:`.factors` evaluated with numpy in one Python callback), replaced as its landmarks gain
  observations;
- eq. (6): the marginalisation prior. gtsam's ``BatchFixedLagSmoother`` (in the installed gtsam
  wheel; ``gtsam_unstable`` is not installed) keeps every key whose timestamp is within the lag
  of the newest and folds the factors of older keys into a ``LinearContainerFactor`` of the
  Schur complement at their linearisation point, which is VINS-Mono's marginalisation. The
  timestamp of a key is its keyframe's serial (a landmark's: its host's), and the lag is
  ``window - 0.5``: adding keyframe n marginalises keyframe ``n - window`` with the landmarks it
  hosts, exactly VINS-Mono's MARGIN_OLD. A feature still seen afterwards is started again as a
  landmark hosted in the oldest window keyframe that saw it (VINS-Mono shifts its depth
  likewise). Non-keyframes never enter the window (motion-only tracking instead, below), so
  VINS-Mono's MARGIN_SECOND_NEW (dropping a non-keyframe newest frame) does not arise.

Gauge: an initialisation's first pose is held in yaw and position; roll and pitch take a weak
prior only (the IMU factors observe gravity). Depth gate: a feature whose host depth does not fit
its other sightings (``depth_gate_px``) keeps its reprojections and loses its depth factors.

Robust kernel: Cauchy of scale 1 on whitened residuals, VINS-Mono's ``CauchyLoss(1.0)`` on its
projection factors (the paper names a robust kernel ``rho`` without saying which).

Non-keyframes (motion-only): the pose is the IMU propagation of the newest window state, refined
by a PnP of the frame's features on the window's landmarks (``cv2.solvePnPRansac`` started at
the propagation), kept only when enough inliers agree. The IMU-rate pose
(:meth:`SlidingWindow.imu_pose`) propagates the newest window state with every sample.

Failure: an optimisation that raises, too few features tracked, a new keyframe that observes
fewer than ``min_landmarks`` of the window's landmarks (checked before the smoother runs: a window
held by the IMU alone is not solvable in double precision, docs/dvio.md "The indeterminate
system"), or a window update whose newest state fails VINS-Mono's ``failureDetection`` adapted to a
walker (:mod:`.failure`: speed, biases, a jump, a vertical jump or a turn since the previous
update; that update is discarded). The window is then cleared; the caller re-initialises
(:mod:`.init`) and the new segment is anchored (position and yaw, its velocities turned with it) on
the last good state (before the failed update) propagated by the IMU through the loss to the first
keyframe of the new initialisation, which also gives the new segment its vertical and gyroscope
bias (on the last good pose's position, with the initialisation's own vertical and bias, when the
loss lasted longer than ``_MAX_DEAD_RECKON_S``; the heading is then still the gyroscope's, carried
through losses of up to ``_MAX_ATTITUDE_S``, else the last good pose's).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import cv2
import gtsam
import numpy as np

from .factors import DepthNoise, Extrinsics, landmark_in_camera
from .failure import REASONS, depth_misfit, diverged, init_refused
from .grouped import HostedLandmark, host_group_factor
from .imu import ImuNoise, ImuPreintegrator, combined_factor
from .init import InitResult, KeyframeObs, initialise
from .window_config import SOLVERS, WindowConfig

__all__ = ["SlidingWindow", "WindowConfig"]

X, V, B, L = (gtsam.symbol_shorthand.X, gtsam.symbol_shorthand.V, gtsam.symbol_shorthand.B,
              gtsam.symbol_shorthand.L)
Sample = tuple[float, np.ndarray, np.ndarray]
# Longest IMU-only propagation a re-initialised segment is anchored on [A]: a walking person's IMU
# with a calibrated bias stays within centimetres for a few seconds.
_MAX_DEAD_RECKON_S = 3.0
# A re-initialisation is checked against the carried vertical only this long into a loss: refused
# any longer, the next segment would start after the propagation's limit, on the last good pose's
# stale position (and, before the carried heading below, its stale yaw: the ring loop, a 3.3 s loss
# at its first corner, 55 deg of yaw; docs/dvio.md).
_MAX_REFUSING_S = _MAX_DEAD_RECKON_S / 2.0
# Longest loss whose gyroscope-propagated attitude still gives a re-initialised segment its heading
# once its position is no longer dead-reckoned [A]: integrated with the last good gyroscope bias,
# whose vertical component the ring loop's windows estimate within 5 mrad/s (95th percentile; the
# simulated IMU's bias stays within 1e-4 rad/s), the heading is off by at most 9 deg after 30 s,
# while the last good pose's is off by whatever the walker turned meanwhile (a corridor corner:
# 90 deg). Yaw is unobservable: a heading left behind at a loss stays in the rest of the walk.
_MAX_ATTITUDE_S = 30.0


@dataclass(eq=False)
class _Keyframe:
    serial: int
    stamp_s: float
    features: dict[int, tuple[np.ndarray, float]]
    samples: list[Sample]  # IMU samples from the previous keyframe to this one (camera clock)
    dead_reckoned: np.ndarray | None = None  # T_G_imu from the last good state, while lost
    dead_reckoned_s: float = math.inf  # how long that state was propagated, s
    carried_R: np.ndarray | None = None  # R_G_imu of that state, while propagated < _MAX_ATTITUDE_S


@dataclass(eq=False)
class _Landmark:
    key: int
    host: int  # serial of the host keyframe
    feature: int  # the tracker's feature id
    obs: set[int] = field(default_factory=set)  # serials with factors in the graph (host included)
    u_host: np.ndarray = field(default_factory=lambda: np.zeros(2))
    d_host: float = math.nan
    observations: list[tuple[int, np.ndarray, float]] = field(default_factory=list)  # (pose key, u, depth)


@dataclass(eq=False)
class _Group:
    """The smoother's factor of the landmarks one keyframe hosts (:func:`.grouped.host_group_factor`)
    and its index in the smoother's graph (None until the update that adds it has run)."""

    factor: gtsam.CustomFactor
    index: int | None = None


class SlidingWindow:
    """The estimator: :meth:`add_imu` for every sample, :meth:`add_frame` for every frame (features
    on the normalised plane with their depths); see the module docstring."""

    def __init__(self, config: WindowConfig, ext: Extrinsics, imu: ImuNoise, depth: DepthNoise,
                 focal_px: float) -> None:
        self.config, self.ext, self.imu, self.depth = config, ext, imu, depth
        self.sigma = config.pixel_sigma_px / focal_px
        self._focal_px = focal_px
        # Features whose depths disagreed with their reprojections (depth_gate_px): no depth
        # factor ever again (the glass stays in front of them).
        self._depth_off: set[int] = set()
        self._dirty_hosts: set[int] = set()
        self._T_IC = gtsam.Pose3(gtsam.Rot3(ext.R_IC), ext.p_IC)
        self.stats = {"keyframes": 0, "reinitialisations": 0, "init_attempts": 0, "optimisation_failures": 0,
                      "pnp_refined": 0, "landmarks": 0, "depths_gated": 0,
                      "lm_iterations": 0, "inits_refused_tilt": 0, "inits_refused_gyro_bias": 0,
                      **{"failures_" + r.replace(" ", "_"): 0 for r in REASONS}}
        self.init_time_s: float | None = None  # stamp of the first pose
        self._anchor: gtsam.Pose3 | None = None  # last good IMU pose, for a re-initialised segment
        self.loss_reasons: dict[str, int] = {}
        self._bounds = config.failure_bounds()
        self.last_error = ""  # gtsam's message of the last failed optimisation
        # While lost: the IMU propagation of the last good state (preintegrator, nav, bias).
        self._lost: tuple[ImuPreintegrator, gtsam.NavState, gtsam.imuBias.ConstantBias] | None = None
        self._clear()

    # -- state --------------------------------------------------------------------------------
    def _clear(self) -> None:
        self._kfs: list[_Keyframe] = []
        self._serial = 0
        self._landmarks: dict[int, _Landmark] = {}
        self._groups: dict[int, _Group] = {}  # host serial -> its landmarks' factor
        self._dirty_hosts = set()
        self._next_lm = 0
        self._smoother: gtsam.BatchFixedLagSmoother | None = None
        self._nav: gtsam.NavState | None = None
        self._bias = gtsam.imuBias.ConstantBias()
        self._pending: list[Sample] = []  # samples since the newest keyframe
        self._last_sample: Sample | None = None
        self._prop = ImuPreintegrator(self.imu)
        self._estimate: gtsam.Values | None = None
        self._misfit = math.nan  # the window's depth misfit after the last update

    @property
    def tracking(self) -> bool:
        return self._nav is not None

    def keyframe_poses(self) -> list[tuple[float, np.ndarray]]:
        """(stamp, camera pose in G) of the window's keyframes from its estimate now; none while
        it is not tracking."""
        if self._estimate is None or not self.tracking:
            return []
        keys = [(float(kf.stamp_s), gtsam.symbol_shorthand.X(kf.serial)) for kf in self._kfs]
        return [(t, (self._estimate.atPose3(k) * self._T_IC).matrix()) for t, k in keys if self._estimate.exists(k)]

    def add_imu(self, stamp_s: float, accel: np.ndarray, gyro: np.ndarray) -> bool:
        """One IMU sample (camera clock); False when skipped (non-finite, not after the last)."""
        a, w = np.asarray(accel, float).reshape(3), np.asarray(gyro, float).reshape(3)
        if not (math.isfinite(stamp_s) and np.all(np.isfinite(a)) and np.all(np.isfinite(w))):
            return False
        if self._last_sample is not None and stamp_s <= self._last_sample[0]:
            return False
        s = (float(stamp_s), a, w)
        self._pending.append(s)
        self._last_sample = s
        if self._nav is not None:
            self._prop.add(*s)
        elif self._lost is not None:
            self._lost[0].add(*s)
        return True

    def imu_pose(self) -> tuple[float, np.ndarray] | None:
        """(stamp, T_G_imu 4x4) propagated to the newest IMU sample, None when not tracking."""
        if self._nav is None or self._prop.end_s is None:
            return None
        return self._prop.end_s, self._prop.predict(self._nav, self._bias).pose().matrix()

    # -- frames -------------------------------------------------------------------------------
    def add_frame(self, stamp_s: float, ids: Sequence[int], u: np.ndarray, depth_m: np.ndarray,
                  is_keyframe: bool) -> tuple[str, np.ndarray | None]:
        """Status ("ok", "initialising", "lost") and the camera's pose T_G_cam (None unless ok)."""
        feats = {int(i): (np.asarray(uu, float), float(d)) for i, uu, d in zip(ids, u, depth_m, strict=True)}
        if self._nav is None:
            return self._initialising(stamp_s, feats, is_keyframe)
        if len(feats) < self.config.min_features:
            return self._fail("too few features")
        self._prop.integrate_to(stamp_s)
        if not is_keyframe:
            return "ok", self._motion_only(stamp_s, feats).matrix()
        before = (self._prop, self._nav, self._bias)
        t_before = self._kfs[-1].stamp_s
        try:
            if not self._add_keyframe(stamp_s, feats):
                return self._fail("too few landmarks")
        except RuntimeError as err:  # gtsam: an indeterminant system, a singular marginal
            self.stats["optimisation_failures"] += 1
            self.last_error = str(err).strip().splitlines()[0][:200] if str(err).strip() else type(err).__name__
            return self._fail("optimisation")
        why = diverged(self._bounds, before[1], self._nav, self._bias, stamp_s - t_before, self._misfit)
        if why:
            # The diverged update is discarded: the loss continues from the state before it, as
            # after a solver failure (whose update never set a state).
            self.stats["failures_" + why.replace(" ", "_")] += 1
            return self._fail("diverged: " + why, before)
        T = self._nav.pose()
        self._anchor = T
        return "ok", (T * self._T_IC).matrix()

    def _fail(self, why: str, last_good: tuple | None = None) -> tuple[str, None]:
        self.stats["reinitialisations"] += 1
        self.loss_reasons[why] = self.loss_reasons.get(why, 0) + 1
        lost = last_good or ((self._prop, self._nav, self._bias) if self._nav is not None else None)
        self._clear()
        self._lost = lost
        return "lost", None

    # -- initialisation -------------------------------------------------------------------------
    def _take_samples(self, stamp_s: float) -> list[Sample]:
        """The pending samples up to ``stamp_s``, with the last one before the previous keyframe
        held from it (so each interval is integrated from its first keyframe's time)."""
        taken = [s for s in self._pending if s[0] <= stamp_s]
        self._pending = [s for s in self._pending if s[0] > stamp_s]
        if taken:  # the hold for the next interval
            self._pending.insert(0, (stamp_s, taken[-1][1], taken[-1][2]))
        return taken

    def propagation(self) -> tuple[float, np.ndarray, float, np.ndarray] | None:
        """While lost: the last good state propagated with the IMU to its newest sample, as (IMU
        time, T_G_camera, seconds propagated, velocity in G); None while tracking or before a
        sample. Only predicts: the propagation that anchors the next segment is not advanced."""
        if self._lost is None or self.tracking:
            return None
        prop, nav, bias = self._lost
        if prop.start_s is None or prop.end_s is None:
            return None
        state = prop.predict(nav, bias)
        return (float(prop.end_s), (state.pose() * self._T_IC).matrix(), float(prop.end_s - prop.start_s),
                np.asarray(state.velocity(), float))

    def _dead_reckon(self, stamp_s: float) -> tuple[np.ndarray | None, float, np.ndarray | None]:
        """T_G_imu at ``stamp_s`` propagated from the last good state; None when there is none or
        it is older than ``_MAX_DEAD_RECKON_S`` (an IMU alone drifts quadratically); how long it
        was propagated (inf without one); and its attitude R_G_imu alone, kept up to
        ``_MAX_ATTITUDE_S`` (the gyroscope's integral drifts linearly, with the bias error)."""
        if self._lost is None:
            return None, math.inf, None
        prop, nav, bias = self._lost
        prop.integrate_to(stamp_s)
        if prop.start_s is None or prop.end_s is None:
            return None, math.inf, None
        age = prop.end_s - prop.start_s
        if age > _MAX_ATTITUDE_S:
            return None, math.inf, None
        T = prop.predict(nav, bias).pose().matrix()
        if age > _MAX_DEAD_RECKON_S:
            return None, math.inf, T[:3, :3]
        return T, age, T[:3, :3]

    def _pim(self, kf: _Keyframe, bias: gtsam.imuBias.ConstantBias) -> gtsam.PreintegratedCombinedMeasurements:
        pre = ImuPreintegrator(self.imu, bias)
        for s in kf.samples:
            pre.add(*s)
        pre.integrate_to(kf.stamp_s)
        return pre.pim

    def _initialising(self, stamp_s: float, feats: dict, is_keyframe: bool) -> tuple[str, None]:
        status = "lost" if self.stats["reinitialisations"] else "initialising"
        if not is_keyframe:
            return status, None
        samples = self._take_samples(stamp_s)
        self._kfs.append(_Keyframe(self._serial, stamp_s, feats, samples, *self._dead_reckon(stamp_s)))
        self._serial += 1
        n = self.config.init_keyframes
        if len(self._kfs) > n:
            self._kfs.pop(0)
        if len(self._kfs) < n:
            return status, None
        self.stats["init_attempts"] += 1
        # After a short loss the last good state, propagated by the gyroscope through it, gives
        # the vertical and the gyroscope bias better than a second of keyframes where tracking was
        # just lost (a bare corridor, a close poster): their alignments came out 14-18 deg off the
        # vertical and their SfM rotations gave biases of 0.2 rad/s (docs/dvio.md "The MH01-like walk").
        anchor = self._kfs[0].dead_reckoned
        lost_bias = self._lost[2] if anchor is not None and self._lost is not None else None
        down = None if anchor is None else anchor[:3, :3].T @ np.array([0.0, 0.0, -1.0])
        bias = gtsam.imuBias.ConstantBias(np.zeros(3), lost_bias.gyroscope() if lost_bias is not None else np.zeros(3))
        pims = [self._pim(kf, bias) for kf in self._kfs[1:]]
        # Both variants initialise with the depth-enhanced SfM (eq. 1-5): the ablation removes
        # the window's depth factors, as Table IV's VINS-Mono row differs from D-VIO.
        obs = [KeyframeObs(kf.stamp_s, kf.features) for kf in self._kfs]
        if any(p.deltaTij() <= 0.0 for p in pims):
            return status, None  # an interval without IMU samples: wait for the stream
        res = initialise(obs, pims, self.ext, self.depth, self.sigma, self.imu.gravity_mps2,
                         estimate_gyro_bias=lost_bias is None, gravity_dir_W=down)
        if not res.ok:
            return status, None
        first = self._kfs[0]
        carried = first.dead_reckoned[:3, :3] if first.dead_reckoned_s <= _MAX_REFUSING_S else None
        why = init_refused(self._bounds, res.T_G_imu[0, :3, :3], res.gyro_bias, carried)
        if why:
            # An alignment over too short a window (docs/dvio.md "The ring loop"): the next
            # keyframe tries again.
            self.stats["inits_refused_" + why.replace(" ", "_")] += 1
            return status, None
        try:
            self._start(res)
        except RuntimeError:
            self.stats["optimisation_failures"] += 1
            self._clear()
            return status, None
        if self.init_time_s is None:
            self.init_time_s = stamp_s
        self._lost = None
        self._anchor = self._nav.pose()
        return "ok", (self._nav.pose() * self._T_IC).matrix()

    def _start(self, res: InitResult) -> None:
        c = self.config
        T_G = res.T_G_imu
        # Continue the last segment: position and yaw of the first keyframe from the IMU
        # propagated through the loss (or, without it, the last good pose, with the heading the
        # gyroscope carried through a loss too long to dead-reckon: docs/dvio.md "The ring loop's heading").
        anchor = self._kfs[0].dead_reckoned
        if anchor is None and self._anchor is not None:
            anchor = self._anchor.matrix()
            if self._kfs[0].carried_R is not None:
                anchor[:3, :3] = self._kfs[0].carried_R
        v_G = np.asarray(res.v_G, float)
        if anchor is not None:
            # The velocities turn with the poses: left in the initialisation's own yaw, the
            # velocity prior below pulled the new segment's first velocity up to twice the walking
            # speed off, and the first window tilted 5-17 deg to reconcile it with the IMU
            # (docs/dvio.md "The re-anchored velocity").
            T_G, R_yaw = _anchored(T_G, anchor)
            v_G = v_G @ R_yaw.T
        bias = gtsam.imuBias.ConstantBias(np.zeros(3), res.gyro_bias)
        lm_params = gtsam.LevenbergMarquardtParams()
        lm_params.setMaxIterations(c.max_iterations)
        # A keyframe's step changes the window little: stop once the cost moves by < 0.1 %
        # (gtsam's default 1e-5 spends most iterations on digits no metric sees).
        lm_params.setRelativeErrorTol(1e-3)
        lm_params.setLinearSolverType(SOLVERS[c.linear_solver])
        self._smoother = gtsam.BatchFixedLagSmoother(c.window - 0.5, lm_params)
        graph, values, stamps = gtsam.NonlinearFactorGraph(), gtsam.Values(), gtsam.FixedLagSmootherKeyTimestampMap()
        for k, kf in enumerate(self._kfs):
            n = kf.serial
            values.insert(X(n), gtsam.Pose3(T_G[k]))
            values.insert(V(n), v_G[k])
            values.insert(B(n), bias)
            for key in (X(n), V(n), B(n)):
                stamps.insert((key, float(n)))
            if k:
                prev = self._kfs[k - 1].serial
                graph.add(combined_factor(X(prev), V(prev), X(n), V(n), B(prev), B(n), self._pim(kf, bias)))
        n0 = self._kfs[0].serial
        # Gauge: yaw and position of G are unobservable and are held; roll and pitch are not
        # (the window's IMU factors observe gravity) and take only the weak tilt prior.
        graph.add(gtsam.PriorFactorPose3(X(n0), gtsam.Pose3(T_G[0]), gauge_prior_model(T_G[0, :3, :3], c.tilt_sigma_rad)))
        graph.add(gtsam.PriorFactorVector(V(n0), v_G[0], gtsam.noiseModel.Isotropic.Sigma(3, 0.1)))
        graph.add(gtsam.PriorFactorConstantBias(B(n0), bias, gtsam.noiseModel.Diagonal.Sigmas(
            np.array([c.bias_sigma_acc] * 3 + [c.bias_sigma_gyro] * 3))))
        poses = {kf.serial: gtsam.Pose3(T_G[k]) for k, kf in enumerate(self._kfs)}
        self._landmarks, self._groups = {}, {}
        self._update(graph, values, stamps, self._add_landmarks(graph, values, stamps, poses))

    # -- window ---------------------------------------------------------------------------------
    def _add_keyframe(self, stamp_s: float, feats: dict) -> bool:
        """The keyframe into the window and the window optimised; False, before any optimisation,
        when the keyframe observes fewer than ``min_landmarks`` of the window's landmarks."""
        prev = self._kfs[-1]
        kf = _Keyframe(self._serial, stamp_s, feats, self._take_samples(stamp_s))
        self._serial += 1
        n, m = kf.serial, prev.serial
        pim = self._pim(kf, self._bias)
        nav = pim.predict(self._nav, self._bias)
        self._kfs.append(kf)
        graph, values, stamps = gtsam.NonlinearFactorGraph(), gtsam.Values(), gtsam.FixedLagSmootherKeyTimestampMap()
        values.insert(X(n), nav.pose())
        values.insert(V(n), nav.velocity())
        values.insert(B(n), self._bias)
        for key in (X(n), V(n), B(n)):
            stamps.insert((key, float(n)))
        graph.add(combined_factor(X(m), V(m), X(n), V(n), B(m), B(n), pim))
        # Keyframes and landmarks the smoother is about to marginalise take no new factors.
        oldest = n - self.config.window + 1
        self._kfs = [k for k in self._kfs if k.serial >= oldest]
        self._landmarks = {f: lm for f, lm in self._landmarks.items() if lm.host >= oldest}
        self._groups = {h: g for h, g in self._groups.items() if h >= oldest}
        poses = {k.serial: self._estimate.atPose3(X(k.serial)) for k in self._kfs[:-1]}
        poses[n] = nav.pose()
        remove = self._add_landmarks(graph, values, stamps, poses)
        if sum(n in lm.obs for lm in self._landmarks.values()) < self.config.min_landmarks:
            return False
        self._update(graph, values, stamps, remove)
        return True

    def _add_landmarks(self, graph: gtsam.NonlinearFactorGraph, values: gtsam.Values,
                       stamps: gtsam.FixedLagSmootherKeyTimestampMap, poses: Mapping[int, gtsam.Pose3]) -> list[int]:
        """New landmarks for features seen twice or more in the window, and every observation not
        yet in the graph: the factor of each host keyframe whose landmarks changed is replaced by
        one holding all their observations (:mod:`.grouped`). Returns the graph indices of the
        factors it replaces, for the smoother to remove."""
        c, kfs = self.config, self._kfs
        seen: dict[int, list[_Keyframe]] = {}
        for kf in kfs:
            for f, (uu, _) in kf.features.items():
                if np.all(np.isfinite(uu)):
                    seen.setdefault(f, []).append(kf)
        changed: set[int] = {h for h in self._dirty_hosts if any(lm.host == h for lm in self._landmarks.values())}
        self._dirty_hosts = set()
        for f, where in seen.items():
            lm = self._landmarks.get(f)
            if lm is None:
                if len(where) < 2:
                    continue
                host = where[0]
                xi = self._start_depth(host, where[1:], f, poses)
                if xi is None:
                    continue
                uu, d = host.features[f]
                lm = self._landmarks[f] = _Landmark(L(self._next_lm), host.serial, f, {host.serial}, uu, d)
                self._next_lm += 1
                self.stats["landmarks"] += 1
                values.insert(lm.key, np.array([xi]))
                stamps.insert((lm.key, float(host.serial)))
                # A landmark seen from two close keyframes (or whose factors the robust kernel has
                # all but switched off) is barely constrained along its ray, and the smoother's
                # marginalisation eliminates it without damping: a weak prior (sigma 2 m^-1 around
                # its start) keeps that definite without pulling a well-observed landmark.
                graph.add(gtsam.PriorFactorVector(lm.key, np.array([xi]), gtsam.noiseModel.Isotropic.Sigma(1, 2.0)))
            for kf in where:
                if kf.serial in lm.obs:
                    continue
                lm.obs.add(kf.serial)
                uu, d = kf.features[f]
                lm.observations.append((X(kf.serial), uu, d))
                changed.add(lm.host)
        by_host: dict[int, list[_Landmark]] = {}
        for lm in self._landmarks.values():
            if lm.host in changed:
                by_host.setdefault(lm.host, []).append(lm)
        remove = []
        depth = self.depth if c.depth_factors else None
        for h in sorted(by_host):
            hosted = [self._hosted(lm) for lm in sorted(by_host[h], key=lambda lm: lm.key)]
            fac = host_group_factor(X(h), hosted, self.ext, self.sigma, depth, c.kernel, c.kernel_k)
            old = self._groups.pop(h, None)
            if old is not None and old.index is not None:
                remove.append(old.index)
            if fac is not None:
                graph.add(fac)
                self._groups[h] = _Group(fac)
        return remove

    def _hosted(self, lm: _Landmark) -> HostedLandmark:
        if lm.feature not in self._depth_off:
            return HostedLandmark(lm.key, lm.u_host, lm.d_host, tuple(lm.observations))
        return HostedLandmark(lm.key, lm.u_host, math.nan, tuple((k, u, math.nan) for k, u, _ in lm.observations))

    def _gate_depths(self, est: gtsam.Values) -> float:
        """Depths off for the landmarks whose reprojections miss by more than ``depth_gate_px``
        on average at the new estimate (their host factors are rebuilt at the next keyframe), and
        the window's depth misfit at it (:func:`.failure.depth_misfit`; NaN without depth factors)."""
        c = self.config
        if not c.depth_factors:
            return math.nan
        gate = c.depth_gate_px
        residuals: list[float] = []
        for lm in self._landmarks.values():
            if not lm.observations or not est.exists(lm.key):
                continue
            T_h = est.atPose3(X(lm.host))
            xi = max(float(est.atVector(lm.key)[0]), 1e-3)
            # Gated depths count in the misfit too: the gate drops the depths that disagree with
            # the estimate, so a window running off sheds them and shows no misfit in the rest.
            if self.depth.valid(lm.d_host):
                residuals.append(abs(1.0 / xi - lm.d_host) / self.depth.sigma_m(lm.d_host))
            miss = []
            for key, uu, d in lm.observations:
                P = landmark_in_camera(T_h, est.atPose3(key), xi, lm.u_host, self.ext, jacobians=False)[0]
                if P[2] <= 1e-3:
                    miss.append(math.inf)
                    continue
                miss.append(float(np.linalg.norm(P[:2] / P[2] - uu) * self._focal_px))
                if self.depth.valid(d):
                    residuals.append(abs(float(P[2]) - d) / self.depth.sigma_m(d))
            if gate > 0.0 and lm.feature not in self._depth_off and float(np.mean(miss)) > gate:
                self._depth_off.add(lm.feature)
                self._dirty_hosts.add(lm.host)
                self.stats["depths_gated"] += 1
        return depth_misfit(residuals)

    def _miss_px(self, T_h: gtsam.Pose3, T_o: gtsam.Pose3, xi: float, u_host: np.ndarray, u_obs: np.ndarray) -> float:
        """How far (px) the landmark at inverse depth ``xi`` on the host's ray projects from its
        sighting ``u_obs`` in another keyframe (inf behind that camera)."""
        P = landmark_in_camera(T_h, T_o, xi, u_host, self.ext, jacobians=False)[0]
        return float(np.linalg.norm(P[:2] / P[2] - u_obs) * self._focal_px) if P[2] > 1e-3 else math.inf

    def _start_depth(self, host: _Keyframe, others: Sequence[_Keyframe], f: int,
                     poses: Mapping[int, gtsam.Pose3]) -> float | None:
        """Start value of a landmark's inverse depth: its host depth (with depth factors), else
        the two-view midpoint triangulation with the farthest other keyframe."""
        uu, d = host.features[f]
        if self.config.depth_factors and self.depth.valid(d) and f not in self._depth_off:
            gate = self.config.depth_gate_px
            miss = [self._miss_px(poses[host.serial], poses[o.serial], 1.0 / d, uu, o.features[f][0]) for o in others]
            if not (gate > 0.0 and float(np.mean(miss)) > gate):
                return 1.0 / d
            # The host's depth does not fit the feature's other sightings: gated from the start.
            self._depth_off.add(f)
            self.stats["depths_gated"] += 1
        T_h = poses[host.serial] * self._T_IC
        best = None
        for o in others:
            T_o = poses[o.serial] * self._T_IC
            base = T_o.translation() - T_h.translation()
            r1 = T_h.rotation().matrix() @ np.array([uu[0], uu[1], 1.0])
            r2 = T_o.rotation().matrix() @ np.array([*o.features[f][0], 1.0])
            A = np.column_stack([r1, -r2])
            st, *_ = np.linalg.lstsq(A, base, rcond=None)
            cos = r1 @ r2 / (np.linalg.norm(r1) * np.linalg.norm(r2))
            # Rays closer than 1 deg do not fix a depth; the same bound as VINS-Mono's parallax.
            if st[0] > 0.1 and st[1] > 0.1 and cos < math.cos(math.radians(1.0)):
                if best is None or cos < best[1]:
                    best = (st[0], cos)
        if best is None or best[0] > 50.0:
            return None
        return 1.0 / best[0]

    def _update(self, graph: gtsam.NonlinearFactorGraph, values: gtsam.Values,
                stamps: gtsam.FixedLagSmootherKeyTimestampMap, remove: Sequence[int] = ()) -> None:
        result = self._smoother.update(graph, values, stamps, list(remove))
        # Where the smoother put the new host factors, to replace them at the next keyframe (it
        # fills the slots of removed factors first, so the index is read back, not predicted).
        pending = {id(g.factor): g for g in self._groups.values() if g.index is None}
        if pending:
            factors = self._smoother.getFactors()
            for i in range(factors.size()):
                g = pending.get(id(factors.at(i)))
                if g is not None:
                    g.index = i
        self.stats["lm_iterations"] += int(result.getIterations())
        est = self._smoother.calculateEstimate()
        newest = self._kfs[-1].serial
        self._estimate = est
        self._misfit = self._gate_depths(est)
        self._nav = gtsam.NavState(est.atPose3(X(newest)), est.atVector(V(newest)))
        self._bias = est.atConstantBias(B(newest))
        self.stats["keyframes"] += 1
        # IMU-rate propagation restarts at the newest keyframe with the new bias.
        self._prop = ImuPreintegrator(self.imu, self._bias)
        for s in self._pending:
            self._prop.add(*s)

    # -- non-keyframes --------------------------------------------------------------------------
    def landmarks_G(self) -> dict[int, np.ndarray]:
        """Feature id -> landmark position in G, from the window's estimate."""
        out = {}
        est = self._estimate
        if est is None:
            return out
        for f, lm in self._landmarks.items():
            if not est.exists(lm.key) or not est.exists(X(lm.host)):
                continue
            xi = float(est.atVector(lm.key)[0])
            host = next((kf for kf in self._kfs if kf.serial == lm.host), None)
            if host is None or xi <= 1e-3:
                continue
            uu = host.features[f][0]
            T_GC = est.atPose3(X(lm.host)) * self._T_IC
            out[f] = T_GC.transformFrom(np.array([uu[0], uu[1], 1.0]) / xi)
        return out

    def _motion_only(self, stamp_s: float, feats: dict) -> gtsam.Pose3:
        """T_G_cam of a non-keyframe (module docstring)."""
        T_pred = self._prop.predict(self._nav, self._bias).pose() * self._T_IC
        lms = self.landmarks_G()
        pairs = [(lms[f], uu) for f, (uu, _) in feats.items() if f in lms and np.all(np.isfinite(uu))]
        if len(pairs) < 8:
            return T_pred
        obj = np.array([p for p, _ in pairs], dtype=np.float64)
        img = np.array([uu for _, uu in pairs], dtype=np.float64)
        T_CG = T_pred.inverse()
        rvec = cv2.Rodrigues(T_CG.rotation().matrix())[0]
        tvec = T_CG.translation().reshape(3, 1).copy()
        ok, rvec, tvec, inl = cv2.solvePnPRansac(obj, img, np.eye(3), None, rvec, tvec, useExtrinsicGuess=True,
                                                 reprojectionError=3.0 * self.sigma, flags=cv2.SOLVEPNP_ITERATIVE)
        if not ok or inl is None or len(inl) < max(8, len(pairs) // 2):
            return T_pred
        T = gtsam.Pose3(gtsam.Rot3(cv2.Rodrigues(rvec)[0]), tvec.ravel()).inverse()
        # A PnP far from the propagation is a wrong minimum, not a correction.
        if (np.linalg.norm(T.translation() - T_pred.translation()) > 0.2
                or np.linalg.norm(gtsam.Rot3.Logmap(T.rotation().between(T_pred.rotation()))) > 0.2):
            return T_pred
        self.stats["pnp_refined"] += 1
        return T


def gauge_prior_model(R_GI: np.ndarray, tilt_sigma_rad: float, held_sigma: float = 1e-3) -> gtsam.noiseModel.Base:
    """Noise model of the prior on an initialisation's first pose ``T_GI``: position and yaw (the
    rotation about G's vertical) held to ``held_sigma``, roll and pitch to ``tilt_sigma_rad``.
    gtsam's ``Pose3`` tangent is (rotation, translation) in the body's axes, where G's vertical
    is ``R_GI^T e_z``: the rotation block is split along it, whatever the body's attitude."""
    a = np.asarray(R_GI, dtype=float).T @ np.array([0.0, 0.0, 1.0])
    up = np.outer(a, a)
    cov = np.zeros((6, 6))
    cov[:3, :3] = held_sigma**2 * up + tilt_sigma_rad**2 * (np.eye(3) - up)
    cov[3:, 3:] = held_sigma**2 * np.eye(3)
    return gtsam.noiseModel.Gaussian.Covariance(cov)


def _anchored(T_G: np.ndarray, T_anchor: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``T_G`` (M, 4, 4) moved by the yaw and translation that put its first pose's position and
    heading on ``T_anchor``'s (gravity stays -z), and that yaw's rotation (3x3), which the
    velocities in G take too."""

    def yaw(R: np.ndarray) -> float:
        return math.atan2(R[1, 0], R[0, 0])

    dy = yaw(T_anchor[:3, :3]) - yaw(T_G[0, :3, :3])
    c, s = math.cos(dy), math.sin(dy)
    M = np.eye(4)
    M[:3, :3] = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    M[:3, 3] = T_anchor[:3, 3] - M[:3, :3] @ T_G[0, :3, 3]
    return np.einsum("ij,njk->nik", M, T_G), M[:3, :3]
