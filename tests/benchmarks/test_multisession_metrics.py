"""The change and map-quality scorer of the multisession track (seeds/000 Exp B-C) on point sets
whose scores are computed by hand in the comments."""

import math

import numpy as np
import pytest

from exobench.benchmarks.tracks.multisession.metrics import (
    change_chamfer_m,
    change_confusion,
    change_f1,
    change_precision,
    change_precision_whole_map,
    change_recall,
    change_recall_whole_map,
    map_error_metrics,
)


def _x(*xs):
    return np.array([[x, 0.0, 0.0] for x in xs])


TRUE_CHANGED = _x(0.0, 0.1, 0.2)
TRUE_STATIC = _x(0.5, *np.round(np.arange(1.0, 2.01, 0.1), 2))
# detected changed: 0.01, 0.12 near changed samples (TP); 0.49 near the static 0.5 and 0.29 m
# from the changed 0.2, inside the changed area (FP); 1.5 static, outside the area (FP of the
# whole map only); 5.0 near nothing (not counted)
DETECTED_CHANGED = _x(0.01, 0.12, 0.49, 1.5, 5.0)
# detected static: 0.2 on a changed sample (FN); 0.48 near the static 0.5, 0.28 m from 0.2 (TN);
# 1.0 static outside the area (TN of the whole map only)
DETECTED_STATIC = _x(0.2, 0.48, 1.0)
ARGS = (DETECTED_CHANGED, DETECTED_STATIC, TRUE_CHANGED, TRUE_STATIC)


def test_confusion_over_changed_areas_and_whole_map():
    c = change_confusion(*ARGS)
    assert (c.tp, c.fp, c.fn, c.tn) == (2, 1, 1, 1)
    w = change_confusion(*ARGS, area_m=None)
    assert (w.tp, w.fp, w.fn, w.tn) == (2, 2, 1, 2)


def test_a_point_goes_to_its_nearest_sample_when_changed_and_static_ones_are_both_near():
    # a box's foot: changed samples on its face at x = 0, the floor static from x = 0.03 on;
    # detected static 0.035 (floor, 3.5 cm from the face, 0.5 cm from the floor) is a true
    # negative, 0.01 (on the face) a false negative; detected changed 0.045 (on the floor) a false
    # positive, 0.005 a true positive; a tie (0.015: 1.5 cm from both) goes to the change
    changed, static = _x(0.0), _x(0.03, 0.04, 0.05)
    c = change_confusion(_x(0.005, 0.045, 0.015), _x(0.01, 0.035), changed, static)
    assert (c.tp, c.fp, c.fn, c.tn) == (2, 1, 1, 1)


def test_precision_recall_f1_by_hand():
    assert change_precision(*ARGS) == pytest.approx(2 / 3)
    assert change_recall(*ARGS) == pytest.approx(2 / 3)
    assert change_f1(*ARGS) == pytest.approx(2 / 3)
    assert change_precision_whole_map(*ARGS) == pytest.approx(0.5)
    assert change_recall_whole_map(*ARGS) == pytest.approx(2 / 3)


def test_undefined_ratios_are_nan_and_no_recall_is_zero_f1():
    assert math.isnan(change_precision(_x(), DETECTED_STATIC, TRUE_CHANGED, TRUE_STATIC))
    assert math.isnan(change_recall(DETECTED_CHANGED, DETECTED_STATIC, _x(), TRUE_STATIC))
    # only a false positive and a false negative: P = R = 0, F1 = 0
    assert change_f1(_x(0.49), _x(0.2), TRUE_CHANGED, TRUE_STATIC) == 0.0


def test_chamfer_by_hand():
    # in the area: 0.01, 0.12, 0.49 -> nearest true 0.01, 0.02, 0.29 (mean 0.32 / 3);
    # true 0, 0.1, 0.2 -> nearest detected 0.01, 0.02, 0.08 (mean 0.11 / 3)
    assert change_chamfer_m(DETECTED_CHANGED, TRUE_CHANGED) == pytest.approx(0.5 * (0.32 / 3 + 0.11 / 3))
    # whole map: 1.5 and 5.0 add 1.3 and 4.8 to the first mean (5 points)
    assert change_chamfer_m(DETECTED_CHANGED, TRUE_CHANGED, area_m=None) == pytest.approx(
        0.5 * ((0.32 + 1.3 + 4.8) / 5 + 0.11 / 3))
    assert math.isnan(change_chamfer_m(_x(5.0), TRUE_CHANGED))


def test_map_error_statistics_by_hand():
    truth = _x(0.0, 1.0, 2.0, 3.0)
    # errors 0.1, 0, 0.5, 0.02, 0: sorted 0, 0, 0.02, 0.1, 0.5; p90 at rank 3.6: 0.1 + 0.6 * 0.4
    m = map_error_metrics(_x(0.1, 1.0, 2.5, 3.02, 0.0), truth)
    assert m["map_error_mean_m"] == pytest.approx(0.124)
    assert m["map_error_median_m"] == pytest.approx(0.02)
    assert m["map_error_p90_m"] == pytest.approx(0.34)
    assert m["map_error_max_m"] == pytest.approx(0.5)
    assert all(math.isnan(v) for v in map_error_metrics(_x(), truth).values())


def test_static_truth_given_as_the_days_sets_scores_as_their_union():
    """The static samples of two days (each a building's worth) need not be joined: the counts by
    hand above, with the static samples split between two sets in either way, and with a third
    set of samples far from every point (left out of the trees) beside them."""
    far = np.array([[50.0, 50.0, 50.0], [-40.0, 3.0, 1.0]])
    for parts in ((TRUE_STATIC[:3], TRUE_STATIC[3:]), (TRUE_STATIC[::2], TRUE_STATIC[1::2], far)):
        c = change_confusion(DETECTED_CHANGED, DETECTED_STATIC, TRUE_CHANGED, parts)
        assert (c.tp, c.fp, c.fn, c.tn) == (2, 1, 1, 1)
        w = change_confusion(DETECTED_CHANGED, DETECTED_STATIC, TRUE_CHANGED, parts, area_m=None)
        assert (w.tp, w.fp, w.fn, w.tn) == (2, 2, 1, 2)
