"""How the BVH caster batches a sweep's rays (envs/sensors/lidar/optics.py, cast.py, bvh.py).

Each test checks a batching against the sequential computation it replaces: the same frames or hits
bit for bit, and fewer casts (the counts the batching is for).
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np

from exobench.envs.sensors.lidar import LidarConfig, LidarSensor
from exobench.envs.sensors.lidar import bvh as bvh_module
from exobench.envs.sensors.lidar import cast as cast_module
from exobench.envs.sensors.lidar.optics import cast_rays
from exobench.envs.sim.pose import site_pose


def _scene(**office):
    from exobench.models.exo_spec import ExoSpec
    from exobench.models.office import build_office
    from exobench.models.office_params import OfficeParams
    from exobench.models.worlds import compose

    scene = compose(build_office(OfficeParams(**office)), ExoSpec())
    data = mujoco.MjData(scene.model)
    mujoco.mj_forward(scene.model, data)
    return scene.model, data, scene.truth, site_pose(scene.model, data, "lidar_trunk")


_GLAZED = {"facade": "windows", "glass_fraction": 1.0, "partition_glass": "float_glass", "facade_glass": "lowe_glass",
           "polished_fraction": 0.0}  # fmt: skip


def _walking_at(T0, height_m):
    def pose(t):
        T = np.repeat(T0[None], len(t), axis=0)
        T[:, :3, 3] += (0.5 * np.asarray(t))[:, None] * T0[:3, 0]
        T[:, 2, 3] = height_m
        return T

    return pose


def _frame(out):
    scan, lt = out
    return (scan.points_xyz, scan.intensity, lt.true_range_m, lt.hit_w, lt.geom_id, lt.surface_id, lt.kind,
            lt.via_geom_id, lt.signal)  # fmt: skip


def test_a_glazed_sweep_casts_one_batch_per_bounce_level(monkeypatch):
    """A strongest-echo sweep of the glazed office at the lidar-filter loops' height: the pane's
    crossing and mirrored branches share their casts, and a ray crossing a pane is cast from beyond
    its far face in the same batch as from its near one. The frame equals the one cast level by
    level and redo by redo (a caster that cannot tell where a ray leaves its pane), in fewer casts."""
    model, data, truth, T0 = _scene(**_GLAZED)
    pose = _walking_at(T0, 0.68)
    config = LidarConfig(caster="bvh", return_mode="strongest")
    batched = LidarSensor("lidar_trunk", config, model, 5)
    plain = LidarSensor("lidar_trunk", config, model, 5)
    calls: list[int] = []
    secondary = cast_module.RayCaster.secondary

    def counted(self, m, d):
        inner = secondary(self, m, d)

        def cast(o, u):
            calls.append(len(o))
            return inner(o, u)

        if self is batched.caster and getattr(inner, "exit_m", None) is not None:
            cast.exit_m = inner.exit_m
        return cast

    monkeypatch.setattr(cast_module.RayCaster, "secondary", counted)
    a = batched.scan(model, data, pose, 0.0, truth)
    n_batched = len(calls)
    calls.clear()
    b = plain.scan(model, data, pose, 0.0, truth)
    for x, y in zip(_frame(a), _frame(b)):
        np.testing.assert_array_equal(x, y)
    assert np.count_nonzero(a[1].via_geom_id >= 0) > 1000  # the glass paths are exercised
    # a bounce level is one cast: the first glass event's, then (max_interactions - 1) levels of
    # both branches; beams that meet a mirror first follow their own max_interactions levels
    k = config.max_interactions
    assert n_batched <= 2 * k < len(calls)


def test_rays_near_moving_geoms_are_cast_once(monkeypatch):
    """A walking sweep at 0.68 m, between the user's thighs: the rays that may meet a moving or
    curved geom go to ``mj_multiRay`` on those geoms once each (a near pass first cast those without
    a hit within ``cast_near_m`` twice), with the MuJoCo caster's sweep."""
    model, data, truth, T0 = _scene()
    pose = _walking_at(T0, 0.68)
    bvh = LidarSensor("lidar_trunk", LidarConfig(caster="bvh"), model, 2)
    ref = LidarSensor("lidar_trunk", LidarConfig(caster="mujoco"), model, 2)
    sent: list[int] = []
    cast_on_rest: list[int] = []
    multi_ray, multi = mujoco.mj_multiRay, cast_module.RayCaster._multi_ray

    def counting_multi_ray(m, *args):
        if m is bvh.caster._bvh_parts[1].rest.model:
            cast_on_rest.append(int(args[-2]))
        return multi_ray(m, *args)

    def counting_multi(self, model_, data_, jobs, dirs_w, n, max_r, scene=None, **kw):
        if scene is not None:
            sent.append(n)
        return multi(self, model_, data_, jobs, dirs_w, n, max_r, scene=scene, **kw)

    monkeypatch.setattr(mujoco, "mj_multiRay", counting_multi_ray)
    monkeypatch.setattr(cast_module.RayCaster, "_multi_ray", counting_multi)
    a = bvh.scan(model, data, pose, 0.0, truth)
    b = ref.scan(model, data, pose, 0.0, truth)
    for x, y in zip(_frame(a), _frame(b)):
        np.testing.assert_array_equal(x, y)
    assert sum(sent) > 1000  # the thighs' proxies: many rays
    assert sum(cast_on_rest) == sum(sent)


def test_rays_leaving_a_floor_and_panes_equal_mj_ray(monkeypatch):
    """Rays mirrored off surfaces or continuing through them, from 1 um past the surface (as the
    optics send them), in the 80 m corridor of 24 offices: far from the origin float32 rounds the
    start back onto the surface, Embree names the surface just left and the exact test rejects it.
    Such a ray is cast again from just past that hit, with the geoms whose boxes hold the hit point
    judged exactly (``near_hits``), instead of listing its whole path through the building
    (``nearest_listed``, about 1 us a ray). The hits equal ``mj_ray``'s."""
    model, data, truth, T0 = _scene(n_offices=24, corridor_length_m=80.0, **_GLAZED)
    sensor = LidarSensor("lidar_trunk", LidarConfig(caster="bvh"), model, 0)
    rng = np.random.default_rng(3)
    d = rng.normal(size=(4000, 3)) * [1.0, 0.1, 0.1]  # along the corridor, far from the origin
    d /= np.linalg.norm(d, axis=1)[:, None]
    o = np.broadcast_to(T0[:3, 3] + [2.0, 0.0, -0.5], d.shape).copy()  # in the corridor, ahead of the user
    r, g, n = cast_rays(model, data, sensor.group, o, d)
    hit = (g >= 0) & (r > 0)
    p = o[hit] + r[hit, None] * d[hit]
    u = d[hit].copy()
    nv = n[hit]
    mirror = rng.random(len(u)) < 0.5
    u[mirror] -= 2.0 * np.einsum("ij,ij->i", u[mirror], nv[mirror])[:, None] * nv[mirror]
    u /= np.linalg.norm(u, axis=1)[:, None]
    start = p + 1e-6 * u
    r0, g0, n0 = cast_rays(model, data, sensor.group, start, u)
    listed: list[int] = []
    recast: list[int] = []
    kernels = bvh_module.nearest_listed, getattr(bvh_module, "near_hits", None)

    def counting_listed(redo, *args):
        listed.append(len(redo))
        return kernels[0](redo, *args)

    def counting_recast(named, *args):
        recast.append(len(named))
        return kernels[1](named, *args)

    monkeypatch.setattr(bvh_module, "nearest_listed", counting_listed)
    monkeypatch.setattr(bvh_module, "near_hits", counting_recast, raising=False)
    r1, g1, n1 = sensor.caster.secondary(model, data)(start, u)
    np.testing.assert_array_equal(g1, g0)
    np.testing.assert_array_equal(r1, r0)
    np.testing.assert_array_equal(n1, n0)
    assert sum(recast) > 0.05 * len(u)  # the case is exercised: about an eighth of the rays start on their surface
    assert sum(listed) < 0.01 * sum(recast)


def test_a_small_batch_in_a_large_building_goes_through_the_bvh(monkeypatch):
    """``mj_ray`` tests every geom (6.5 us a ray in 24 offices' 834), a BVH batch costs about 0.15 ms
    and 0.6 us a ray: a batch of 40 rays there goes through the BVH (before: up to 71 rays went to
    ``mj_ray``), with the same hits."""
    model, data, _, T0 = _scene(n_offices=24, corridor_length_m=80.0)
    sensor = LidarSensor("lidar_trunk", LidarConfig(caster="bvh"), model, 0)
    rng = np.random.default_rng(8)
    d = rng.normal(size=(40, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    o = np.broadcast_to(T0[:3, 3] + [3.0, 0.0, 0.0], d.shape).copy()  # ahead of the user: no moving geom near
    r0, g0, n0 = cast_rays(model, data, sensor.group, o, d)
    sent: list[int] = []

    def counting(m, dd, gg, oo, uu, flg_static=1):
        sent.append(len(oo))
        return cast_rays(m, dd, gg, oo, uu, flg_static=flg_static)

    monkeypatch.setattr(cast_module, "cast_rays", counting)
    r1, g1, n1 = sensor.caster.secondary(model, data)(o, d)
    np.testing.assert_array_equal(g1, g0)
    np.testing.assert_array_equal(r1, r0)
    np.testing.assert_array_equal(n1, n0)
    assert sum(sent) < 5


def test_rays_sure_to_leave_their_pane_first_are_those_mj_ray_says():
    """``own_first`` (optics' ``_leave`` casts a crossing ray from inside its pane only where it is not
    sure): a ray is sure to meet its pane first, where it leaves it, only if ``mj_ray`` from inside says
    so (the pane at that exact distance). Not sure: rays meeting a box embedded in the pane, a mullion
    through it, or a box abutting its far face that ``mj_ray`` reports first; every ray leaving a pane
    a moving body's box overlaps. Most other rays are sure."""
    spec = mujoco.MjSpec()
    box = mujoco.mjtGeom.mjGEOM_BOX
    x0, t = 20.0, 2.0**-7  # dyadic: the abutting box's near face and the pane's far face tie exactly
    spec.worldbody.add_geom(type=box, size=[2.0**-4, 0.2, 0.2], pos=[x0 + t + 2.0**-4, 0.7, 0.0])  # 0: abutting, first
    spec.worldbody.add_geom(type=box, size=[t, 1.0, 1.0], pos=[x0, 0.0, 0.0])  # 1: the pane
    spec.worldbody.add_geom(type=box, size=[0.003, 0.1, 0.1], pos=[x0, -0.5, 0.0])  # 2: embedded in it
    spec.worldbody.add_geom(type=box, size=[0.03, 0.1, 0.3], pos=[x0, 0.0, 0.6])  # 3: a mullion through it
    spec.worldbody.add_geom(type=box, size=[t, 1.0, 1.0], pos=[x0 + 2.0, 0.0, 0.0])  # 4: a second pane
    spec.worldbody.add_geom(type=box, size=[0.1, 2.0, 2.0], pos=[x0 + 5.0, 0.0, 0.0])  # 5: a wall behind
    walker = spec.worldbody.add_body(pos=[x0 + 2.0, 0.5, 0.5], mocap=True)
    walker.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.05, 0, 0])  # 6: moving, overlapping the second pane
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    group = np.ones(6, dtype=np.uint8)
    cast = cast_module.RayCaster(LidarConfig(caster="bvh"), group, -1).secondary(model, data)
    rng = np.random.default_rng(9)
    n = 6000
    own = np.where(rng.random(n) < 0.75, 1, 4)
    o = np.column_stack([x0 + 2.0 * (own == 4) - t + 1e-6, rng.uniform(-0.95, 0.95, n), rng.uniform(-0.95, 0.95, n)])
    d = np.column_stack([np.ones(n), rng.normal(scale=0.3, size=n), rng.normal(scale=0.3, size=n)])
    d /= np.linalg.norm(d, axis=1)[:, None]
    x = cast.exit_m(o, d, own)
    assert np.all(x > 0.0)
    sure = cast.own_first(o, d, own, x)
    r0, g0, _ = cast_rays(model, data, group, o, d)
    first = (g0 == own) & (r0 == x)
    assert not np.any(sure & ~first)  # never sure where mj_ray meets another geom first
    assert not np.any(sure[own == 4])  # the moving body's box overlaps that pane
    # each case occurs (the abutting box wins its ties: its id is lower; the mullion's side is met within
    # the pane only by rays starting within a few millimetres of it)
    for g, least in ((0, 10), (2, 10), (3, 1)):
        assert np.count_nonzero((own == 1) & (g0 == g)) >= least
    assert np.count_nonzero((g0 == 0) & (r0 == x)) > 10  # ties with the pane's far face
    assert np.count_nonzero(sure) > 0.9 * np.count_nonzero(first & (own == 1))


def test_a_recast_judges_the_geoms_met_within_its_shift():
    """A ray leaving a slab through its face, with thin boxes just past that face, nearer than the
    recast's shift (:func:`bvh._recast` starts Embree 50 um past the rejected hit), and a box
    abutting the face (the ray starts in it): Embree from the shifted start cannot name the boxes
    behind it, which ``near_hits`` judges exactly. Each ray's hit equals ``mj_ray``'s."""
    spec = mujoco.MjSpec()
    x0 = 40.0  # far from the origin: float32 rounds a start 1 um past the face back onto it
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.005, 1.0, 1.0], pos=[x0 - 0.005, 0.0, 0.0])
    for k, gap in enumerate((2e-5, 3.5e-5, 4.9e-5)):  # foils 10 um thick, their near faces within the shift
        spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[5e-6, 0.1, 0.1],
                                pos=[x0 + gap + 5e-6, -0.6 + 0.4 * k, 0.3])  # fmt: skip
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.2, 0.1, 0.1], pos=[x0 + 0.2, 0.6, -0.5])
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.1, 2.0, 2.0], pos=[x0 + 3.0, 0.0, 0.0])
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    rng = np.random.default_rng(5)
    n = 2000
    p = np.column_stack([np.full(n, x0), rng.uniform(-0.9, 0.9, n), rng.uniform(-0.9, 0.9, n)])
    u = np.column_stack([np.ones(n), rng.normal(scale=0.2, size=n), rng.normal(scale=0.2, size=n)])
    u /= np.linalg.norm(u, axis=1)[:, None]
    start = p + 1e-6 * u
    r0, g0, n0 = cast_rays(model, data, np.ones(6, dtype=np.uint8), start, u)
    bvh = bvh_module.StaticBvh(model, data, np.arange(model.ngeom), far_m=100.0)
    g1, r1, n1 = bvh.cast(start, u, 1, inside=True)
    np.testing.assert_array_equal(g1, g0)
    np.testing.assert_array_equal(r1, r0)
    np.testing.assert_array_equal(n1, n0)
    assert np.count_nonzero((g0 >= 1) & (g0 <= 3)) > 20  # the foils within the shift are hit
    assert np.count_nonzero(g0 == 4) > 20  # and the box the rays start in


def test_secondary_rays_use_the_primary_casts_proxies(monkeypatch):
    """A sweep's secondary rays are tested against the proxies its primary cast built (one Embree
    scene a sweep, not two) and the sensor's own body, which the primary rays exclude, in a compiled
    slab loop: rays aimed at that body from around it hit it as ``mj_ray`` says, and a glazed
    sweep equals the MuJoCo caster's."""
    model, data, truth, T0 = _scene(**_GLAZED)
    pose = _walking_at(T0, 0.68)
    config = LidarConfig(caster="bvh", return_mode="strongest")
    sensor = LidarSensor("lidar_trunk", config, model, 4)
    built: list[int] = []
    casters: list[object] = []
    proxies_init, secondary = bvh_module.Proxies.__init__, cast_module.RayCaster.secondary

    def counted_init(self, m, d, geoms):
        built.append(len(geoms))
        proxies_init(self, m, d, geoms)

    def kept(self, m, d):
        inner = secondary(self, m, d)
        if self is sensor.caster:
            casters.append(inner)
        return inner

    monkeypatch.setattr(bvh_module.Proxies, "__init__", counted_init)
    monkeypatch.setattr(cast_module.RayCaster, "secondary", kept)
    a = sensor.scan(model, data, pose, 0.0, truth)
    assert len(built) == 1  # the primary cast's; the secondary batches (thousands of rays) reuse it
    b = LidarSensor("lidar_trunk", dataclasses.replace(config, caster="mujoco"), model, 4).scan(model, data, pose, 0.0, truth)
    for x, y in zip(_frame(a), _frame(b)):
        np.testing.assert_array_equal(x, y)
    # rays from around the sensor's own body towards its geoms (the primary proxies do not hold them)
    own = sensor.caster._bvh_parts[1].own_others
    assert len(own) > 0
    rng = np.random.default_rng(7)
    target = np.asarray(data.geom_xpos)[rng.choice(own, 600)] + rng.normal(scale=0.03, size=(600, 3))
    start = target + rng.normal(size=(600, 3)) * 0.5
    u = target - start
    u /= np.linalg.norm(u, axis=1)[:, None]
    r0, g0, n0 = cast_rays(model, data, sensor.group, start, u)
    r1, g1, n1 = casters[-1](start, u)
    np.testing.assert_array_equal(g1, g0)
    np.testing.assert_array_equal(r1, r0)
    np.testing.assert_array_equal(n1, n0)
    assert np.count_nonzero(np.isin(g0, own)) > 100  # the own body is hit


def test_secondary_rays_near_moving_geoms_cast_on_them_alone(monkeypatch):
    """Secondary rays that may meet a moving geom (the user's legs) but no static curved one are cast
    by ``mj_ray`` on the moving geoms alone (``flg_static`` 0), the nearer of that and the BVH's static
    hit kept; those that may meet a static curved geom by ``mj_ray`` on every geom. Rays aimed at the
    legs, at static curved geoms and at both from around them hit what ``mj_ray`` says, and a glazed
    sweep between the thighs equals the MuJoCo caster's."""
    model, data, truth, T0 = _scene(**_GLAZED)
    pose = _walking_at(T0, 0.68)
    config = LidarConfig(caster="bvh", return_mode="strongest")
    sensor = LidarSensor("lidar_trunk", config, model, 6)
    moving_only: list[int] = []
    every: list[int] = []
    casters: list[object] = []
    ray_cast, secondary = cast_module.cast_rays, cast_module.RayCaster.secondary

    def counted(m, d, g, o, u, flg_static=1):
        (every if flg_static else moving_only).append(len(o))
        return ray_cast(m, d, g, o, u, flg_static=flg_static)

    def kept(self, m, d):
        inner = secondary(self, m, d)
        if self is sensor.caster:
            casters.append(inner)
        return inner

    monkeypatch.setattr(cast_module, "cast_rays", counted)
    monkeypatch.setattr(cast_module.RayCaster, "secondary", kept)
    a = sensor.scan(model, data, pose, 0.0, truth)
    b = LidarSensor("lidar_trunk", dataclasses.replace(config, caster="mujoco"), model, 6).scan(model, data, pose, 0.0, truth)
    for x, y in zip(_frame(a), _frame(b)):
        np.testing.assert_array_equal(x, y)
    assert sum(moving_only) > 100  # the secondary rays near the legs
    # rays from around moving and static curved geoms towards them, in one batch (beyond mj_ray's small batches)
    parts = sensor.caster._bvh_parts[1]
    curved = parts.curved.geom
    moving = np.setdiff1d(parts.others, curved)
    assert len(curved) > 0 and len(moving) > 0
    rng = np.random.default_rng(11)
    geoms = np.concatenate([rng.choice(moving, 400), rng.choice(curved, 400)])
    target = np.asarray(data.geom_xpos)[geoms] + rng.normal(scale=0.02, size=(800, 3))
    start = target + rng.normal(size=(800, 3)) * 0.6
    u = target - start
    u /= np.linalg.norm(u, axis=1)[:, None]
    r0, g0, n0 = ray_cast(model, data, sensor.group, start, u)
    moving_only.clear()
    every.clear()
    r1, g1, n1 = casters[-1](start, u)
    np.testing.assert_array_equal(g1, g0)
    np.testing.assert_array_equal(r1, r0)
    np.testing.assert_array_equal(n1, n0)
    assert np.count_nonzero(np.isin(g0, moving)) > 100 and np.count_nonzero(np.isin(g0, curved)) > 100
    assert sum(moving_only) > 100 and sum(every) > 100
