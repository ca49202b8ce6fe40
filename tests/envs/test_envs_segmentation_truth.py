"""Per-pixel segmentation truth (``EpisodeTruth.segmentation``): aligned with the RGB-D frames,
labels consistent with the depth, off by default without changing a frame, kept by sessions."""

from __future__ import annotations

import json

import numpy as np
import pytest

from exobench.core import ConfigError, RgbdFrame, SegmentationTruth
from exobench.envs.sensors import RgbdConfig
from exobench.envs.session import read_session, write_session
from exobench.envs.sim import OfficeScenario, simulate_office
from exobench.envs.sim.scenarios.course import LocomotionScenario, simulate_locomotion

pytestmark = pytest.mark.long(seconds=20)  # the workers take it first (tests/conftest.py); 20: the file at -n 0 in one run at load 12-15, scaled to that run's CPU

# noise-free depth (quantised to 1 mm) so that the measured depth back-projects onto the planes
COURSE = {"width_px": 64, "height_px": 48, "rate_hz": 5.0, "duration_cap_s": 3.0, "pedestrians": 1,
          "depth_noise_scale": 0.0}  # fmt: skip


def _frames(ep) -> list[RgbdFrame]:
    return [f for f in ep.frames if isinstance(f, RgbdFrame)]


@pytest.fixture(scope="module")
def course():
    on = simulate_locomotion(LocomotionScenario.from_dict({**COURSE, "segmentation_truth": True}), 2)
    off = simulate_locomotion(LocomotionScenario.from_dict(COURSE), 2)
    return on, off


@pytest.fixture(scope="module")
def office():
    return simulate_office(OfficeScenario(max_distance_m=0.6, extra_sensors="rgbd_thigh", segmentation_truth=True), 1)


def test_one_truth_per_frame_aligned_with_its_depth(course, office):
    for ep in (course[0], office):
        frames, segs = _frames(ep), ep.truth.segmentation
        assert len(frames) == len(segs) > 0
        for f, s in zip(frames, segs):
            assert isinstance(s, SegmentationTruth) and (s.stamp_s, s.sensor_id) == (f.stamp_s, f.sensor_id)
            for a in (s.surface_id, s.geom_id, s.object_index):
                assert a.shape == f.depth_m.shape and a.dtype == np.int32
            assert np.all(s.surface_id[s.geom_id < 0] == -1)  # background shows no surface


def test_labelled_surface_passes_through_the_back_projected_point(course):
    ep = course[0]
    surfaces = {s.surface_id: s for s in ep.truth.scene.surfaces}
    T_cam, t_cam = ep.truth.extra["camera_T_world"], ep.truth.extra["camera_stamps_s"]
    labelled = valid = 0
    for f, s in zip(_frames(ep), ep.truth.segmentation):
        T = T_cam[int(np.flatnonzero(t_cam == f.stamp_s)[0])]
        v, u = np.nonzero((f.depth_m > 0) & (s.surface_id >= 0))
        z = f.depth_m[v, u].astype(float)
        p_c = np.stack([(u - f.K[0, 2]) / f.K[0, 0] * z, (v - f.K[1, 2]) / f.K[1, 1] * z, z], axis=1)
        p_w = p_c @ T[:3, :3].T + T[:3, 3]
        for sid in np.unique(s.surface_id[v, u]):
            sel = s.surface_id[v, u] == sid
            assert np.abs(surfaces[int(sid)].signed_distance(p_w[sel])).max() < 2e-3  # depth quantised to 1 mm
        labelled += len(u)
        valid += int((f.depth_m > 0).sum())
    assert labelled > 0.5 * valid  # most of what the camera sees is a listed surface


def test_pedestrian_pixels_carry_its_geom(course):
    import mujoco

    from exobench.envs.sim.compose import attached_sites
    from exobench.envs.sim.scenarios.course import _compiled, _world_key, default_rig

    ep = course[0]
    sc = LocomotionScenario.from_dict(ep.scenario)
    heights = tuple(float(h) for h in ep.truth.extra["pedestrian_height_m"])
    model = _compiled(_world_key(sc), sc.exo_spec(), sc.pattern, attached_sites(default_rig(sc)), False, heights).model
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, n) for n in ep.truth.extra["pedestrian_geom_names"][0]]
    assert min(ids) >= 0
    frac = ep.truth.extra["pedestrian_pixel_fraction"][:, 0]  # the camera's own share of those geoms
    assert frac.max() > 0.01
    for j, s in enumerate(ep.truth.segmentation):
        person = np.isin(s.geom_id, ids)
        assert person.mean() == frac[j] and np.all(s.surface_id[person] == -1)


def test_office_objects_are_indexed(office):
    objects = office.truth.scene.objects
    seen = set()
    for s in office.truth.segmentation:
        idx = np.unique(s.object_index)
        assert idx.min() >= -1 and idx.max() < len(objects)
        seen |= {int(i) for i in idx if i >= 0}
    for i in seen:
        assert objects[i]["geom_names"]


def test_off_by_default_and_frames_unchanged(course):
    on, off = course
    assert off.truth.segmentation == () and "segmentation_truth" not in off.scenario
    fa, fb = _frames(on), _frames(off)
    assert len(fa) == len(fb)
    for a, b in zip(fa, fb):
        assert a.stamp_s == b.stamp_s and np.array_equal(a.depth_m, b.depth_m) and np.array_equal(a.rgb, b.rgb)
    with pytest.raises(ConfigError, match="rgbd.segmentation_truth"):
        RgbdConfig(segmentation_truth="yes")


def test_session_round_trip_is_bit_exact(course, office, tmp_path):
    for name, ep in (("course", course[0]), ("office", office)):
        back = read_session(write_session(ep, tmp_path / name)).truth.segmentation
        assert len(back) == len(ep.truth.segmentation)
        for a, b in zip(ep.truth.segmentation, back):
            assert (a.stamp_s, a.sensor_id) == (b.stamp_s, b.sensor_id)
            for n in ("surface_id", "geom_id", "object_index"):
                assert getattr(b, n).dtype == np.int32 and np.array_equal(getattr(a, n), getattr(b, n))
        meta = json.loads((tmp_path / name / "meta.json").read_text())
        assert meta["truth_counts"]["segmentation"] == len(back)
    # a session without the part (or written before it) reads with an empty one
    path = write_session(course[1], tmp_path / "off")
    assert not (path / "truth" / "segmentation").exists()
    assert "segmentation" not in json.loads((path / "meta.json").read_text())["truth_counts"]
    assert read_session(path).truth.segmentation == ()
