"""Conformance of every registered piece, driven by the registries (as dm_control's suite test).

A pipeline, a track or a gymnasium environment is covered here the moment it is registered
(the default registries: built-ins and installed entry points; and the toy track of
``docs/adding-a-track.md``, ``tests/toy_track.py``, with its pipeline):

- every pipeline, on its track's smoke episode (``Track.smoke_scenario``, seed 0): the default
  config is valid and saved whole as JSON, it returns the track's ``estimate_type``, the same
  frames give the same scores (timings aside; a pipeline that declares ``deterministic = False``,
  :func:`exobench.core.pipeline.is_deterministic`, is not compared but its run is marked so),
  it survives a frame with no return, one with NaN
  and a dropped frame in every stream (:func:`exobench.core.faults.inject_faults`) and still
  returns its estimate type with well-formed scores; fed in every stream a frame removed, one
  with NaN, one with values no sensor can report (ranges of 1e308 m, LiDAR points at 1e6 m and
  at the origin, depth of 1e6 m, IMU values of 1e308, ...), one repeated and one out of order
  (:func:`exobench.core.faults.inject_stream_faults`), it counts each in the one vocabulary of
  :mod:`exobench.core.counters`, per kind, exactly for the streams it reads (the same check for
  every pipeline); it refuses something that is not a frame
  (:class:`FrameTypeError`) and ``process`` before ``reset`` (:class:`PipelineStateError`); and
  it refuses an unknown config key;
- every track: its smoke episode carries only its declared streams, every case of every suite
  validates and case names are unique per suite, a failed episode and a bad estimate are scored
  well-formed with the reason, the summary rows and the published references name metrics the
  scorer gives, groups its suites have and pipelines that serve it;
- every sensor kind: both of its records are registered whole (the core record of its frames
  and its adapter and codec, :func:`exobench.envs.sensors.kinds.registration_problems`), and on
  the frames it recorded in a smoke episode its fault forms, NaN-value counter, absurd-value rule
  and codec do what they promise (``tests/kind_conformance.py``, which the toy sensor passes too);
- every gymnasium environment whose id starts with ``exobench/`` passes gymnasium's ``check_env``.

Every sensor kind's session round trip on its codec's example frame is in
``test_session_codecs.py``, driven by the same table.
Each smoke episode is simulated once per test session and each pipeline's clean run is kept.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import tempfile
import warnings
from collections.abc import Mapping
from typing import Any

import gymnasium
import numpy as np
import pytest
from kind_conformance import kind_problems
from orbslam3_support import vocabulary as small_orb_vocabulary
from toy_track import ToyScale, ToyScaleTrack
from vio_pipeline import StillCamera

import exobench.envs  # noqa: F401  (registers the gymnasium environments)
from exobench.benchmarks.registry import build_registry
from exobench.benchmarks.results import json_safe
from exobench.benchmarks.runner import PipelineRun, plan_run, run_pipelines, untimed_metrics
from exobench.benchmarks.tracks.registry import build_track_registry
from exobench.benchmarks.tracks.spec import headline_rows
from exobench.core.counters import FrameCounts, stream_rates
from exobench.core.errors import FrameTypeError, PipelineStateError, UnknownNameError
from exobench.core.faults import STREAM_FAULTS, inject_faults, inject_stream_faults, n_absurd_points
from exobench.core.frames import LidarScan, RgbdFrame
from exobench.core.kinds import FRAME_TYPES, frame_kind
from exobench.core.pipeline import is_deterministic
from exobench.envs.sensors.kinds import SENSOR_KINDS, registration_problems

pytestmark = pytest.mark.long(seconds=102)  # the workers take it first (tests/conftest.py); 102: the file's CPU-s alone at -n 0 (103.5 before this branch, at load ~13)

# built once, at collection, with the toy track of docs/adding-a-track.md (tests/toy_track.py)
# beside the registered ones: it passes what they pass. A registration a test makes later (such
# as the toy of test_benchmarks_track_registry.py, which rebuilds the default registries) is not
# picked up.
PIPELINE_REGISTRY = build_registry()
PIPELINE_REGISTRY.register("toy-scale", ToyScale)
PIPELINE_REGISTRY.register("vio-still", StillCamera)  # the zero-motion vio pipeline of the track's tests (tests/vio_pipeline.py)
TRACK_REGISTRY = build_track_registry()
TRACK_REGISTRY.register("toy-scale", ToyScaleTrack)
PIPELINES = PIPELINE_REGISTRY.names()
TRACKS = TRACK_REGISTRY.names()
GYM_IDS = sorted(k for k in gymnasium.registry if k.startswith("exobench/"))
REASON = "conformance: pipeline raised RuntimeError: boom"

# What the harness gives a pipeline in place of a default that takes long to build, and nothing
# else: orb-slam3's default vocabulary is rendered and clustered from 510 images on first use (30 s
# to 2 min here, by the load; benchmarks/orbvoc.py); a small one of another walk (tests/orbslam3_support.py, about 60
# images) serves a 3 s episode, as frame-to-frame tracking does not use the vocabulary.
_VOCAB_DIR = tempfile.TemporaryDirectory(prefix="exobench-conformance-")
HARNESS_CONFIG = {"orb-slam3": lambda: {"vocabulary": str(small_orb_vocabulary(_VOCAB_DIR.name))}}


def _track(name: str) -> Any:
    return TRACK_REGISTRY.get(name)


@functools.cache
def smoke_episode(track_name: str) -> Any:
    """The track's smoke episode (its ``smoke_scenario``, seed 0), simulated once per session."""
    track = _track(track_name)
    return track.simulate(track.validate_scenario(track.smoke_scenario), 0)


def _make(name: str) -> Any:
    """A default-config instance of the pipeline (with :data:`HARNESS_CONFIG`'s values)."""
    given = HARNESS_CONFIG.get(name)
    return PIPELINE_REGISTRY.make(name, PIPELINE_REGISTRY.make_config(name, given() if given else {}))


def _run(name: str, frames: tuple) -> Any:
    """Feed ``frames`` to a fresh default-config instance of the pipeline, as the runner does."""
    pipe = _make(name)
    pipe.reset(smoke_episode(pipe.track).calibration)
    for frame in frames:
        pipe.process(frame)
    return pipe.finalize()


@functools.cache
def clean_run(name: str) -> tuple[Any, dict[str, Any]]:
    """(estimate, metrics) of the pipeline on its track's smoke episode, run once per session."""
    track_name = PIPELINE_REGISTRY.load(name).track
    episode = smoke_episode(track_name)
    estimate = _run(name, episode.frames)
    return estimate, _track(track_name).score(episode, estimate)


def _same(a: Any, b: Any) -> bool:
    """Equal, NaN equal to NaN, recursively over dicts, lists and arrays."""
    if isinstance(a, Mapping) and isinstance(b, Mapping):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.shape(a) == np.shape(b) and bool(np.array_equal(a, b, equal_nan=True))
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return type(a) is type(b) and a == b


def _plain(value: Any, where: str) -> None:
    """Fail unless ``value`` holds only what a results.jsonl line stores as it is: dicts with
    string keys, lists and tuples, None, bool, int, float, str and numpy numbers (which
    ``json_safe`` converts); anything else would be stored as its ``str``."""
    if isinstance(value, Mapping):
        for k, v in value.items():
            assert isinstance(k, str), f"{where}: key {k!r} is not a string"
            _plain(v, f"{where}.{k}")
    elif isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            _plain(v, f"{where}[{i}]")
    else:
        ok = (type(None), bool, int, float, str, np.bool_, np.integer, np.floating)
        assert isinstance(value, ok), f"{where}: {type(value).__name__} is not a JSON value"


def _well_formed(metrics: Any, where: str) -> None:
    """A non-empty dict of plain values with a boolean ``failed``, storable as a results.jsonl line."""
    assert isinstance(metrics, dict) and metrics, f"{where}: metrics are not a non-empty dict"
    _plain(metrics, where)
    assert isinstance(metrics.get("failed"), (bool, np.bool_)), f"{where}: no boolean 'failed'"
    json.dumps(json_safe(metrics), allow_nan=False)


def _failed_with(metrics: dict[str, Any], reason: str, where: str) -> None:
    _well_formed(metrics, where)
    assert metrics["failed"], f"{where}: not marked failed"
    assert reason in str(metrics.get("failed_reason")), f"{where}: the reason is not carried"


# ------------------------------------------------------------------ pipelines


def test_every_pipeline_serves_a_registered_track():
    assert PIPELINES, "no pipeline registered"
    for name in PIPELINES:
        assert PIPELINE_REGISTRY.load(name).track in TRACKS, name


@pytest.mark.parametrize("name", PIPELINES)
def test_pipeline_default_config_is_valid_and_saved_whole(name):
    cls = PIPELINE_REGISTRY.load(name)
    cfg = PIPELINE_REGISTRY.make_config(name, {})
    assert _same(dataclasses.asdict(cfg), dataclasses.asdict(cls.Config()))
    PIPELINE_REGISTRY.make(name, cfg)
    raw = dataclasses.asdict(cfg)
    _plain(raw, f"{name}.Config")
    saved = json.loads(json.dumps(PipelineRun(name, "", cfg).config_dict(), allow_nan=False))
    assert _same(saved, json.loads(json.dumps(raw))), f"{name}: the saved config differs from the config (NaN or inf?)"


@pytest.mark.parametrize("name", PIPELINES)
def test_pipeline_returns_its_estimate_type_and_is_deterministic(name):
    cls = PIPELINE_REGISTRY.load(name)
    track = _track(cls.track)
    estimate, metrics = clean_run(name)
    assert isinstance(estimate, track.estimate_type), f"{name} returned {type(estimate).__name__}"
    _well_formed(metrics, name)
    assert not metrics["failed"], f"{name} failed on the smoke episode: {metrics.get('failed_reason')}"
    if not is_deterministic(cls):
        # declared not bit-reproducible: not compared, and a run says so in its configuration
        # (and records and report, tests/benchmarks/test_benchmarks_runner.py)
        plan = plan_run(cls.track, pipelines=[name], registry=PIPELINE_REGISTRY)
        assert [p.deterministic for p in plan.pipelines] == [False], f"{name}: its run is not marked"
        assert plan.run_config()["pipelines"][0].get("deterministic") is False, f"{name}: its run config is not marked"
        return
    again = track.score(smoke_episode(cls.track), _run(name, smoke_episode(cls.track).frames))
    first, second = untimed_metrics(track, metrics), untimed_metrics(track, again)
    diff = sorted(k for k in first.keys() | second.keys() if not _same(first.get(k), second.get(k)))
    assert not diff, f"{name} is not deterministic: {diff}"


@pytest.mark.parametrize("name", PIPELINES)
def test_pipeline_survives_no_return_nan_and_dropped_frames(name):
    cls = PIPELINE_REGISTRY.load(name)
    track = _track(cls.track)
    episode = smoke_episode(cls.track)
    faulty = inject_faults(episode.frames)
    kinds = {frame_kind(f) for f in episode.frames}
    # a session mark starts each session of a multi-session episode: two sessions, two marks
    streams = {f.sensor_id for f in episode.frames if frame_kind(f) != "session"}
    assert len(episode.frames) - len(faulty) == len(streams), "a stream had < 4 frames"
    # a pipeline that is not deterministic (ORB-SLAM3's threads) may start its map or not on the
    # same frames: it gets three tries to give a scored estimate; every try must not raise
    reasons = []
    for _ in range(1 if is_deterministic(cls) else 3):
        estimate = _run(name, faulty)  # must not raise
        assert isinstance(estimate, track.estimate_type), f"{name} returned {type(estimate).__name__} on faulty frames"
        # scored as the runner would score a session holding these frames
        metrics = track.score(dataclasses.replace(episode, frames=faulty), estimate)
        _well_formed(metrics, f"{name} on faulty frames ({sorted(kinds)})")
        if not metrics["failed"]:
            break
        reasons.append(metrics.get("failed_reason"))
    assert not metrics["failed"], f"{name} on faulty frames: {reasons}"
    missing = {r.metric for r in track.summary_rows()} - set(metrics)
    assert not missing, f"{name} on faulty frames: no {sorted(missing)}"


def _n_values(frame: Any) -> int:
    """The values a frame holds as the counters count them: points, pixels, else one."""
    if isinstance(frame, LidarScan):
        return len(np.asarray(frame.points_xyz).reshape(-1, 3))
    return int(np.asarray(frame.depth_m).size) if isinstance(frame, RgbdFrame) else 1


def _kind_counts(estimate: Any, where: str) -> dict[str, FrameCounts]:
    counts = getattr(estimate, "counts", None)
    assert isinstance(counts, dict) and counts, f"{where}: the estimate carries no input counters"
    assert all(k in FRAME_TYPES and isinstance(c, FrameCounts) for k, c in counts.items()), f"{where}: {counts}"
    return counts


@pytest.mark.parametrize("name", PIPELINES)
def test_pipeline_counts_every_fault_it_is_fed(name):
    """One vocabulary for every pipeline: fed its smoke episode with, in every stream, a frame
    removed, one with NaN, one absurd, one repeated and one out of order
    (:func:`exobench.core.faults.inject_stream_faults`), it counts exactly those of the streams
    it reads, per kind; every frame of a stream it does not read is ignored."""
    cls = PIPELINE_REGISTRY.load(name)
    track = _track(cls.track)
    episode = smoke_episode(cls.track)
    clean = _kind_counts(clean_run(name)[0], f"{name} (clean)")
    for kind, c in clean.items():  # the simulator delivers none of these
        assert (c.nan, c.absurd, c.repeated, c.out_of_order) == (0, 0, 0, 0), f"{name}: clean {kind}: {c}"
    frames, injected = inject_stream_faults(episode.frames)
    estimate = _run(name, frames)  # must not raise
    assert isinstance(estimate, track.estimate_type), f"{name} returned {type(estimate).__name__} on faulty frames"
    _well_formed(track.score(dataclasses.replace(episode, frames=frames), estimate), f"{name} on faulty frames")
    counts = _kind_counts(estimate, name)
    rates = stream_rates(episode.calibration)
    read_faulty = 0
    for kind in {frame_kind(f) for f in frames}:
        read = set(clean[kind].sensors) if kind in clean else set()
        mine = [f for f in frames if frame_kind(f) == kind]
        made = {fault: [f for sid in read for f in injected.get(sid, {}).get(fault, ())] for fault in STREAM_FAULTS}
        want = {fault: len(fs) for fault, fs in made.items()}
        # a late frame leaves a gap when the next one arrives: dropped too, where the rate is known
        want["dropped"] = clean[kind].dropped + sum(2 * len(injected[sid]["dropped"]) for sid in read if sid in injected and sid in rates)
        # every value of a NaN frame is NaN; an absurd LiDAR sweep has every other point absurd
        want["nan_values"] = sum(_n_values(f) for f in made["nan"])
        want["absurd_values"] = sum(n_absurd_points(f) if isinstance(f, LidarScan) else _n_values(f) for f in made["absurd"])
        c = counts.get(kind, FrameCounts())
        got = {fault: getattr(c, fault) for fault in want}
        assert got == want, f"{name}, {kind} (reads {sorted(read)}): counted {got}, injected {want}"
        assert c.seen == len(mine) and c.ignored == sum(f.sensor_id not in read for f in mine), f"{name}, {kind}: {c}"
        assert c.used + c.ignored + c.repeated + c.out_of_order <= c.seen, f"{name}, {kind}: {c}"
        read_faulty += sum(want[f] for f in ("nan", "absurd", "repeated", "out_of_order"))
    assert read_faulty, f"{name}: no fault in a stream it reads"


@pytest.mark.parametrize("name", PIPELINES)
def test_pipeline_refuses_what_is_not_a_frame(name):
    pipe = _make(name)
    pipe.reset(smoke_episode(pipe.track).calibration)
    for bad in ({"stamp_s": 0.0, "sensor_id": "tof_r_lat", "range_m": 0.3}, None, "tof_r_lat"):
        with pytest.raises(FrameTypeError, match=type(bad).__name__) as err:
            pipe.process(bad)
        assert isinstance(err.value, TypeError) and "ToFReading" in str(err.value)


@pytest.mark.parametrize("name", PIPELINES)
def test_pipeline_refuses_process_before_reset(name):
    pipe = PIPELINE_REGISTRY.make(name)
    with pytest.raises(PipelineStateError, match="reset"):
        pipe.process(smoke_episode(pipe.track).frames[0])


@pytest.mark.parametrize("name", PIPELINES)
def test_pipeline_refuses_an_unknown_config_key(name):
    with pytest.raises(UnknownNameError, match="no_such_parameter_xyz"):
        PIPELINE_REGISTRY.make_config(name, {"no_such_parameter_xyz": "1"})


# ------------------------------------------------------------------ tracks


@pytest.mark.parametrize("name", TRACKS)
def test_track_smoke_episode_carries_only_its_streams(name):
    track = _track(name)
    assert isinstance(track.estimate_type, type)
    assert set(track.streams) <= set(FRAME_TYPES), f"{name}: unknown stream kinds"
    episode = smoke_episode(name)
    assert episode.frames, f"{name}: the smoke episode has no frame"
    carried = {frame_kind(f) for f in episode.frames}
    assert carried <= set(track.streams), f"{name}: undeclared streams {carried - set(track.streams)}"
    stamps = [f.stamp_s for f in episode.frames]
    assert stamps == sorted(stamps), f"{name}: frames out of time order"
    assert PIPELINE_REGISTRY.names(track=name), f"no pipeline serves {name}"


@pytest.mark.parametrize("name", TRACKS)
def test_track_cases_validate_with_unique_names(name):
    track = _track(name)
    assert track.default_suite in track.suites
    for suite in track.suites:
        cases = track.cases(suite)
        assert cases, f"{name}/{suite} has no case"
        names = [c.name for c in cases]
        assert len(set(names)) == len(names), f"{name}/{suite}: duplicate case names"
        for c in cases:
            values = track.validate_scenario(c.scenario)
            assert all(_same(values[k], v) for k, v in c.scenario.items()), (name, suite, c.name)
    with pytest.raises(UnknownNameError):
        track.cases("no-such-suite")


@pytest.mark.parametrize("name", TRACKS)
def test_track_scores_failures_well_formed_with_the_reason(name):
    track = _track(name)
    episode = smoke_episode(name)
    rows = {r.metric for r in track.summary_rows()}
    keys = []
    for ep in (None, episode):
        failed = track.failed_metrics(ep, REASON)
        _failed_with(failed, REASON, f"{name}.failed_metrics({'None' if ep is None else 'episode'})")
        assert rows <= set(failed), f"{name}: failed metrics lack summary rows {sorted(rows - set(failed))}"
        keys.append(set(failed))
    assert keys[0] == keys[1], f"{name}: failed metrics differ in keys with and without an episode"
    # no estimate is a failure the runner records (the scorer never sees it), never an exception
    _, metrics, _, _ = run_pipelines(track, episode, [PipelineRun("none", f"{__name__}:NoEstimate", NoEstimate.Config())])
    _failed_with(metrics["none"], f"NoneType, not {track.estimate_type.__name__}", f"{name}: finalize() returned None")


class NoEstimate:
    """A pipeline whose ``finalize()`` returns None, whatever the track."""

    @dataclasses.dataclass(frozen=True)
    class Config:
        pass

    def __init__(self, config: Any) -> None:
        pass

    def reset(self, calibration: Any) -> None:
        pass

    def process(self, frame: Any) -> None:
        return None

    def finalize(self) -> None:
        return None


@pytest.mark.parametrize("name", TRACKS)
def test_track_summary_rows_and_references_resolve(name):
    track = _track(name)
    pipes = PIPELINE_REGISTRY.names(track=name)
    scored = [(p, clean_run(p)[1]) for p in pipes]
    rows = {r.metric for r in track.summary_rows()}
    assert rows, f"{name}: no summary row"
    for p, metrics in scored:
        assert rows <= set(metrics), f"{name}: summary rows the scorer does not give for {p}: {sorted(rows - set(metrics))}"
    assert set(track.timing_metrics) <= set().union(*(m for _, m in scored)), f"{name}: timing metrics never scored"
    groups = {c.group for s in track.suites for c in track.cases(s)}
    for ref in track.references():
        assert ref.metric in rows, f"{name}: reference to {ref.metric!r}, which no summary row shows"
        assert set(ref.pipelines) <= set(pipes), f"{name}: reference to pipelines {sorted(set(ref.pipelines) - set(pipes))}"
        assert set(ref.groups) <= groups, f"{name}: reference to groups {sorted(set(ref.groups) - groups)}"


@pytest.mark.parametrize("name", TRACKS)
def test_track_marks_its_headline_metrics_and_which_way_is_better(name):
    track = _track(name)
    headline = tuple(getattr(track, "headline_metrics", ()))
    assert headline, f"{name}: no headline_metrics (what compare and leaderboard rank on)"
    marked = [r for r in track.summary_rows() if r.better]
    assert all(r.better in ("higher", "lower") for r in marked)
    assert sorted(r.metric for r in marked) == sorted(headline), (
        f"{name}: headline metrics {sorted(headline)} need one summary row each with better='higher' or 'lower'; "
        f"marked: {sorted(r.metric for r in marked)}")
    assert [r.metric for r in headline_rows(track)] == list(headline)


# ------------------------------------------------------------------ sensor kinds


def test_every_kind_is_registered_in_both_tables():
    assert not registration_problems(), "\n".join(registration_problems())


@pytest.mark.parametrize("name", sorted(SENSOR_KINDS))
def test_sensor_kind_does_what_its_records_promise(name, tmp_path):
    frame_kind_name = SENSOR_KINDS[name].codec.kind
    carriers = [t for t in TRACKS if frame_kind_name in _track(t).streams]
    assert carriers, f"sensor kind {name!r}: no track streams its frames {frame_kind_name!r}"
    episode = smoke_episode(carriers[0])
    problems = kind_problems(name, list(episode.frames), episode.calibration, tmp_path / "s")
    assert not problems, "\n".join(problems)


# ------------------------------------------------------------------ gymnasium


def test_exobench_gym_environments_are_registered():
    assert GYM_IDS, "no exobench/ environment registered with gymnasium"


@pytest.mark.parametrize("env_id", GYM_IDS)
def test_gym_environment_passes_check_env(env_id):
    from gymnasium.utils.env_checker import check_env

    env = gymnasium.make(env_id)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", UserWarning)  # check_env reports most findings as warnings
            check_env(env.unwrapped, skip_render_check=True)
    finally:
        env.close()
