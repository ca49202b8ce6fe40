"""The BVH caster (Embree for static boxes and planes, MuJoCo for the rest) against MuJoCo's.

The reference is ``LidarConfig(caster="mujoco")``: every primary ray by ``mj_multiRay``, every
secondary ray by one ``mj_ray`` on the simulation's model. Both must give the same sweeps (points,
geoms, surface labels, return kinds) on the bench scenes, and the BVH's secondary rays must
reach ``mj_ray`` only for the few rays that may meet a moving or curved geom.
"""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest

from exobench.core import ConfigError
from exobench.envs.sensors.lidar import LidarConfig, LidarSensor
from exobench.envs.sensors.lidar import cast as cast_module
from exobench.envs.sensors.lidar.bvh import StaticBvh, _face_table, _in_any_box, exact_hits, face_hits
from exobench.envs.sensors.lidar.optics import cast_rays
from exobench.envs.sim.pose import site_pose


def _scene(world):
    from exobench.models.exo_spec import ExoSpec
    from exobench.models.worlds import compose

    scene = compose(world, ExoSpec())
    data = mujoco.MjData(scene.model)
    mujoco.mj_forward(scene.model, data)
    T0 = site_pose(scene.model, data, "lidar_trunk")
    return scene.model, data, scene.truth, T0


def _worlds():
    from exobench.models.office import build_office
    from exobench.models.office_params import OfficeParams
    from exobench.models.worlds import build_course, build_staircase

    glazed = OfficeParams(facade="windows", glass_fraction=1.0, partition_glass="float_glass", facade_glass="lowe_glass",
                          polished_fraction=0.0)  # fmt: skip
    return {"office": build_office(), "glazed office": build_office(glazed), "staircase": build_staircase(),
            "course": build_course()}  # fmt: skip


def _assert_same_sweeps(a, b):
    (sa, ta), (sb, tb) = a, b
    np.testing.assert_array_equal(sa.points_xyz, sb.points_xyz)
    np.testing.assert_array_equal(ta.geom_id, tb.geom_id)
    np.testing.assert_array_equal(ta.surface_id, tb.surface_id)
    np.testing.assert_array_equal(ta.kind, tb.kind)
    np.testing.assert_array_equal(ta.true_range_m, tb.true_range_m)


@pytest.mark.parametrize("name", ["office", "glazed office", "staircase", "course"])
def test_bvh_and_mujoco_casters_give_the_same_sweeps_on_the_bench_scenes(name):
    model, data, truth, T0 = _scene(_worlds()[name])

    def walking(t):
        T = np.repeat(T0[None], len(t), axis=0)
        T[:, :3, 3] += (0.5 * np.asarray(t))[:, None] * T0[:3, 0]
        return T

    facing = T0.copy()  # in front of the user at knee height: the rings cross the moving legs
    facing[:3, 3] += T0[:3, :3] @ np.array([1.5, 0.0, 0.0])
    facing[2, 3] = 0.6
    modes = ("strongest", "sampled") if name == "glazed office" else ("sampled",)
    for mode in modes:
        ref = LidarSensor("lidar_trunk", LidarConfig(caster="mujoco", return_mode=mode), model, 3)
        bvh = LidarSensor("lidar_trunk", LidarConfig(caster="bvh", return_mode=mode), model, 3)
        for pose in (T0, walking, facing):
            a = ref.scan(model, data, pose, 0.0, truth)
            b = bvh.scan(model, data, pose, 0.0, truth)
            _assert_same_sweeps(a, b)
        assert bvh.caster.fallback is None
    if name == "glazed office":  # the glass paths are exercised: ghosts and returns through panes
        assert np.count_nonzero(b[1].via_geom_id >= 0) > 100


def test_secondary_rays_are_cast_in_batches_and_equal_mj_ray(monkeypatch):
    """Rays from their own origins (as glass and mirrors send them) through the office and the user:
    the same hits as one ``mj_ray`` each, and only rays near a moving or curved geom reach ``mj_ray``."""
    model, data, _, T0 = _scene(_worlds()["office"])
    rng = np.random.default_rng(1)
    o = T0[:3, 3] + rng.uniform(-3.0, 3.0, (6000, 3)) * [1.0, 1.0, 0.3]
    d = rng.normal(size=(6000, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    group = LidarSensor("lidar_trunk", LidarConfig(), model, 0).group
    r0, g0, n0 = cast_rays(model, data, group, o, d)
    sent = []

    def counting(m, dd, gg, oo, uu, flg_static=1):
        sent.append(len(oo))
        return cast_rays(m, dd, gg, oo, uu, flg_static=flg_static)

    monkeypatch.setattr(cast_module, "cast_rays", counting)
    sensor = LidarSensor("lidar_trunk", LidarConfig(caster="bvh"), model, 0)
    r1, g1, n1 = sensor.caster.secondary(model, data)(o, d)
    np.testing.assert_array_equal(g1, g0)
    np.testing.assert_array_equal(r1, r0)
    np.testing.assert_array_equal(n1, n0)
    assert sum(sent) < 0.1 * len(o)  # a batch: most rays never reach mj_ray
    assert np.count_nonzero(np.isin(g0, np.flatnonzero(model.body_weldid[model.geom_bodyid] != 0))) > 10


def test_exact_hits_are_mujocos_bit_for_bit():
    """Rotated boxes and finite planes, rays from random points: MuJoCo's distance and normal."""
    rng = np.random.default_rng(4)
    spec = mujoco.MjSpec()
    for k in range(12):
        q = rng.normal(size=4)
        spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX if k % 3 else mujoco.mjtGeom.mjGEOM_PLANE,
                                size=list(rng.uniform(0.05, 2.0, 3)), pos=list(rng.uniform(-5, 5, 3)),
                                quat=list(q / np.linalg.norm(q)))  # fmt: skip
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    plane = model.geom_type == mujoco.mjtGeom.mjGEOM_PLANE
    n, hits = 3000, 0
    for g in range(model.ngeom):
        o = rng.uniform(-8, 8, (n, 3))
        d = data.geom_xpos[g] + rng.uniform(-1.5, 1.5, (n, 3)) - o
        d /= np.linalg.norm(d, axis=1)[:, None]
        x, nrm, _ = exact_hits(np.repeat(data.geom_xpos[g][None], n, 0), np.repeat(data.geom_xmat[g][None], n, 0),
                               np.repeat(model.geom_size[g][None], n, 0), np.full(n, plane[g]), o, d)  # fmt: skip
        ref, ref_n = np.empty(n), np.zeros((n, 3))
        gid = np.zeros(1, dtype=np.int32)
        for i in range(n):
            ref[i] = mujoco.mj_ray(model, data, o[i], d[i], None, 1, -1, gid, ref_n[i])
            if gid[0] != g:  # another geom is in front: test this geom alone below
                ref[i] = mujoco.mju_rayGeom(data.geom_xpos[g], data.geom_xmat[g], model.geom_size[g], o[i], d[i],
                                            int(model.geom_type[g]), ref_n[i])  # fmt: skip
        np.testing.assert_array_equal(x, ref)
        hit = ref >= 0
        np.testing.assert_array_equal(nrm[hit], ref_n[hit])
        hits += int(np.count_nonzero(hit))
    assert hits > 0.3 * n * model.ngeom


def _mesh_scene():
    spec = mujoco.MjSpec()
    verts = [0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1]
    spec.add_mesh(name="tet", uservert=verts)
    spec.worldbody.add_geom(name="wall", type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.1, 5.0, 2.0], pos=[3.0, 0.0, 1.0])
    spec.worldbody.add_geom(name="rock", type=mujoco.mjtGeom.mjGEOM_MESH, meshname="tet", pos=[-2.0, 0.0, 0.5])
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    from exobench.core import SceneTruth

    return model, data, SceneTruth(surfaces=(), geom_surfaces={}, geom_materials={})


def test_a_scene_with_meshes_falls_back_to_mujoco_and_says_so_once():
    model, data, truth = _mesh_scene()
    pose = np.eye(4)
    pose[2, 3] = 1.0
    bvh = LidarSensor("lidar", LidarConfig(caster="bvh"), model, 0)
    with pytest.warns(RuntimeWarning, match="mesh"):
        b = bvh.scan(model, data, pose, 0.0, truth)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        bvh.scan(model, data, pose, 0.1, truth)
    assert "mesh" in bvh.caster.fallback
    a = LidarSensor("lidar", LidarConfig(caster="mujoco"), model, 0).scan(model, data, pose, 0.0, truth)
    _assert_same_sweeps(a, b)
    assert len(a[0].points_xyz) > 1000


def test_an_unknown_caster_is_named():
    with pytest.raises(ConfigError, match="lidar.caster"):
        LidarConfig(caster="embree")


def test_a_ray_starting_inside_overlapping_boxes_reports_mujocos_geom_at_a_tie():
    """A mullion (lowest id) touches a pane at x = 0.025; a wall overlaps both and holds the rays'
    origins with the mullion. Leaving the mullion and entering the pane happen at one distance:
    MuJoCo reports the mullion (first visited), whichever of the two Embree names (a glazed
    loop's crossing beams start inside such overlapping frames)."""
    spec = mujoco.MjSpec()
    box = mujoco.mjtGeom.mjGEOM_BOX
    spec.worldbody.add_geom(name="mullion", type=box, pos=[0.0, 0.0, 1.0], size=[0.025, 0.025, 1.0])
    spec.worldbody.add_geom(name="pane", type=box, pos=[0.525, 0.0, 1.0], size=[0.5, 0.005, 1.0])
    spec.worldbody.add_geom(name="wall", type=box, pos=[0.99, 0.0, 1.0], size=[1.0, 0.02, 1.0])
    spec.worldbody.add_geom(name="back", type=box, pos=[3.0, 0.0, 1.0], size=[0.1, 3.0, 2.0])
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    rng = np.random.default_rng(2)
    o = np.column_stack([rng.uniform(-0.009, 0.02, 400), rng.uniform(-0.004, 0.004, 400), rng.uniform(0.2, 1.8, 400)])
    d = np.column_stack([np.ones(400), rng.uniform(-0.004, 0.004, 400), rng.uniform(-0.2, 0.2, 400)])
    d /= np.linalg.norm(d, axis=1)[:, None]
    group = np.ones(6, dtype=np.uint8)
    r0, g0, n0 = cast_rays(model, data, group, o, d)
    caster = LidarSensor("lidar", LidarConfig(caster="bvh"), model, 0).caster
    caster.group = group
    r1, g1, n1 = caster.secondary(model, data)(o, d)
    assert np.count_nonzero(g0 == 0) > 200  # the mullion wins most ties (the rest differ in the last bit)
    np.testing.assert_array_equal(g1, g0)
    np.testing.assert_array_equal(r1, r0)


def test_face_hits_sure_rays_are_mujocos_bit_for_bit():
    """The per-face shortcut (the face Embree names, away from its edges) gives MuJoCo's distance."""
    rng = np.random.default_rng(7)
    spec = mujoco.MjSpec()
    for _ in range(6):
        q = rng.normal(size=4)
        spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=list(rng.uniform(0.05, 2.0, 3)),
                                pos=list(rng.uniform(-5, 5, 3)), quat=list(q / np.linalg.norm(q)))  # fmt: skip
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    table = _face_table(data.geom_xpos.copy(), data.geom_xmat.copy(), model.geom_size.copy())
    n, sure_hits = 2000, 0
    for g in range(model.ngeom):
        o = rng.uniform(-8, 8, (n, 3))
        d = data.geom_xpos[g] + rng.uniform(-1.5, 1.5, (n, 3)) - o
        d /= np.linalg.norm(d, axis=1)[:, None]
        ref, ref_n = np.empty(n), np.zeros((n, 3))
        for i in range(n):
            ref[i] = mujoco.mju_rayGeom(data.geom_xpos[g], data.geom_xmat[g], model.geom_size[g], o[i], d[i],
                                        int(model.geom_type[g]), ref_n[i])  # fmt: skip
        hit = np.flatnonzero(ref >= 0)
        # the face MuJoCo's hit lies on (the one Embree names, but for rounding): its outward normal
        face = np.argmax(ref_n[hit] @ table[15:18, 6 * g : 6 * g + 6], axis=1)
        x, sure = face_hits(table, 6 * g + face, o[hit], d[hit])
        np.testing.assert_array_equal(x[sure], ref[hit][sure])
        np.testing.assert_array_equal(table[15:18, 6 * g + face].T, ref_n[hit])
        sure_hits += int(sure.sum())
    assert sure_hits > 0.3 * n * model.ngeom


def test_in_any_box_matches_a_brute_force_test():
    rng = np.random.default_rng(3)
    for _ in range(100):
        n, b = int(rng.integers(0, 200)), int(rng.integers(1, 30))
        lo = np.round(rng.uniform(-1, 1, (b, 3)), 1)
        hi = lo + np.round(rng.uniform(0, 0.5, (b, 3)), 1)
        p = rng.uniform(-1.2, 1.5, (n, 3))
        p[: n // 3] = np.round(p[: n // 3], 1)  # points on the boxes' faces too
        ref = np.any(np.all((p[:, None] >= lo[None]) & (p[:, None] <= hi[None]), axis=2), axis=1)
        np.testing.assert_array_equal(_in_any_box(p, lo, hi), ref)


def test_face_hits_is_not_sure_of_a_neighbouring_face_near_an_edge():
    """Embree (float32) may name the neighbouring face of a hit within its rounding (a few um) of a box
    edge: the shortcut must then not be sure, or give MuJoCo's distance."""
    rng = np.random.default_rng(11)
    spec = mujoco.MjSpec()
    q = rng.normal(size=4)
    size = np.array([0.4, 0.7, 1.1])
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=list(size), pos=[1.0, -2.0, 0.5],
                            quat=list(q / np.linalg.norm(q)))  # fmt: skip
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    pos, R = data.geom_xpos[0].copy(), data.geom_xmat[0].reshape(3, 3).copy()
    table = _face_table(pos[None], data.geom_xmat[0][None].copy(), size[None])
    tested = 0
    for face in range(6):
        i, s = face // 2, (1.0 if face % 2 else -1.0)
        for a in [ax for ax in range(3) if ax != i]:
            for t in (-1.0, 1.0):
                n = 300
                local = rng.uniform(-0.9, 0.9, (n, 3)) * size
                local[:, i] = s * size[i]
                local[:, a] = t * (size[a] - rng.uniform(-3e-6, 3e-6, n))  # at the edge, within float32 rounding
                o_local = local + rng.uniform(0.5, 3.0, n)[:, None] * (s * np.eye(3)[i] + rng.uniform(-0.5, 0.5, (n, 3)))
                o = o_local @ R.T + pos
                d = (local - o_local) @ R.T
                d /= np.linalg.norm(d, axis=1)[:, None]
                ref, ref_n = np.empty(n), np.zeros((n, 3))
                for r in range(n):
                    ref[r] = mujoco.mju_rayGeom(pos, data.geom_xmat[0], size, o[r], d[r], int(mujoco.mjtGeom.mjGEOM_BOX),
                                                ref_n[r])  # fmt: skip
                on_face = (ref >= 0) & np.all(ref_n == table[15:18, face], axis=1)
                x, sure = face_hits(table, np.full(n, 2 * a + (t > 0)), o, d)  # the neighbour named instead
                # Embree can only name it where the two faces' hits lie within its rounding
                close = on_face & (np.abs(x - ref) <= 1e-5)
                np.testing.assert_array_equal(x[sure & close], ref[sure & close])
                tested += int(close.sum())
    assert tested > 0.3 * 6 * 4 * 300


def _mj_ray_each(model, data, o, u):
    """MuJoCo's own hit of each ray, one mj_ray per ray: (distances, geom ids, normals)."""
    n = len(o)
    ref, ref_g, ref_n = np.empty(n), np.zeros(n, dtype=np.int32), np.zeros((n, 3))
    one = np.zeros(1, dtype=np.int32)
    for i in range(n):
        ref[i] = mujoco.mj_ray(model, data, o[i], u[i], None, 1, -1, one, ref_n[i])
        ref_g[i] = one[0]
    return ref, ref_g, ref_n


def test_rays_grazing_box_edges_report_mujocos_geom():
    """Beams aimed within float32 rounding of box edges, 16-22 m from the origin as in the ring's
    building: mullions (one at a pane's end, the pane abutting its side), a chair seat's lower edge
    and a finite plane's rim, in front of a wall. Embree may miss the box whose edge a beam grazes
    (the ring-windows-float walk's sweeps 345, 479 and 588) where MuJoCo hits it, metres before the
    wall; the BVH caster must report MuJoCo's geom, distance and normal for every beam."""
    spec = mujoco.MjSpec()
    box = mujoco.mjtGeom.mjGEOM_BOX
    spec.worldbody.add_geom(name="wall", type=box, pos=[22.14, 3.92, 1.35], size=[0.06, 6.0, 1.35])
    for k in range(6):
        spec.worldbody.add_geom(type=box, pos=[16.2 + 0.9 * k, 4.0 + 0.5 * k, 1.35], size=[0.025, 0.025 + 0.1 * (k % 3), 1.35])
    # a pane ending exactly at the last mullion's side (x = 21.83292667), as the ring's windows do
    spec.worldbody.add_geom(name="mullion", type=box, pos=[21.85792667, 7.9, 1.35], size=[0.025, 0.025, 1.35])
    spec.worldbody.add_geom(name="pane", type=box, pos=[21.34439, 7.9, 1.35], size=[0.48853667, 0.005, 1.35])
    spec.worldbody.add_geom(name="seat", type=box, pos=[19.69424789, 2.86649411, 0.39], size=[0.23, 0.23, 0.03])
    spec.worldbody.add_geom(name="sign", type=mujoco.mjtGeom.mjGEOM_PLANE, pos=[18.5, 1.0, 1.2], size=[0.3, 0.2, 0.1],
                            quat=[0.7071067811865476, 0.0, 0.7071067811865476, 0.0])  # fmt: skip
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    rng = np.random.default_rng(5)
    n = 6000
    g = rng.integers(1, model.ngeom, n)
    R = data.geom_xmat[g].reshape(-1, 3, 3)
    half = model.geom_size[g].copy()
    half[model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE, 2] = 0.0
    # a point on one of the geom's edges (two local coordinates at +-half, the third anywhere), jittered
    local = rng.uniform(-0.95, 0.95, (n, 3)) * half
    axis = rng.integers(0, 3, n)
    for a in range(3):
        on = axis != a
        local[on, a] = rng.choice([-1.0, 1.0], int(on.sum())) * half[on, a]
    local += rng.uniform(-2e-6, 2e-6, (n, 3))
    p = np.einsum("nij,nj->ni", R, local) + data.geom_xpos[g]
    o = np.column_stack([rng.uniform(10.0, 14.0, n), rng.uniform(5.0, 8.0, n), rng.uniform(0.3, 1.5, n)])
    u = p - o
    u /= np.linalg.norm(u, axis=1)[:, None]
    ref, ref_g, ref_n = _mj_ray_each(model, data, o, u)
    bvh = StaticBvh(model, data, np.arange(model.ngeom), far_m=100.0)
    for nthreads in (1, 2):
        gid, dist, nrm = bvh.cast(o, u, nthreads)
        np.testing.assert_array_equal(gid, ref_g)
        np.testing.assert_array_equal(dist, ref)
        np.testing.assert_array_equal(nrm, ref_n)
    assert np.count_nonzero(ref_g == g) > 0.3 * n  # most beams do meet the edge they aim at


def test_rays_at_the_crease_of_interpenetrating_boxes_report_mujocos_geom():
    """Columns sunk into a wall: where a column's side leaves the wall's face the two surfaces cross
    away from either box's edges, and Embree (float32) may name the wall where MuJoCo hits the
    column's side a micrometre before it. Beams aimed within rounding of those creases must get
    MuJoCo's geom, distance and normal."""
    spec = mujoco.MjSpec()
    box = mujoco.mjtGeom.mjGEOM_BOX
    spec.worldbody.add_geom(name="wall", type=box, pos=[20.0, 4.0, 1.35], size=[0.06, 3.0, 1.35])
    cols = [([19.95 - 0.01 * k, 2.0 + 0.8 * k, 1.35], [0.03 + 0.01 * k, 0.04, 1.35]) for k in range(5)]
    for p, s in cols:
        spec.worldbody.add_geom(type=box, pos=p, size=s)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    rng = np.random.default_rng(8)
    n = 4000
    k = rng.integers(0, len(cols), n)
    p, s = np.array([cols[i][0] for i in k]), np.array([cols[i][1] for i in k])
    aim = np.column_stack([np.full(n, 20.0 - 0.06), p[:, 1] + rng.choice([-1.0, 1.0], n) * s[:, 1], rng.uniform(0.1, 2.6, n)])
    aim[:, :2] += rng.uniform(-3e-6, 3e-6, (n, 2))
    o = np.column_stack([rng.uniform(12.0, 15.0, n), rng.uniform(0.0, 8.0, n), rng.uniform(0.3, 1.5, n)])
    u = aim - o
    u /= np.linalg.norm(u, axis=1)[:, None]
    ref, ref_g, ref_n = _mj_ray_each(model, data, o, u)
    gid, dist, nrm = StaticBvh(model, data, np.arange(model.ngeom), far_m=100.0).cast(o, u, 1)
    np.testing.assert_array_equal(gid, ref_g)
    np.testing.assert_array_equal(dist, ref)
    np.testing.assert_array_equal(nrm, ref_n)
    assert 0.1 * n < np.count_nonzero(ref_g == 0) < 0.9 * n  # both the wall and the columns are hit
