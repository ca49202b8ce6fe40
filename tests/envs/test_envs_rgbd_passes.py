"""RGB-D rendering in two passes (depth with the geom ids when asked, then colour): the same
images bit for bit as the three passes of before (benchmarks/bench/render_baseline.py, run in the
same test), on a course walk and an office walk; geom ids only when something reads them."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from exobench.benchmarks.bench.render_baseline import ThreePassCamera, three_pass_rendering
from exobench.core import RgbdFrame
from exobench.envs.sensors.rgbd import RgbdCamera, RgbdConfig
from exobench.envs.sensors.rgbd.render import RgbdRenderer
from exobench.envs.sim import OfficeScenario, simulate_office
from exobench.envs.sim.rig import camera_rig
from exobench.envs.sim.scenarios.course import LocomotionScenario, simulate_locomotion
from exobench.models import worlds
from exobench.models.exo_spec import ExoSpec

pytestmark = pytest.mark.long(seconds=8)  # the workers take it first (tests/conftest.py); 8: the file at -n 0 in one run at load 12-15, scaled to that run's CPU

# a person crosses the view, so that the geom ids show more than the course
COURSE = {"width_px": 64, "height_px": 48, "rate_hz": 5.0, "duration_cap_s": 3.0, "pedestrians": 1}
# the office walk with the thigh camera alone: no LiDAR to cast; the baseline renders the glass
# panes' depth (mujoco.Renderer), as the two passes do without depth_through_glass
OFFICE_RIG = camera_rig("thigh", RgbdConfig(width_px=96, height_px=72, rate_hz=10.0, depth_through_glass=False))


def _rgbd(ep) -> list[RgbdFrame]:
    return [f for f in ep.frames if isinstance(f, RgbdFrame)]


def _both(simulate):
    """The episode rendered in two passes and with the three-pass baseline."""
    new = simulate()
    with three_pass_rendering():
        old = simulate()
    return new, old


@pytest.fixture(scope="module")
def walks():
    course = _both(lambda: simulate_locomotion(LocomotionScenario.from_dict({**COURSE, "segmentation_truth": True}), 2))
    office = _both(lambda: simulate_office(OfficeScenario(max_distance_m=0.6, segmentation_truth=True), 1, rig=OFFICE_RIG))
    return {"course": course, "office": office}


@pytest.mark.parametrize("walk", ["course", "office"])
def test_two_passes_give_the_three_pass_images_bit_for_bit(walks, walk):
    new, old = walks[walk]
    fn, fo = _rgbd(new), _rgbd(old)
    assert len(fn) == len(fo) > 3
    for a, b in zip(fn, fo):
        assert (a.stamp_s, a.sensor_id) == (b.stamp_s, b.sensor_id)
        assert a.rgb.dtype == b.rgb.dtype and a.depth_m.dtype == b.depth_m.dtype
        np.testing.assert_array_equal(a.rgb, b.rgb)
        np.testing.assert_array_equal(a.depth_m, b.depth_m)
        assert a.rgb.flags.c_contiguous and a.depth_m.flags.c_contiguous
    assert len(new.truth.segmentation) == len(old.truth.segmentation) == len(fn)
    for a, b in zip(new.truth.segmentation, old.truth.segmentation):
        for name in ("geom_id", "surface_id", "object_index"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert any((s.geom_id >= 0).mean() > 0.5 for s in new.truth.segmentation)  # the ids show the scene
    if walk == "course":
        frac = new.truth.extra["pedestrian_pixel_fraction"]
        np.testing.assert_array_equal(frac, old.truth.extra["pedestrian_pixel_fraction"])
        assert frac.max() > 0.01  # the person is in view: the ids are not all the course's


@pytest.fixture()
def passes(monkeypatch):
    """Counts of mjr_render calls and of mjr_readPixels calls that read an image (ids or colour)."""
    count = {"render": 0, "read": 0, "read_rgb": 0}
    render, read = mujoco.mjr_render, mujoco.mjr_readPixels

    def counted_render(*args):
        count["render"] += 1
        return render(*args)

    def counted_read(rgb, depth, *args):
        count["read"] += 1
        count["read_rgb"] += rgb is not None
        return read(rgb, depth, *args)

    monkeypatch.setattr(mujoco, "mjr_render", counted_render)
    monkeypatch.setattr(mujoco, "mjr_readPixels", counted_read)
    return count


@pytest.fixture(scope="module")
def stairs():
    scene = worlds.compose(worlds.build_staircase(worlds.StaircaseParams(position_m=(1.0, 0.0))), ExoSpec())
    data = mujoco.MjData(scene.model)
    mujoco.mj_forward(scene.model, data)
    return scene.model, data


@pytest.mark.parametrize("segmentation", [False, True])
def test_a_frame_is_two_passes_with_or_without_geom_ids(stairs, passes, segmentation):
    model, data = stairs
    config = RgbdConfig(width_px=160, height_px=120)
    with RgbdCamera("rgbd_chest", config, model, seed=0, segmentation=segmentation) as cam:
        passes.update(render=0, read=0, read_rgb=0)  # what making the context drew does not count
        for k in range(3):
            cam.capture(model, data, k / 30.0)
    # depth (and the ids, read in the same call) from one pass, colour from the other
    assert passes == {"render": 6, "read": 6, "read_rgb": 6 if segmentation else 3}


def test_without_geom_ids_colour_and_depth_are_those_of_the_baseline(stairs):
    model, data = stairs
    config = RgbdConfig(width_px=160, height_px=120)
    with RgbdCamera("rgbd_chest", config, model, seed=4) as cam, ThreePassCamera("rgbd_chest", config, model, seed=4) as ref:
        assert not cam.segmentation  # nothing asked for them
        (f, t), (g, u) = cam.capture(model, data, 0.0), ref.capture(model, data, 0.0)
    np.testing.assert_array_equal(f.rgb, g.rgb)
    np.testing.assert_array_equal(f.depth_m, g.depth_m)
    np.testing.assert_array_equal(t["depth_m"], u["depth_m"])
    assert (t["geom_id"] == -1).all() and (u["geom_id"] >= 0).mean() > 0.5


def test_a_recording_renders_geom_ids_only_for_a_consumer(monkeypatch):
    """A course walk without pedestrians or segmentation truth reads no ids; with a pedestrian,
    whose image share the episode reports, every frame's ids are read, and the share is the
    baseline's (which always rendered them)."""
    labelled = {"n": 0}
    geom_ids = RgbdRenderer._geom_ids

    def counted(self, colours):
        labelled["n"] += 1
        return geom_ids(self, colours)

    monkeypatch.setattr(RgbdRenderer, "_geom_ids", counted)
    plain = simulate_locomotion(LocomotionScenario.from_dict({**COURSE, "pedestrians": 0, "duration_cap_s": 2.0}), 2)
    assert labelled["n"] == 0 and len(_rgbd(plain)) > 0
    walk = simulate_locomotion(LocomotionScenario.from_dict(COURSE), 2)
    n_cam = len(walk.truth.extra["camera_stamps_s"])
    assert labelled["n"] == n_cam > 0
    with three_pass_rendering():
        ref = simulate_locomotion(LocomotionScenario.from_dict(COURSE), 2)
    np.testing.assert_array_equal(walk.truth.extra["pedestrian_pixel_fraction"], ref.truth.extra["pedestrian_pixel_fraction"])
    assert walk.truth.extra["pedestrian_pixel_fraction"].max() > 0.01


def test_the_depth_pass_draws_single_sample_and_the_colour_pass_with_the_models_samples(stairs, monkeypatch):
    """MuJoCo draws the segmentation-mode pass with multisampling off, so the depth pass gets a
    single-sample buffer without a shadow map (nothing to resolve); the colour pass keeps the
    model's multisampled buffer and its shadow map, each exactly the image's size."""
    model, data = stairs
    config = RgbdConfig(width_px=160, height_px=120)
    seen = []
    render = mujoco.mjr_render
    segment = int(mujoco.mjtRndFlag.mjRND_SEGMENT)

    def spy(rect, scene, con):
        seen.append((bool(scene.flags[segment]), con.offSamples, bool(con.shadowFBO), con.offWidth, con.offHeight))
        return render(rect, scene, con)

    monkeypatch.setattr(mujoco, "mjr_render", spy)
    with RgbdCamera("rgbd_chest", config, model, seed=0, segmentation=True) as cam:
        for k in range(2):
            cam.capture(model, data, k / 30.0)
    assert model.vis.quality.offsamples == 4 and model.vis.quality.shadowsize > 0  # the model is left as it was
    assert seen == [(True, 0, False, 160, 120), (False, 4, True, 160, 120)] * 2


def test_with_shadows_colour_depth_and_geom_ids_are_those_of_the_baseline(stairs):
    """The colour pass casts shadows from its own context's shadow map (the depth pass's has none)."""
    model, data = stairs
    lit, shaded = (RgbdConfig(width_px=160, height_px=120, shadows=s) for s in (False, True))
    with RgbdCamera("rgbd_chest", shaded, model, seed=4, segmentation=True) as cam, \
            ThreePassCamera("rgbd_chest", shaded, model, seed=4) as ref, RgbdCamera("rgbd_chest", lit, model, seed=4) as flat:  # fmt: skip
        (f, t), (g, u), (h, _) = cam.capture(model, data, 0.0), ref.capture(model, data, 0.0), flat.capture(model, data, 0.0)
    assert (f.rgb != h.rgb).any()  # the shadows show
    np.testing.assert_array_equal(f.rgb, g.rgb)
    np.testing.assert_array_equal(f.depth_m, g.depth_m)
    np.testing.assert_array_equal(t["depth_m"], u["depth_m"])
    np.testing.assert_array_equal(t["geom_id"], u["geom_id"])


def test_a_model_without_multisampling_renders_both_passes_in_one_context():
    scene = worlds.compose(worlds.build_staircase(worlds.StaircaseParams(position_m=(1.0, 0.0))), ExoSpec())
    model = scene.model
    model.vis.quality.offsamples = 0
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    config = RgbdConfig(width_px=96, height_px=72)
    with RgbdCamera("rgbd_chest", config, model, seed=2, segmentation=True) as cam, \
            ThreePassCamera("rgbd_chest", config, model, seed=2) as ref:  # fmt: skip
        assert cam.renderer._depth_con is cam.renderer._con and cam.renderer._con.offSamples == 0
        (f, t), (g, u) = cam.capture(model, data, 0.0), ref.capture(model, data, 0.0)
    np.testing.assert_array_equal(f.rgb, g.rgb)
    np.testing.assert_array_equal(f.depth_m, g.depth_m)
    np.testing.assert_array_equal(t["geom_id"], u["geom_id"])
    cam.close()  # closing twice frees nothing twice
