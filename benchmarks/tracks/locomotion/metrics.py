"""Scoring locomotion-mode predictions against the true steps of an episode (seeds/002, Sec. IV).

Everything here is a pure function of ``StepTruth`` and ``ModePrediction`` sequences (sorted
by index and by stamp on entry). Definitions:

- **Decision of step k**: the prediction *in effect at the step's liftoff* (the controller must
  know the mode before the foot leaves the ground): the last prediction with
  ``stamp_s <= liftoff_s`` of step k (ties: the later one in the pipeline's output order).
  ``stamp_s`` is the time of the input frame, so simulated time alone decides which prediction
  counts; the wall-clock ``latency_s`` is reported apart and never changes a score (runs stay
  bit-identical). A prediction of mode ``""`` (none yet), an unknown mode, or no prediction
  before the liftoff leaves the step *undecided*: wrong, and outside the confusion matrix.
- ``strike_index`` is a consistency check, not a selector: a prediction made after heel strike
  k-1 and before heel strike k has ``strike_index == k`` and is meant for step k.
  ``n_stale_decisions`` counts decisions with ``strike_index < k`` (the pipeline had not yet
  registered the previous heel strike, so its footprint was aimed at an earlier step),
  ``n_ahead_decisions`` those with ``strike_index > k``.
- **Warm-up**: the first :data:`WARMUP_STEPS` (3) steps of a walk are not scored. Eq. 17
  extrapolates the next step size from the last two, so the paper's method has its first
  footprint, hence its first mode, only after the third heel strike; every course starts with
  a level approach long enough for these steps (they are LG). ``n_warmup_steps`` counts them and
  ``accuracy_incl_warmup`` is the accuracy over every step, warm-up included. ``n_steps`` and
  every other metric below are over the scored steps.
- ``accuracy``: correct decisions / steps. ``accuracy_{M}`` for M in ``LG SA SD RA RD``: the
  same over the steps whose true mode is M (the recall of M; NaN when the episode has none),
  ``n_steps_{M}`` their number. ``confusion``: 5x5 counts, rows the true mode, columns the
  decided mode, in :data:`LOCOMOTION_MODES` order (undecided steps are not in it).
- **Transition step**: a step whose true mode differs from the previous step's (LG -> SA,
  SA -> LG, ...). Its *decision window* runs from the previous step's liftoff (exclusive: that
  instant belongs to the previous decision) to its own liftoff (inclusive). ``anticipation_s``
  of a transition decided correctly is the time from the first prediction after which the
  output stays the correct mode up to the liftoff ("first and stably output") to the liftoff:
  ``liftoff_s - stamp_s(first stable prediction)``, the stable run being searched within the
  decision window. A wrong or missing decision, or a decision made before the window (no
  output during the whole previous step), has no anticipation (NaN). Reported: the mean and
  minimum over the transitions, the mean per transition type (``anticipation_s_LG_SA``, ...),
  ``transition_accuracy`` and each transition in ``transitions`` (a list of dicts).
- ``latency_ms_median`` / ``latency_ms_p95``: median and 95th percentile (linear
  interpolation) of ``latency_s`` over every prediction with a finite latency, ms.
- ``n_status_{status}`` for every status of :data:`KNOWN_STATUSES` and any other seen, and
  ``n_faults``: predictions whose status is not ``"ok"`` (over the whole episode, warm-up included).
- ``footprint_error_m``: when the odometry frame's pose is known (``T_world_odom``, a pose or a
  function of the prediction's stamp), the mean horizontal distance between the footprint of
  each decision made for its own step (``strike_index == k``, finite footprint), mapped to the
  world, and the true footprint of step k (eq. 16-18), m. The track passes the odometry's local
  alignment at the prediction (true camera pose times the inverse of the odometry's camera
  pose), so the error is the prediction's, not the drift accumulated since the start; for a
  pipeline on its own odometry, the same with the camera pose each prediction carries.
- ``failed`` / ``failed_reason``: the pipeline raised, returned no estimate, or made no
  prediction at all; the simulation raised (no episode).

Missing values are NaN (the result store writes them as JSON null).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from exobench.core.episode import Episode
from exobench.core.estimates import LOCOMOTION_MODES, LocomotionEstimate, ModePrediction
from exobench.core.truth import StepTruth

NAN = float("nan")
MODE_INDEX = {m: i for i, m in enumerate(LOCOMOTION_MODES)}
TRANSITION_TYPES = (("LG", "SA"), ("SA", "LG"), ("LG", "SD"), ("SD", "LG"), ("LG", "RA"), ("RA", "LG"), ("LG", "RD"), ("RD", "LG"))
# the statuses of exobench.mapping.locomotion (other pipelines may add their own)
KNOWN_STATUSES = ("ok", "no_depth", "bad_frame", "no_odometry", "no_planes", "few_strikes", "no_direction", "no_terrain", "error")
WARMUP_STEPS = 3


@dataclass(frozen=True)
class StepDecision:
    """The decision of one step (see the module docstring).

    Attributes:
        step: ``StepTruth.index``.
        true_mode: the step's true mode.
        mode: the decided mode, ``""`` when undecided.
        prediction: position of the deciding prediction in the sorted predictions, -1 if none.
        strike_index: its ``strike_index`` (-1 if none).
    """

    step: int
    true_mode: str
    mode: str
    prediction: int
    strike_index: int

    @property
    def decided(self) -> bool:
        return self.mode in MODE_INDEX

    @property
    def correct(self) -> bool:
        return self.decided and self.mode == self.true_mode


@dataclass(frozen=True)
class Transition:
    """One transition step and how early its mode was output (NaN when it was not)."""

    step: int
    from_mode: str
    to_mode: str
    liftoff_s: float
    decided_mode: str
    anticipation_s: float

    def as_dict(self) -> dict[str, Any]:
        return {
            "step": self.step, "from": self.from_mode, "to": self.to_mode, "liftoff_s": self.liftoff_s,
            "decided": self.decided_mode, "anticipation_s": self.anticipation_s,
        }  # fmt: skip


def sorted_steps(steps: Sequence[StepTruth]) -> list[StepTruth]:
    """Steps by index."""
    return sorted(steps, key=lambda s: s.index)


def sorted_predictions(predictions: Sequence[ModePrediction]) -> list[ModePrediction]:
    """Predictions with a finite stamp, by stamp (stable: ties keep the pipeline's order)."""
    valid = [p for p in predictions if _finite(p.stamp_s)]
    return sorted(valid, key=lambda p: float(p.stamp_s))


def _finite(x: Any) -> bool:
    try:
        return math.isfinite(float(x))
    except (TypeError, ValueError):
        return False


def _last_at_or_before(stamps: np.ndarray, t: float) -> int:
    """Position of the last stamp <= t, -1 if none (stamps sorted)."""
    return int(np.searchsorted(stamps, t, side="right")) - 1


def step_decisions(steps: Sequence[StepTruth], predictions: Sequence[ModePrediction]) -> list[StepDecision]:
    """The decision of each step (inputs sorted with :func:`sorted_steps` / :func:`sorted_predictions`)."""
    stamps = np.array([float(p.stamp_s) for p in predictions], dtype=float)
    out = []
    for s in steps:
        i = _last_at_or_before(stamps, float(s.liftoff_s)) if len(stamps) else -1
        if i < 0:
            out.append(StepDecision(int(s.index), str(s.mode), "", -1, -1))
            continue
        p = predictions[i]
        mode = str(p.mode) if str(p.mode) in MODE_INDEX else ""
        out.append(StepDecision(int(s.index), str(s.mode), mode, i, int(p.strike_index)))
    return out


def confusion_matrix(decisions: Sequence[StepDecision]) -> np.ndarray:
    """5x5 counts, rows true mode, columns decided mode (undecided steps left out)."""
    cm = np.zeros((len(LOCOMOTION_MODES), len(LOCOMOTION_MODES)), dtype=int)
    for d in decisions:
        if d.decided and d.true_mode in MODE_INDEX:
            cm[MODE_INDEX[d.true_mode], MODE_INDEX[d.mode]] += 1
    return cm


def accuracy(decisions: Sequence[StepDecision]) -> float:
    """Fraction of steps decided correctly; NaN without steps."""
    return float(np.mean([d.correct for d in decisions])) if decisions else NAN


def accuracy_by_mode(decisions: Sequence[StepDecision]) -> dict[str, float]:
    """Accuracy over the steps of each true mode (NaN for a mode without steps)."""
    return {m: accuracy([d for d in decisions if d.true_mode == m]) for m in LOCOMOTION_MODES}


def transitions(
    steps: Sequence[StepTruth], predictions: Sequence[ModePrediction], decisions: Sequence[StepDecision]
) -> list[Transition]:
    """Every transition step with its anticipation (inputs sorted; ``decisions`` from
    :func:`step_decisions` on the same inputs)."""
    out = []
    for k in range(1, len(steps)):
        prev, s, d = steps[k - 1], steps[k], decisions[k]
        if s.mode == prev.mode:
            continue
        antic = NAN
        window_start = float(prev.liftoff_s)
        if d.correct and float(predictions[d.prediction].stamp_s) > window_start:
            first = d.prediction
            while (
                first - 1 >= 0
                and float(predictions[first - 1].stamp_s) > window_start
                and str(predictions[first - 1].mode) == s.mode
            ):
                first -= 1
            antic = float(s.liftoff_s) - float(predictions[first].stamp_s)
        out.append(Transition(int(s.index), str(prev.mode), str(s.mode), float(s.liftoff_s), d.mode, antic))
    return out


def latency_ms(predictions: Sequence[ModePrediction]) -> tuple[float, float]:
    """(median, p95) of ``latency_s`` over the predictions with a finite latency, ms."""
    lat = np.array([float(p.latency_s) for p in predictions if _finite(p.latency_s)], dtype=float)
    if lat.size == 0:
        return NAN, NAN
    return float(np.median(lat) * 1e3), float(np.percentile(lat, 95) * 1e3)


def status_counts(predictions: Sequence[ModePrediction]) -> dict[str, int]:
    """Number of predictions per status (the known statuses always present)."""
    counts = {s: 0 for s in KNOWN_STATUSES}
    for p in predictions:
        key = str(p.status) or "unknown"
        counts[key] = counts.get(key, 0) + 1
    return counts


def footprint_errors(
    steps: Sequence[StepTruth],
    predictions: Sequence[ModePrediction],
    decisions: Sequence[StepDecision],
    T_world_odom: np.ndarray | Callable[[float], np.ndarray],
) -> list[float]:
    """Horizontal distance (m) between each decision's footprint, mapped to the world, and the
    true footprint of its step, for decisions made for their own step (``strike_index == k``).
    ``T_world_odom``: the odometry frame's pose, or a function of the prediction's stamp giving
    it (the local alignment of a drifting odometry)."""
    out = []
    for s, d in zip(steps, decisions):
        if d.prediction < 0 or d.strike_index != s.index:
            continue
        f = np.asarray(predictions[d.prediction].footprint_odom, dtype=float).reshape(-1)
        if f.size != 3 or not np.all(np.isfinite(f)):
            continue
        T = np.asarray(T_world_odom(float(predictions[d.prediction].stamp_s)) if callable(T_world_odom)
                       else T_world_odom, dtype=float)
        if not np.all(np.isfinite(T)):  # the odometry frame's pose unknown then: not scored
            continue
        f_w = T[:3, :3] @ f + T[:3, 3]
        out.append(float(np.linalg.norm(f_w[:2] - np.asarray(s.footprint_w, dtype=float)[:2])))
    return out


def _stats(stats: dict[str, Any]) -> dict[str, float]:
    """Numeric diagnostics of the estimate as ``stat_*`` metrics; wall-clock figures (keys with
    ``latency`` or ``time``) are left out so that a record depends on the simulated input only,
    apart from the two latency metrics."""
    out: dict[str, float] = {}
    for k, v in stats.items():
        if k == "config" or "latency" in k or "time" in k:
            continue
        if isinstance(v, dict):
            out.update({f"stat_{k}_{kk}": vv for kk, vv in v.items() if isinstance(vv, (bool, int, float))})
        elif isinstance(v, (bool, int, float)):
            out[f"stat_{k}"] = v
    return out


def empty_metrics(n_steps: int = 0) -> dict[str, Any]:
    """The metric schema with every value missing."""
    m: dict[str, Any] = {
        "failed": True, "failed_reason": "", "n_steps": n_steps, "n_warmup_steps": 0, "accuracy_incl_warmup": NAN,
        "n_predictions": 0, "n_decided": 0,
        "n_undecided": n_steps, "n_stale_decisions": 0, "n_ahead_decisions": 0, "accuracy": NAN,
        "confusion": np.zeros((5, 5), dtype=int).tolist(), "n_transitions": 0, "n_transitions_correct": 0,
        "transition_accuracy": NAN, "anticipation_s": NAN, "anticipation_min_s": NAN, "transitions": [],
        "latency_ms_median": NAN, "latency_ms_p95": NAN, "n_status_ok": 0, "n_faults": 0,
        "footprint_error_m": NAN,
    }  # fmt: skip
    for mode in LOCOMOTION_MODES:
        m[f"accuracy_{mode}"] = NAN
        m[f"n_steps_{mode}"] = 0
    for a, b in TRANSITION_TYPES:
        m[f"anticipation_s_{a}_{b}"] = NAN
    for s in KNOWN_STATUSES[1:]:
        m[f"n_status_{s}"] = 0
    return m


def score_predictions(
    steps: Sequence[StepTruth],
    estimate: LocomotionEstimate,
    *,
    T_world_odom: np.ndarray | Callable[[float], np.ndarray] | None = None,
    warmup_steps: int = WARMUP_STEPS,
) -> dict[str, Any]:
    """Every metric of the module docstring (never raises on bad prediction values)."""
    every = sorted_steps(steps)
    preds = sorted_predictions(estimate.predictions)
    dec_all = step_decisions(every, preds)
    scored = [i for i, s in enumerate(every) if s.index >= warmup_steps]
    st = [every[i] for i in scored]
    dec = [dec_all[i] for i in scored]
    m = empty_metrics(len(st))
    m["n_warmup_steps"] = len(every) - len(st)
    m["accuracy_incl_warmup"] = accuracy(dec_all)
    m["n_predictions"] = len(estimate.predictions)
    for mode in LOCOMOTION_MODES:
        m[f"n_steps_{mode}"] = sum(s.mode == mode for s in st)
    m["n_decided"] = sum(d.decided for d in dec)
    m["n_undecided"] = len(dec) - m["n_decided"]
    m["n_stale_decisions"] = sum(d.prediction >= 0 and d.strike_index < d.step for d in dec)
    m["n_ahead_decisions"] = sum(d.prediction >= 0 and d.strike_index > d.step for d in dec)
    m["accuracy"] = accuracy(dec)
    m.update({f"accuracy_{k}": v for k, v in accuracy_by_mode(dec).items()})
    m["confusion"] = confusion_matrix(dec).tolist()

    trans = [t for t in transitions(every, preds, dec_all) if t.step >= warmup_steps]
    antic = np.array([t.anticipation_s for t in trans], dtype=float)
    good = antic[np.isfinite(antic)]
    m["n_transitions"] = len(trans)
    m["n_transitions_correct"] = sum(t.decided_mode == t.to_mode for t in trans)
    m["transition_accuracy"] = m["n_transitions_correct"] / len(trans) if trans else NAN
    m["anticipation_s"] = float(good.mean()) if good.size else NAN
    m["anticipation_min_s"] = float(good.min()) if good.size else NAN
    for a, b in TRANSITION_TYPES:
        vals = [t.anticipation_s for t in trans if (t.from_mode, t.to_mode) == (a, b) and math.isfinite(t.anticipation_s)]
        m[f"anticipation_s_{a}_{b}"] = float(np.mean(vals)) if vals else NAN
    m["transitions"] = [t.as_dict() for t in trans]

    m["latency_ms_median"], m["latency_ms_p95"] = latency_ms(preds)
    counts = status_counts(estimate.predictions)
    m.update({f"n_status_{k}": v for k, v in counts.items()})
    m["n_faults"] = sum(v for k, v in counts.items() if k != "ok")
    if T_world_odom is not None:
        errs = footprint_errors(st, preds, dec, T_world_odom)
        m["footprint_error_m"] = float(np.mean(errs)) if errs else NAN
    if not estimate.predictions:
        m["failed_reason"] = "no predictions"
    elif not st:
        m["failed_reason"] = "the episode has no steps after the warm-up"
    else:
        m["failed"] = False
    m.update(_stats(dict(estimate.stats or {})))
    return m


def failure_metrics(n_steps: int, reason: str) -> dict[str, Any]:
    """Metrics of a pipeline that raised or returned no LocomotionEstimate, or of a failed simulation."""
    m = empty_metrics(n_steps)
    m["failed_reason"] = reason
    return m


# The footprints' world frame: the given odometry's, or the poses an estimate on its own odometry used


def local_odometry_alignment(episode: Episode) -> Callable[[float], np.ndarray] | np.ndarray | None:
    """T_world_odom at a time: the true camera pose (times the calibration's ``T_camera_body``)
    times the inverse of the odometry's body pose at the odometry sample nearest to it (the odometry named in the calibration, which
    tracks the camera's optical frame; truth ``camera_T_world`` at ``camera_stamps_s``). Without
    those, the fixed ``T_world_estimator`` (None if absent)."""
    from exobench.core.frames import OdometrySample

    truth = episode.truth
    extra = truth.extra or {}
    info = (episode.calibration.extra or {}).get("odometry") if episode.calibration is not None else None
    odom_id = info.get("sensor_id") if isinstance(info, dict) else None
    try:
        T_fixed = np.asarray(truth.T_world_estimator, dtype=float).reshape(4, 4)
    except (TypeError, ValueError):
        T_fixed = None
    if odom_id is None or "camera_T_world" not in extra or "camera_stamps_s" not in extra:
        return T_fixed
    t_cam = np.asarray(extra["camera_stamps_s"], dtype=float)
    T_cam = np.asarray(extra["camera_T_world"], dtype=float)
    odo = [f for f in episode.frames if isinstance(f, OdometrySample) and f.sensor_id == odom_id]
    if not odo or len(t_cam) == 0:
        return T_fixed
    t_odo = np.array([float(f.stamp_s) for f in odo])
    k_cam = _nearest(t_cam, t_odo)
    try:  # the tracked body in the camera frame (identity: the optical frame itself)
        T_cb = np.asarray(info.get("T_camera_body", np.eye(4)), dtype=float).reshape(4, 4)
    except (TypeError, ValueError):
        T_cb = np.eye(4)
    aligned = np.array([T_cam[k] @ T_cb @ np.linalg.inv(np.asarray(f.T_odom_body, dtype=float)) for k, f in zip(k_cam, odo)])

    def at(t_s: float) -> np.ndarray:
        return aligned[int(_nearest(t_odo, np.array([t_s]))[0])]

    return at


def own_pose_alignment(episode: Episode, estimate: LocomotionEstimate) -> Callable[[float], np.ndarray] | None:
    """T_world_odom at a prediction's stamp for an estimate on its own odometry
    (``estimate.odometry`` not ``"given"``): the true camera pose at the truth stamp nearest to it
    times the inverse of the camera pose the prediction was made with (``T_odom_camera``); NaN
    where the prediction had none. The footprint is so scored where the prediction puts it
    relative to the camera, as the controller uses it (docs/tracks/locomotion.md). None without
    the camera truth."""
    extra = episode.truth.extra or {}
    if "camera_T_world" not in extra or "camera_stamps_s" not in extra:
        return None
    t_cam = np.asarray(extra["camera_stamps_s"], dtype=float)
    T_cam = np.asarray(extra["camera_T_world"], dtype=float)
    if len(t_cam) == 0:
        return None
    used: dict[float, np.ndarray] = {}
    for p in estimate.predictions:
        T = p.T_odom_camera
        if T is not None and np.shape(T) == (4, 4) and np.all(np.isfinite(T)):
            used[float(p.stamp_s)] = np.asarray(T, dtype=float)
    nan = np.full((4, 4), np.nan)

    def at(t_s: float) -> np.ndarray:
        T = used.get(float(t_s))
        if T is None:
            return nan
        return T_cam[int(_nearest(t_cam, np.array([t_s]))[0])] @ np.linalg.inv(T)

    return at


def _nearest(sorted_s: np.ndarray, t_s: np.ndarray) -> np.ndarray:
    """Index of the nearest of the sorted stamps to each time (the earlier on a tie)."""
    k = np.clip(np.searchsorted(sorted_s, t_s), 0, len(sorted_s) - 1)
    return np.where((k > 0) & (np.abs(sorted_s[k - 1] - t_s) <= np.abs(sorted_s[k] - t_s)), k - 1, k)
