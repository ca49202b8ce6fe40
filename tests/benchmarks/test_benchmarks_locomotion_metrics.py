"""Locomotion scoring on constructed steps and predictions with hand-computed answers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from exobench.benchmarks.tracks.locomotion.metrics import (
    score_predictions,
    sorted_predictions,
    sorted_steps,
    step_decisions,
)
from exobench.core.estimates import LocomotionEstimate, ModePrediction
from exobench.core.truth import StepTruth

NAN3 = np.full(3, np.nan)


def _steps() -> list[StepTruth]:
    # liftoff at k + 1 s, heel strike 0.6 s later; true modes LG LG SA SA LG SD
    modes = ("LG", "LG", "SA", "SA", "LG", "SD")
    feet = {0: (1.3, 2.9, 0.0), 2: (2.0, 3.0, 0.45)}
    return [
        StepTruth(k, "lr"[k % 2], k + 1.0, k + 1.6, np.array(feet.get(k, (0.0, 0.0, 0.0))), "ground", m)
        for k, m in enumerate(modes)
    ]


# (stamp, mode, strike_index, latency_ms, status, footprint_odom)
_ROWS = [
    (0.5, "SA", 0, 5.0, "ok", NAN3),
    (1.0, "LG", 0, 3.0, "ok", np.array([0.5, 0.0, 0.0])),  # exactly at step 0's liftoff: in effect
    (1.7, "LG", 1, 1.0, "ok", NAN3),
    (1.9, "LG", 0, 13.0, "ok", np.array([9.0, 9.0, 9.0])),  # stale: strike at 1.6 not seen yet
    (2.2, "LG", 1, 0.1, "dropped", NAN3),
    (2.4, "SA", 1, 2.0, "ok", NAN3),
    (2.5, "LG", 1, 4.0, "ok", NAN3),
    (2.7, "SA", 2, 6.0, "ok", NAN3),
    (2.9, "SA", 2, 7.0, "ok", np.array([1.0, -1.0, 0.3])),
    (3.5, "SA", 2, 0.2, "no_depth", NAN3),
    (3.95, "RA", 3, 8.0, "ok", NAN3),
    (4.65, "LG", 4, 9.0, "ok", NAN3),
    (4.9, "LG", 4, 10.0, "ok", NAN3),
    (5.7, "SD", 5, 11.0, "ok", NAN3),
    (5.9, "", 5, 12.0, "ok", NAN3),
]


def _preds(rows=_ROWS) -> list[ModePrediction]:
    return [ModePrediction(t, m, f, si, lat / 1000.0, st) for t, m, si, lat, st, f in rows]


def _T_world_odom() -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]  # yaw +90 deg
    T[:3, 3] = [1.0, 2.0, 0.0]
    return T


def test_decisions_are_the_predictions_in_effect_at_liftoff():
    dec = step_decisions(sorted_steps(_steps()), sorted_predictions(_preds()))
    assert [d.mode for d in dec] == ["LG", "LG", "SA", "RA", "LG", ""]
    assert [d.correct for d in dec] == [True, True, True, False, True, False]
    assert [d.strike_index for d in dec] == [0, 0, 2, 3, 4, 5]


def test_accuracy_confusion_and_per_mode():
    m = score_predictions(_steps(), LocomotionEstimate(tuple(_preds())), warmup_steps=0, T_world_odom=_T_world_odom())
    assert m["failed"] is False
    assert m["n_steps"] == 6 and m["n_predictions"] == 15
    assert m["accuracy"] == pytest.approx(4 / 6)
    assert m["accuracy_LG"] == 1.0 and m["accuracy_SA"] == 0.5 and m["accuracy_SD"] == 0.0
    assert math.isnan(m["accuracy_RA"]) and math.isnan(m["accuracy_RD"])
    assert (m["n_steps_LG"], m["n_steps_SA"], m["n_steps_SD"], m["n_steps_RA"]) == (3, 2, 1, 0)
    expected = np.zeros((5, 5), dtype=int)
    expected[0, 0] = 3  # LG -> LG
    expected[1, 1] = 1  # SA -> SA
    expected[1, 3] = 1  # SA -> RA
    assert m["confusion"] == expected.tolist()  # the undecided SD step is not in it
    assert (m["n_decided"], m["n_undecided"], m["n_stale_decisions"], m["n_ahead_decisions"]) == (5, 1, 1, 0)


def test_anticipation_of_transitions():
    m = score_predictions(_steps(), LocomotionEstimate(tuple(_preds())), warmup_steps=0)
    # LG->SA at step 2 (liftoff 3.0): window (2.0, 3.0] holds LG SA LG SA SA -> stable from 2.7
    # SA->LG at step 4 (liftoff 5.0): window (4.0, 5.0] holds LG LG -> stable from 4.65
    # LG->SD at step 5: undecided, no anticipation
    assert m["n_transitions"] == 3 and m["n_transitions_correct"] == 2
    assert m["transition_accuracy"] == pytest.approx(2 / 3)
    assert m["anticipation_s_LG_SA"] == pytest.approx(0.3)
    assert m["anticipation_s_SA_LG"] == pytest.approx(0.35)
    assert math.isnan(m["anticipation_s_LG_SD"])
    assert m["anticipation_s"] == pytest.approx(0.325)
    assert m["anticipation_min_s"] == pytest.approx(0.3)
    assert [(t["step"], t["from"], t["to"], t["decided"]) for t in m["transitions"]] == [
        (2, "LG", "SA", "SA"), (4, "SA", "LG", "LG"), (5, "LG", "SD", ""),
    ]  # fmt: skip
    assert math.isnan(m["transitions"][2]["anticipation_s"])


def test_anticipation_window_starts_after_the_previous_liftoff():
    steps = [StepTruth(0, "l", 1.0, 1.6, np.zeros(3), "ground", "LG"), StepTruth(1, "r", 2.0, 2.6, np.zeros(3), "tread", "SA")]
    preds = [ModePrediction(t, "SA", NAN3, si, 0.01) for t, si in ((0.9, 0), (1.5, 0), (1.8, 1))]
    m = score_predictions(steps, LocomotionEstimate(tuple(preds)), warmup_steps=0)
    assert m["accuracy"] == 0.5  # step 0 was decided SA at 0.9: wrong
    assert m["anticipation_s_LG_SA"] == pytest.approx(0.5)  # from 1.5, not from 0.9


def test_latency_statuses_and_footprint():
    m = score_predictions(_steps(), LocomotionEstimate(tuple(_preds())), warmup_steps=0, T_world_odom=_T_world_odom())
    # the 15 latencies are 0.1, 0.2 and 1..13 ms: median 6, p95 at rank 0.95 * 14 = 13.3 -> 12.3
    assert m["latency_ms_median"] == pytest.approx(6.0)
    assert m["latency_ms_p95"] == pytest.approx(12.3)
    assert (m["n_status_ok"], m["n_status_dropped"], m["n_status_no_depth"], m["n_faults"]) == (13, 1, 1, 2)
    assert m["n_status_few_strikes"] == 0
    # step 0: (0.5, 0) odom -> (1, 2.5) world vs (1.3, 2.9): 0.5 m; step 2: (1, -1) -> (2, 3): 0 m;
    # step 1's decision is stale (strike_index 0) and is left out
    assert m["footprint_error_m"] == pytest.approx(0.25)


def test_order_of_predictions_does_not_matter_but_ties_keep_output_order():
    rng = np.random.default_rng(0)
    shuffled = [_preds()[i] for i in rng.permutation(len(_ROWS))]
    a = score_predictions(_steps()[::-1], LocomotionEstimate(tuple(_preds())), warmup_steps=0)
    b = score_predictions(_steps(), LocomotionEstimate(tuple(shuffled)), warmup_steps=0)
    assert a["accuracy"] == b["accuracy"] and a["confusion"] == b["confusion"]
    assert a["anticipation_s"] == b["anticipation_s"]
    steps = [StepTruth(0, "l", 1.0, 1.6, np.zeros(3), "ground", "LG")]
    tie = [ModePrediction(1.0, "SA", NAN3, 0, 0.01), ModePrediction(1.0, "LG", NAN3, 0, 0.01)]
    assert score_predictions(steps, LocomotionEstimate(tuple(tie)), warmup_steps=0)["accuracy"] == 1.0


def test_no_predictions_and_bad_values_never_raise():
    m = score_predictions(_steps(), LocomotionEstimate(()), warmup_steps=0)
    assert m["failed"] is True and m["failed_reason"] == "no predictions"
    assert m["accuracy"] == 0.0 and m["n_undecided"] == 6
    bad = [ModePrediction(float("nan"), "LG", NAN3, 0, float("nan")), ModePrediction(0.5, "XX", NAN3, 0, float("inf"))]
    m = score_predictions(_steps(), LocomotionEstimate(tuple(bad)), warmup_steps=0, T_world_odom=_T_world_odom())
    assert m["n_undecided"] == 6 and m["accuracy"] == 0.0
    assert math.isnan(m["latency_ms_median"]) and math.isnan(m["footprint_error_m"])


def test_the_first_three_steps_are_warm_up():
    # default warm-up: steps 0-2 (LG LG SA) are left out; steps 3-5 are SA (RA: wrong), LG (right),
    # SD (undecided); the LG->SA transition at step 2 is in the warm-up, SA->LG and LG->SD are not
    m = score_predictions(_steps(), LocomotionEstimate(tuple(_preds())))
    assert (m["n_steps"], m["n_warmup_steps"]) == (3, 3)
    assert m["accuracy"] == pytest.approx(1 / 3)
    assert m["accuracy_incl_warmup"] == pytest.approx(4 / 6)
    assert (m["n_steps_LG"], m["n_steps_SA"], m["n_steps_SD"]) == (1, 1, 1)
    assert [t["step"] for t in m["transitions"]] == [4, 5]
    assert m["anticipation_s"] == pytest.approx(0.35)
