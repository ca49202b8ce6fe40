"""Conformance of every scenario key of every registered track: a key a track accepts changes the
simulated episode, or is refused at plan time (``validate_scenario``). No key is accepted and
silently ignored (loop-closure took ``--set facade=windows`` and built the same office).

What is compared, and why it is enough. Simulating two whole episodes per key (some 150 keys)
would take many minutes, so the test stops each simulation where everything a scenario decides
has been handed to the simulator: the call of the recorder (``envs.sim.recorder.record``, the one
function every world's ``simulate_*`` hands the compiled model, the world truth, the device, the
planned motion, the rig, the seed and the hooks to). Everything the episode is made of comes
from those arguments, so two scenarios whose recorder calls differ simulate from different
inputs; the test compares a fingerprint of that call: the compiled MuJoCo model's bytes (world
geometry, materials, the device's size, the rig's sites, pedestrians), the world truth, the
device, the motion sampled at 40 instants, the rig's sensors with their configs, the seed, the
duration and what the hooks do at those instants (the camera's view motion, the people's
paths). A key that changes none of that (e.g. ``lidar_truth``, applied to the recording) is
simulated whole, both ways, and the frames, truth and calibration compared. Every key is moved
away from the track's smoke scenario to the first of its low, high, middle (a quarter, a tenth)
or other choice that the track accepts and the planner can walk; a key that only acts together with another one (the pelvis LiDAR's height)
is tried where it acts (:data:`CONTEXT`). The vio track's delivery faults, which act after the
recorder, are tried on a small camera (:data:`SMALL_CAMERA`): their two walks are simulated whole.
"""

from __future__ import annotations

import math
import pickle
from typing import Any

import numpy as np
import pytest

import exobench.envs.sim.scenarios.course as course
import exobench.envs.sim.scenarios.office as office
import exobench.envs.sim.scenarios.stairs as stairs
from exobench.benchmarks.tracks import get_track, track_names
from exobench.core.errors import ConfigError

pytestmark = pytest.mark.long(seconds=37)  # the workers take it first (tests/conftest.py); 37: the file's CPU-s alone at -n 0 (52.3 before the batched footholds)

# (track or None for every track, key) -> the values under which the key acts (the other keys
# are tried on the smoke scenario)
CONTEXT: dict[tuple[str | None, str], dict[str, Any]] = {
    (None, "lidar_height_m"): {"lidar_mount": "pelvis"},  # the mast LiDAR's height follows the user
    (None, "slope_deg"): {"terrain": "ramp"},
    (None, "ramp_length_m"): {"terrain": "ramp"},
    (None, "parallel_first"): {"terrain": "parallel"},
    (None, "segmentation_truth"): {"extra_sensors": "rgbd_head"},  # it needs a camera
    (None, "max_turn_deg"): {"route": "loop", "max_distance_m": 3.0},  # a corner 2.5 m along the loop
    ("locomotion", "segmentation_truth"): {},  # which it has
    (None, "texture_seed"): {"surfaces": "textured"},  # the seed of the textures that setting draws
    (None, "change_seed"): {"day": 1},  # it draws a script of `day` days
    (None, "start_x_m"): {"route_regions": "corridor_n"},  # the fixed routes start at the office's own start
    ("multisession", "start_x_m"): {},  # its sessions walk through regions
    # a change script acts from day 1 on: with the first session on day 1 the recorder's first
    # call (the one compared) shows it, where on day 0 both episodes were simulated whole (12 s each)
    ("multisession", "change_seed"): {"changes": "", "sessions": "1:corridor_s;1:corridor_s"},  # written or drawn, not both
    ("multisession", "changes"): {"sessions": "1:corridor_s;1:corridor_s"},
    ("multisession", "furnish"): {"changes": ""},  # the lab has no plant0 to remove
    ("multisession", "repeated_rooms"): {"n_offices": 2, "changes": ""},  # two offices to repeat one in
    # the wrong-label fault acts after the recorder, so both episodes are simulated whole: one
    # session of the shortest walk at 2 Hz (7 place labels, each swapped at the high value, 1.0)
    # costs 5 s of CPU where the smoke's two sessions cost 15 s
    ("multisession", "place_label_error_fraction"): {"sessions": "0:corridor_s", "changes": "", "max_distance_m": 0.5,
                                                     "frame_rate_hz": 2.0},
}

# free-string keys: values to try
FREE_STRINGS: dict[str, tuple[str, ...]] = {"changes": ("1 remove chair0",), "route_regions": ("corridor_s",),
                                             "sessions": ("0:corridor_n;1:corridor_n",)}


# a shorter course than the smoke scenario's, so that each of the ~15 courses is planned quickly
BASE: dict[str, dict[str, Any]] = {"locomotion": {"n_steps": 2, "approach_m": 1.0, "landing_m": 1.2}}


# 2 Hz: seven frames over the smoke walk's 3.4 s, each of which a fault at its high value (1.0)
# hits; rendering costs ~55 ms a frame whatever the size, so the rate sets these walks' cost
SMALL_CAMERA: dict[str, Any] = {"width_px": 64, "height_px": 48, "rate_hz": 2.0}


def _vio_context() -> dict[tuple[str, str], dict[str, Any]]:
    """The vio track walks an office (its smoke scenario) or a course: a course's row is tried on
    the short course (the smoke's office length back at its default), and so is ``world``."""
    from exobench.benchmarks.tracks.vio.faults import FAULT_ROWS
    from exobench.benchmarks.tracks.vio.scenario import scenario_classes

    office, course_rows = (set(c.PARAMS) for c in scenario_classes().values())
    away = {"max_distance_m": office_default("max_distance_m")}
    out = {("vio", k): {**away, "world": "course", **BASE["locomotion"], **CONTEXT.get((None, k), {})}
           for k in course_rows - office}  # fmt: skip
    out[("vio", "world")] = away
    # the delivery faults act after the recorder, so both walks are simulated whole: on a small
    # image at 2 Hz, which the faults reach as they reach the D455's (at 424x240 and 30 Hz these
    # walks took 37 s of the vio check's 70 s of CPU, 9 s at 64x48 and 10 Hz, 3 s at 2 Hz)
    out.update({("vio", k): SMALL_CAMERA for k in FAULT_ROWS})
    return out


def office_default(key: str) -> Any:
    return office.PARAMS[key].default


CONTEXT.update(_vio_context())


def _context(track_name: str, key: str) -> dict[str, Any]:
    return {**BASE.get(track_name, {}), **CONTEXT.get((track_name, key), CONTEXT.get((None, key), {}))}


TIMES_FRACTION = np.linspace(0.0, 1.0, 40)


class _Recorded(Exception):
    """Raised by the stand-in recorder once it has the call's arguments."""

    def __init__(self, fingerprint: bytes) -> None:
        self.fingerprint = fingerprint


def _model_bytes(model: Any) -> bytes:
    import mujoco

    buf = np.zeros(mujoco.mj_sizeModel(model), dtype=np.uint8)
    mujoco.mj_saveModel(model, None, buf)
    return buf.tobytes()


def _fingerprint(model, truth, exo, motion, rig, seed, *, duration_s=None, hooks=(), **kw) -> bytes:
    dur = float(motion.duration_s if duration_s is None else duration_s)
    t = TIMES_FRACTION * dur
    st = motion.state(t)
    moved = [st.pelvis_w, st.yaw, st.pitch, st.joints, *st.ankle_w.values(), *st.foot_pitch.values()]
    hooked = []
    for h in hooks:
        if hasattr(h, "view"):
            hooked += list(h.view.values(t).values())
        if hasattr(h, "positions"):
            xy, z = h.positions(t)
            hooked += [*xy, *z, np.array([p.height_m for p in h.paths]), np.array([p.yaw for p in h.paths])]
    parts = [_model_bytes(model), pickle.dumps(truth), repr(exo).encode(), pickle.dumps(tuple(rig)), str(seed).encode(),
             str(dur).encode(), repr(sorted(kw.items())).encode(), *(np.ascontiguousarray(a).tobytes() for a in moved),
             *(np.ascontiguousarray(a).tobytes() for a in hooked)]  # fmt: skip
    return b"\x00".join(parts)


def _stop_at_the_recorder(monkeypatch) -> None:
    def record(*args, **kw):
        raise _Recorded(_fingerprint(*args, **kw))

    for module in (office, stairs, course):
        monkeypatch.setattr(module, "record", record)


def _recorder_inputs(track, scenario: dict[str, Any]) -> bytes:
    try:
        track.simulate(scenario, 0)
    except _Recorded as r:
        return r.fingerprint
    raise AssertionError(f"{track.name}: simulate() never called the recorder")


_BEFORE: dict[tuple[str, str], bytes] = {}


def _base_inputs(track, scenario: dict[str, Any]) -> bytes:
    """:func:`_recorder_inputs` of a key's base scenario, once per (track, scenario): most keys
    share the smoke scenario as their base (an office built again for each took ~0.06 s)."""
    key = (track.name, repr(sorted(scenario.items())))
    if key not in _BEFORE:
        _BEFORE[key] = _recorder_inputs(track, scenario)
    return _BEFORE[key]


_EPISODES: dict[tuple[str, str], bytes] = {}


def _episode_bytes(track, scenario: dict[str, Any]) -> bytes:
    """The whole episode's bytes, simulated once per (track, scenario): the base scenario of every
    key that acts after the recorder is the same smoke scenario."""
    key = (track.name, repr(sorted(scenario.items())))
    if key not in _EPISODES:
        ep = track.simulate(scenario, 0)
        _EPISODES[key] = pickle.dumps((ep.frames, ep.truth, ep.calibration))
    return _EPISODES[key]


def _candidates(p, base: Any) -> list[str]:
    """Values of a parameter other than ``base``, as the command line gives them."""
    if p.choices:
        return [str(c) for c in p.choices if c != base]
    if p.name == "extra_sensors":
        from exobench.envs.sim.rig import PRESETS

        return list(PRESETS)
    if p.name in FREE_STRINGS:
        return [v for v in FREE_STRINGS[p.name] if v != base]
    lo, hi = p.low, p.high
    vals = [lo if not p.low_open else None, hi] + [lo + f * (hi - lo) for f in (0.5, 0.25, 0.1)]
    if isinstance(p.default, int) and not isinstance(p.default, bool):
        vals = [None if v is None else int(round(v)) for v in vals]
    return [repr(v) for v in vals if v is not None and math.isfinite(v) and v != base]


def _accepted(track, p) -> list[tuple[str, dict[str, Any]]]:
    """(value, validated scenario) of every candidate the track accepts at plan time."""
    ctx = {**track.smoke_scenario, **_context(track.name, p.name)}
    base = track.validate_scenario(ctx)
    out = []
    for text in _candidates(p, base.get(p.name, p.default)):
        try:
            out.append((text, track.validate_scenario({**ctx, p.name: text})))
        except ConfigError:
            continue
    return out


# tracks whose keys take most of a minute each are checked in files of their own
# (test_conformance_scenario_keys_<track>.py), which the two workers take first (tests/conftest.py)
OWN_FILES = ("vio", "multisession")


@pytest.mark.parametrize("track_name", [n for n in track_names() if n not in OWN_FILES])
def test_every_scenario_key_changes_the_simulation_or_is_refused(track_name, monkeypatch):
    check_scenario_keys(track_name, monkeypatch)


def check_scenario_keys(track_name: str, monkeypatch) -> None:
    """Every scenario key of the track changes its simulation or is refused (module docstring)."""
    track = get_track(track_name)
    _stop_at_the_recorder(monkeypatch)
    inert, no_value = [], []
    for p in track.params():
        if p.name in track.scoring_keys:  # they change the score, not the episode (the runner hands them to score)
            continue
        base = track.validate_scenario({**track.smoke_scenario, **_context(track_name, p.name)})
        before = _base_inputs(track, base)
        tried = []
        for text, other in _accepted(track, p):
            try:  # a geometry the motion planner cannot walk is refused here (it needs the built world)
                after = _recorder_inputs(track, other)
            except ConfigError:
                continue
            tried.append(text)
            if after != before:
                break
            monkeypatch.undo()  # the key may act after the recorder: simulate both whole
            same = _episode_bytes(track, base) == _episode_bytes(track, other)
            _stop_at_the_recorder(monkeypatch)
            if not same:
                break
        else:
            (inert if tried else no_value).append(f"{p.name} ({', '.join(tried)})")
    assert not inert and not no_value, (
        f"{track_name}: accepted and without effect on the simulation: {inert}; no other value accepted: {no_value}"
    )
