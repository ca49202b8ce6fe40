"""The optimised RTLS pipelines against a straightforward reference computation of the same thing.

The pipelines compute the ToF points with hand-rolled kinematic chains in plain floats and run
Algorithm 1 on plain floats (perception/kinematics/, staircase.py, rtls.py). Here the
same recorded frame stream is also processed the obvious way: a full pinocchio
``forwardKinematics`` for every point, and Algorithm 1 written directly from the listing with
each surface's plane refitted in batch (centroid and eigen-decomposition of the scatter of its
member points) whenever it is needed. Both must agree: the same points (1e-12 m), the same
surface for every reading, the same planes (1e-12) and read-out.
"""

import functools
from collections import deque

import numpy as np
import pinocchio as pin
import pytest
from test_perception_pipelines import CAL, make_frames
from test_perception_staircase import sweep_stream

from exobench.core import ImuSample, JointState, PlaneEstimate, ToFReading, TofStatus
from exobench.perception.stairs import RtlsHtvrStairs, RtlsStairs, sensor_flags
from exobench.perception.stairs.readout import orient_normal, riser_height_m, tread_depth_m
from exobench.perception.stairs.staircase import StaircaseAlgorithm, StaircaseParams

TOL = 1e-12


# --- reference kinematics: pinocchio forward kinematics for every point ----------------------
def _quat_to_R(q):
    w, x, y, z = np.asarray(q, float) / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def reference_points(frames, cal, leg="r", stance="l", imu_id="imu_trunk"):
    """[(index of the ToF frame, flag, point)] of the readings the pipeline should use."""
    model = pin.buildModelFromXML(cal.robot_urdf)
    data = model.createData()
    mounts = {m.sensor_id: m for m in cal.mounts}
    flags = sensor_flags(leg)

    def T_base(link):
        fid = model.getFrameId(link, pin.FrameType.BODY)
        return (data.oMf[model.getFrameId(cal.base_link, pin.FrameType.BODY)].inverse() * data.oMf[fid]).homogeneous

    joints, quat, out, k_tof = None, None, [], -1
    for f in frames:
        if isinstance(f, JointState):
            joints = dict(zip(f.names, np.asarray(f.position_rad, float), strict=False))
        elif isinstance(f, ImuSample) and f.sensor_id == imu_id:
            quat = f.quat_wxyz
        elif isinstance(f, ToFReading):
            k_tof += 1
            ok = f.status == TofStatus.VALID and np.isfinite(f.range_m) and f.range_m >= 0
            if f.sensor_id not in flags or not ok or joints is None or quat is None:
                continue
            q = pin.neutral(model)
            for j in range(1, model.njoints):
                jm, a = model.joints[j], joints.get(model.names[j], 0.0)
                if jm.nq == 1:
                    q[jm.idx_q] = a
                elif jm.nq == 2:
                    q[jm.idx_q : jm.idx_q + 2] = (np.cos(a), np.sin(a))
            pin.forwardKinematics(model, data, q)
            pin.updateFramePlacements(model, data)
            T_bs = T_base(mounts[f.sensor_id].parent_link) @ mounts[f.sensor_id].T_parent_sensor
            R_wb = _quat_to_R(quat) @ (T_base(mounts[imu_id].parent_link) @ mounts[imu_id].T_parent_sensor)[:3, :3].T
            p_ankle = T_base(f"foot_{stance}")[:3, 3]  # the foot's origin is the ankle joint
            p = R_wb @ (T_bs[:3, 3] + f.range_m * T_bs[:3, 2] - p_ankle) + np.array([0.0, 0.0, cal.sole_height_m])
            out.append((k_tof, flags[f.sensor_id], p))
    return out


# --- reference Algorithm 1: batch planes refitted from their member points ---------------------
class RefSurface:
    def __init__(self, index, kind):
        self.index, self.kind = index, kind
        self.members: list[int] = []  # points in the plane (V, e)
        self.B: deque[int] = deque()
        self.count = {"r": 0, "l": 0}
        self.ok, self.ok_uid = False, None

    def fit(self, P):
        """(normal, centroid, sigma) by batch total least squares on the member points."""
        X = P[self.members]
        e = X.mean(axis=0)
        if self.kind == "horizontal":
            return np.array([0.0, 0.0, 1.0]), e, float(np.sqrt(np.mean((X[:, 2] - e[2]) ** 2)))
        dims = [0, 1] if self.kind == "vertical" else [0, 1, 2]
        D = X[:, dims] - e[dims]
        w, U = np.linalg.eigh(D.T @ D)
        n = np.zeros(3)
        n[dims] = U[:, 0]
        return n, e, float(np.sqrt(max(w[0], 0.0) / len(X)))


def reference_algorithm(points, flags, params: StaircaseParams):
    """Surface of every point at the end, and the surfaces, by the listing of Algorithm 1."""
    P = np.array(points)
    kinds = [("horizontal" if i % 2 == 0 else "vertical") if params.htvr else "general" for i in range(params.n_surfaces)]
    S = [RefSurface(i, k) for i, k in enumerate(kinds)]
    where = [-1] * len(P)
    Q = {"r": deque(), "l": deque()}
    ids = {"r": 0, "l": 0}  # the surface under investigation (both equal with shared ids)
    call = -1

    def e_z(s):
        return float(P[s.members, 2].mean()) if s.members else 0.0

    def add(u, s):
        s.members.append(u)
        s.count[flags[u]] += 1
        where[u] = s.index

    def remove(u, s):
        s.members.remove(u)
        s.count[flags[u]] -= 1
        where[u] = -1

    def surf_update(u, s):
        if len(s.B) >= params.buffer_b:
            r = s.B.popleft()
            n, e, sigma = s.fit(P)
            if not abs(np.dot(P[r] - e, n)) <= sigma + 1e-12:
                remove(r, s)
        s.B.append(u)
        add(u, s)
        need = params.reliable_n_riser if s.index % 2 and params.reliable_n_riser else params.reliable_n
        if not s.ok and all(s.count[f] >= need for f in ("r", "l")):
            s.ok, s.ok_uid = True, call
        if s.index > 0 and s.ok and S[s.index - 1].B:
            prev = S[s.index - 1]
            (n0, e0, _), (n1, e1, _) = prev.fit(P), s.fit(P)
            move = [v for v in prev.B if abs(np.dot(P[v] - e1, n1)) < abs(np.dot(P[v] - e0, n0))]
            for v in move:
                prev.B.remove(v)
                remove(v, prev)
                add(v, s)

    for uid, flag in enumerate(flags):
        call = uid
        q = Q[flag]
        if len(q) >= params.queue_q:
            zs = P[list(q), 2]
            z_bar, sigma_z = zs.mean(), zs.std()
            u = q.popleft()
            qz, target = P[u, 2], None
            flat = sigma_z < params.th_z_m
            cur = ids[flag]
            if cur >= params.n_surfaces:
                target = None  # beyond S4: discarded
            elif cur % 2 == 0:
                moved = np.hypot(*(P[q[-1], :2] - P[u, :2]))
                travel = moved >= params.th_z_m and moved > abs(P[q[-1], 2] - qz)
                if flat and abs(qz - z_bar) < sigma_z and (travel or not params.tread_travel):
                    target = cur
                    if params.tread_gate_m and S[cur].ok:
                        n, e, _ = S[cur].fit(P)
                        if abs(np.dot(P[u] - e, n)) > params.tread_gate_m:
                            target = None
                elif not flat and qz > e_z(S[cur]) + 1.5 * params.th_z_m:
                    target = cur + 1
            elif not flat:
                target = cur
            elif qz > e_z(S[cur - 1]) + params.th_pl_m:
                h = np.hypot(*(P[q[-1], :2] - P[u, :2]))
                travel = h >= params.th_z_m and h > abs(P[q[-1], 2] - qz) and abs(qz - z_bar) < sigma_z
                if params.riser_exit == "paper" or travel:
                    target = cur + 1
            elif params.riser_flat_low == "assign":
                target = cur
            if target is not None:
                if params.sensor_ids == "shared":
                    ids["r"] = ids["l"] = target
                else:
                    ids[flag] = target
                if target < params.n_surfaces:
                    surf_update(u, S[target])
        q.append(uid)
    return where, S, P


def _assert_planes_equal(planes, surfaces, P, uid_stamps):
    """Reported planes (PlaneEstimate) equal the reference surfaces with at least 3 points."""
    by_index = {p.index: p for p in planes}
    expected = [s for s in surfaces if len(s.members) >= 3]
    assert sorted(by_index) == [s.index for s in expected]
    ref_planes = []
    for s in expected:
        got = by_index[s.index]
        n, e, sigma = s.fit(P)
        np.testing.assert_allclose(got.normal, orient_normal(n, e), atol=TOL, rtol=0)
        np.testing.assert_allclose(got.centroid, e, atol=TOL, rtol=0)
        assert abs(got.sigma_m - sigma) <= TOL
        assert got.n_points == {"tof_r_lat": s.count["r"], "tof_r_med": s.count["l"]}
        assert got.reliable == s.ok
        assert got.reliable_stamp_s == (None if s.ok_uid is None else uid_stamps[s.ok_uid])
        X = P[s.members] - e
        scatter = X.T @ X if s.kind == "general" else None
        ref_planes.append(PlaneEstimate(s.index, orient_normal(n, e), e, {}, sigma, s.ok, scatter=scatter))
    return ref_planes


@pytest.mark.parametrize("htvr", [False, True], ids=["general", "htvr"])
def test_algorithm_equals_the_reference_on_point_streams(htvr):
    """Algorithm 1 alone, on swept point streams and parameters that exercise every branch."""
    totals = dict.fromkeys(("n_assigned", "n_discarded", "n_removed", "n_shifted"), 0)
    new = {"th_pl_m": 0.08, "reliable_n_riser": 2, "tread_gate_m": 8e-3, "sensor_ids": "per_sensor", "riser_exit": "travel",
           "tread_travel": True}
    for seed, yaw_deg, noise_m, b, n_rel, policy, options in [
        (0, 0.0, 1.5e-3, 10, 5, "assign", {}),
        (1, 20.0, 1.5e-3, 4, 2, "assign", {}),
        (2, 20.0, 4e-3, 6, 3, "discard", {}),
        (3, -15.0, 4e-3, 4, 2, "assign", {}),
        (1, -25.0, 8e-3, 2, 1, "assign", {}),
        (0, 0.0, 1.5e-3, 10, 5, "assign", new),
        (1, 20.0, 4e-3, 10, 5, "assign", new),
        (2, -25.0, 1.5e-3, 4, 2, "discard", new),
    ]:
        stream = sweep_stream(seed=seed, yaw_deg=yaw_deg, noise_m=noise_m)
        params = StaircaseParams(buffer_b=b, reliable_n=n_rel, htvr=htvr, riser_flat_low=policy, **options)
        alg = StaircaseAlgorithm(params)
        for _, flag, p, _ in stream:
            alg.assign(p, flag)
        where, surfaces, P = reference_algorithm([p for _, _, p, _ in stream], [f for _, f, _, _ in stream], params)
        assert alg.point_surfaces().tolist() == where
        for S, ref in zip(alg.surfaces, surfaces, strict=True):
            assert S.plane.n == len(ref.members) and S.n_by_flag == ref.count and S.ok == ref.ok
            assert S.reliable_uid == ref.ok_uid and list(S.buffer) == list(ref.B)
            if len(ref.members) >= 3:
                n, e, sigma = ref.fit(P)
                np.testing.assert_allclose(S.plane.centroid, e, atol=TOL, rtol=0)
                assert abs(abs(float(np.dot(S.plane.normal, n))) - 1.0) <= TOL
                np.testing.assert_allclose(orient_normal(S.plane.normal, e), orient_normal(n, e), atol=TOL, rtol=0)
                assert abs(S.plane.sigma_m - sigma) <= TOL
        for k in totals:
            totals[k] += alg.counts[k]
    assert all(v > 0 for v in totals.values()), totals


@functools.cache
def _simulated_frames():
    from exobench.envs import sim
    # the paper's case B (23 deg yaw, close to the stairs)
    scenario = sim.StairScenario.from_dict({"yaw_deg": 23.0, "distance_m": 0.27})
    ep = sim.simulate_stairs(scenario, seed=1)
    return tuple(ep.frames), ep.calibration


STREAMS = {
    "synthetic": lambda: (make_frames(seed=3, yaw_deg=10.0)[0], CAL),
    "simulated": _simulated_frames,
}


# the pipelines' defaults, and the paper's Algorithm 1 and read-out as published
PAPER_CONFIG = {
    "th_pl_m": 0.13, "reliable_n_riser": 0, "tread_gate_m": 0.0, "sensor_ids": "shared", "riser_exit": "paper",
    "tread_travel": False, "riser_at": "midpoint",
}  # fmt: skip


@pytest.mark.parametrize("cls", [RtlsStairs, RtlsHtvrStairs], ids=["rtls", "rtls-htvr"])
@pytest.mark.parametrize("stream", list(STREAMS))
@pytest.mark.parametrize("config", [{}, PAPER_CONFIG], ids=["default", "paper"])
def test_optimised_pipeline_equals_the_reference_computation(cls, stream, config):
    frames, cal = STREAMS[stream]()
    pipe = cls(cls.Config(**config))
    pipe.reset(cal)
    online = [pipe.process(f) for f in frames]
    est = pipe.finalize()

    # the points: lazy float kinematics = pinocchio forward kinematics per point
    ref = reference_points(frames, cal)
    used = [a for a in est.assignments if a.surface_index != -2]
    assert len(used) == len(ref) == len(est.compute_time_s) > 50
    assert [k for k, a in enumerate(est.assignments) if a.surface_index != -2] == [k for k, _, _ in ref]
    for a, (_, _, p) in zip(used, ref, strict=True):
        np.testing.assert_allclose(a.point, p, atol=TOL, rtol=0)

    # the assignments, planes and read-out: the listing with batch-refitted planes
    where, surfaces, P = reference_algorithm([p for _, _, p in ref], [f for _, f, _ in ref], pipe.config.params(cls.htvr))
    assert [a.surface_index for a in used] == where
    assert sum(w >= 0 for w in where) > 0.25 * len(where)
    ref_planes = _assert_planes_equal(est.planes, surfaces, P, [a.stamp_s for a in used])
    riser_at = pipe.config.riser_at
    for read, value in ((lambda p: riser_height_m(p, riser_at), est.riser_height_m), (tread_depth_m, est.tread_depth_m)):
        want = read(ref_planes)
        assert (np.isnan(want) and np.isnan(value)) or abs(want - value) <= TOL
    # the last online estimate is the final one without assignments and timings
    last = online[-1]
    assert last.assignments == () and len(last.compute_time_s) == 0
    assert [p.index for p in last.planes] == [p.index for p in est.planes]
    for a, b in zip(last.planes, est.planes, strict=True):
        np.testing.assert_array_equal(a.normal, b.normal)
        assert a.sigma_m == b.sigma_m and a.reliable == b.reliable and a.n_points == b.n_points
