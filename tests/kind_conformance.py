"""What every sensor kind must do, shipped or added by a user: the checks behind the kind tests
of ``test_conformance.py`` and ``envs/test_envs_toy_sensor.py``.

:func:`kind_problems` returns one line per thing a kind lacks or gets wrong (empty when none):
its entries in the two tables (:func:`exobench.envs.sensors.kinds.kind_problems`), then, on
frames the kind recorded, what its record promises: ``check_frame`` accepts them; clean frames
hold no NaN and no absurd value; its NaN form is counted by its NaN-value counter, its absurd
forms by its absurd-value rule (with the calibration's limits), its no-return form by neither;
a pipeline that admits every frame and counts with the record's rules counts exactly the faults
:func:`exobench.core.faults.inject_stream_faults` put in each stream; and its codec writes and
reads frames back bit for bit.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from exobench.core import Calibration, Episode, EpisodeTruth, SceneTruth
from exobench.core.counters import StreamCounters
from exobench.core.errors import FrameTypeError
from exobench.core.faults import STREAM_FAULTS, absurd, inject_stream_faults, no_return, with_nan
from exobench.core.kinds import KINDS, kind_of
from exobench.core.pipeline import check_frame
from exobench.envs.sensors import kinds as sensor_kinds
from exobench.envs.session import iter_frames, write_session

EMPTY_CALIBRATION = Calibration(
    robot_urdf="<robot name='x'/>", base_link="pelvis", joint_names=(), mounts=(),
    sole_height_m=0.068, foot_length_m=0.26, heel_to_ankle_m=0.065,
)  # fmt: skip


def bit_difference(a: Any, b: Any) -> str | None:
    """Where two values differ bit for bit (NaN payloads and signed zeros included), or None."""
    if type(a) is not type(b):
        return f"{type(a).__name__} != {type(b).__name__}"
    if isinstance(a, np.ndarray):
        same = a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
        return None if same else f"arrays differ ({a.dtype}{a.shape} vs {b.dtype}{b.shape})"
    if isinstance(a, float):
        return None if np.float64(a).tobytes() == np.float64(b).tobytes() else f"{a!r} != {b!r}"
    if isinstance(a, tuple):
        if len(a) != len(b):
            return "lengths differ"
        return next((f"[{i}] {d}" for i, (x, y) in enumerate(zip(a, b)) if (d := bit_difference(x, y))), None)
    return None if a == b else f"{a!r} != {b!r}"


def frames_difference(a: Any, b: Any) -> str | None:
    """The first field where two frames differ bit for bit, or None."""
    if type(a) is not type(b):
        return f"{type(a).__name__} != {type(b).__name__}"
    for fl in dataclasses.fields(a):
        d = bit_difference(getattr(a, fl.name), getattr(b, fl.name))
        if d:
            return f"{fl.name}: {d}"
    return None


def round_trip(frames: list[Any], folder: Path, calibration: Calibration = EMPTY_CALIBRATION) -> list[Any]:
    """The frames written to a session in ``folder`` and read back."""
    truth = EpisodeTruth(scene=SceneTruth((), {}), T_world_estimator=np.eye(4))
    write_session(Episode({}, 0, calibration, tuple(frames), truth), folder)
    return list(iter_frames(folder))


def _fault_counts(frames: tuple, calibration: Calibration | None) -> dict[str, dict[str, int]]:
    """Counters of a pipeline that reads every stream and counts NaN and absurd frames by the records."""
    counters = StreamCounters()
    rules = {name: k.absurd_values(calibration) for name, k in KINDS.items()}
    for f in frames:
        c = counters.admit(f)
        if c is None:
            continue
        kind = kind_of(f)
        c.add_nan(kind.nan_values(f))
        c.add_absurd(rules[kind.name](f))
    return {k: c.as_dict() for k, c in counters.snapshot().items()}


def kind_problems(sensor_kind: str, frames: list[Any], calibration: Calibration | None, folder: Path) -> list[str]:
    """What ``sensor_kind`` lacks, checked on ``frames`` it recorded (module docstring); ``folder``
    receives a session for the round trip."""
    out = sensor_kinds.kind_problems(sensor_kind)
    if out:
        return out  # the behaviour below needs both records
    sk = sensor_kinds.SENSOR_KINDS[sensor_kind]
    kind = KINDS[sk.codec.kind]
    where = f"sensor kind {sensor_kind!r} (frames {kind.name!r})"
    mine = [f for f in frames if isinstance(f, kind.frame_type)]
    if not mine:
        return [f"{where}: no frame of the kind to check"]
    try:
        check_frame(None, mine[0], True)
    except FrameTypeError as e:
        out.append(f"{where}: check_frame refuses its frames ({e})")
    rule = kind.absurd_values(calibration)
    picks = mine[:: max(1, len(mine) // 8)][:8]
    for f in picks:
        at = f"{where}, frame at {f.stamp_s} s"
        if kind.nan_values(f) or rule(f):
            out.append(f"{at}: a clean frame counts {kind.nan_values(f)} NaN and {rule(f)} absurd values")
        nan = with_nan(f)
        if (nan.stamp_s, nan.sensor_id) != (f.stamp_s, f.sensor_id) or kind.nan_values(nan) < 1:
            out.append(f"{at}: its NaN form is not counted by its NaN-value counter (or changed stamp or id)")
        for variant in range(3):
            bad = absurd(f, variant)
            if rule(bad) < 1 or kind.nan_values(bad):
                out.append(f"{at}: its absurd form {variant} is not counted by its absurd-value rule")
        if kind.no_return is not None:
            none = no_return(f)
            if kind.nan_values(none) or rule(none):
                out.append(f"{at}: its no-return form counts as NaN or absurd (it is a measurement)")
    faulty, injected = inject_stream_faults(mine)
    if not injected:
        out.append(f"{where}: no stream of 10 frames to fault")
    counts = _fault_counts(faulty, calibration).get(kind.name, {})
    want = {fault: sum(len(by[fault]) for by in injected.values()) for fault in STREAM_FAULTS if fault != "dropped"}
    got = {fault: counts.get(fault, 0) for fault in want}
    if got != want:
        out.append(f"{where}: faults injected {want}, counted by the record's rules {got}")
    back = round_trip(picks, folder)
    diffs = [d for a, b in zip(picks, back) if (d := frames_difference(a, b))]
    if len(back) != len(picks) or diffs:
        out.append(f"{where}: its codec does not give its frames back bit for bit ({len(back)}/{len(picks)}; {diffs[:1]})")
    return out
