"""D-VIO's front end: KLT feature tracking and keyframe choice by parallax (seeds/002 II-C).

The paper takes VINS-Mono's tracker; the defaults are VINS-Mono's (``config/euroc/
euroc_config.yaml``: ``max_cnt`` 150, ``min_dist`` 30 px, ``F_threshold`` 1 px,
``keyframe_parallax`` 10 px; pyramidal LK with a 21 px window and 3 levels, as
``feature_tracker.cpp``) with VINS-Fusion's forward-backward check (``flow_back``, 0.5 px):
the paper gives no numbers of its own. Per frame (:meth:`FeatureTracker.track`):

0. equalise the grey image with CLAHE (clip limit 3, 8x8 tiles), as VINS-Mono does with its
   default ``equalize: 1`` ("if image is too dark or light ... to find enough features"): a dim
   room's image or a plain wall's weak texture otherwise gives KLT too few corners to hold
   (docs/tracks/vio.md, "The general draw");
1. track the previous frame's features with ``cv2.calcOpticalFlowPyrLK``, track the result back,
   keep those found both ways that land within ``fb_max_px`` of their start and inside the image;
2. reject outliers with a fundamental-matrix RANSAC (``ransac_px`` from the epipolar line) when
   at least 8 survive;
3. keep the longest-tracked features first and drop any within ``min_distance_px`` of a kept one
   (VINS-Mono's ``setMask``), then detect ``cv2.goodFeaturesToTrack`` corners away from them up
   to ``max_features``, with new ids;
4. the frame is a keyframe if it is the first, if fewer than ``min_tracked`` features are shared
   with the last keyframe, or if their mean displacement since it (parallax, px) reaches
   ``keyframe_parallax_px``. VINS-Mono measures it between the second and third newest frames of
   its window; here it is measured against the last keyframe, which chooses the same frames on a
   steady motion and needs no window.

Input never raises: a frame whose stamp is not after the previous one is skipped (None, counted
in :attr:`FeatureTracker.skipped`), NaN pixels read as black, a featureless image gives a frame
without features, after which tracking restarts by detection.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from exobench.core.errors import check_int, check_range

__all__ = ["FeatureTracker", "TrackedFrame", "TrackerConfig", "normalised"]


@dataclass(frozen=True)
class TrackerConfig:
    """Front-end parameters (VINS-Mono's defaults, see the module docstring); pixels."""

    max_features: int = 150
    min_distance_px: float = 30.0
    quality_level: float = 0.01
    win_size_px: int = 21
    pyramid_levels: int = 3
    fb_max_px: float = 0.5
    ransac_px: float = 1.0
    ransac_confidence: float = 0.99
    keyframe_parallax_px: float = 10.0
    min_tracked: int = 20
    equalize: bool = True

    def __post_init__(self) -> None:
        check_int("tracker.max_features", self.max_features, 1, 5000)
        check_range("tracker.min_distance_px", self.min_distance_px, 1.0, 500.0)
        check_range("tracker.quality_level", self.quality_level, 0.0, 1.0, low_open=True)
        check_int("tracker.win_size_px", self.win_size_px, 5, 101)
        check_int("tracker.pyramid_levels", self.pyramid_levels, 0, 8)
        check_range("tracker.fb_max_px", self.fb_max_px, 0.0, 50.0, low_open=True)
        check_range("tracker.ransac_px", self.ransac_px, 0.0, 50.0, low_open=True)
        check_range("tracker.ransac_confidence", self.ransac_confidence, 0.5, 1.0, high_open=True)
        check_range("tracker.keyframe_parallax_px", self.keyframe_parallax_px, 0.0, 1000.0, low_open=True)
        check_int("tracker.min_tracked", self.min_tracked, 0, 5000)


@dataclass(frozen=True, eq=False)
class TrackedFrame:
    """The features of one frame.

    Attributes:
        stamp_s: frame time.
        ids: (N,) feature ids, unique over the tracker's life.
        pts_px: (N, 2) pixel positions (x right, y down).
        track_len: (N,) frames each feature has been seen in, this one included.
        is_keyframe: chosen as a keyframe (see the module docstring).
        parallax_px: mean displacement of the features shared with the last keyframe (0 on a
            keyframe that starts the tracking, NaN if none is shared).
        n_shared: number of those features.
    """

    stamp_s: float
    ids: np.ndarray
    pts_px: np.ndarray
    track_len: np.ndarray
    is_keyframe: bool
    parallax_px: float
    n_shared: int


def normalised(pts_px: np.ndarray, fx: float, fy: float, cx: float, cy: float) -> np.ndarray:
    """(N, 2) pixels of a pinhole camera to normalised-plane coordinates (the factors' ``u``)."""
    p = np.asarray(pts_px, dtype=float).reshape(-1, 2)
    return np.column_stack([(p[:, 0] - cx) / fx, (p[:, 1] - cy) / fy])


def _gray(image: np.ndarray) -> np.ndarray:
    img = np.asarray(image)
    if img.ndim == 3:
        img = img[..., :3].mean(axis=2) if img.shape[2] >= 3 else img[..., 0]
    if img.dtype != np.uint8:
        f = np.nan_to_num(img.astype(np.float64), nan=0.0, posinf=0.0, neginf=0.0)
        # Float images in [0, 1] (rendered) are scaled; anything else is taken as 0-255 counts.
        if f.size and f.max() <= 1.0:
            f = f * 255.0
        img = np.clip(f, 0.0, 255.0).astype(np.uint8)
    return np.ascontiguousarray(img)


class FeatureTracker:
    """KLT tracker with keyframe choice; one instance per camera stream."""

    def __init__(self, config: TrackerConfig | None = None) -> None:
        self.config = config if config is not None else TrackerConfig()
        self.skipped = 0
        self._next_id = 0
        self._prev_img: np.ndarray | None = None
        self._prev_stamp = -math.inf
        self._ids = np.zeros(0, dtype=np.int64)
        self._pts = np.zeros((0, 2), dtype=np.float32)
        self._len = np.zeros(0, dtype=np.int64)
        self._kf: dict[int, np.ndarray] | None = None
        self._clahe = cv2.createCLAHE(clipLimit=3.0, tileGridSize=(8, 8))

    def track(self, stamp_s: float, image: np.ndarray) -> TrackedFrame | None:
        """Track into ``image`` (HxW or HxWxC) taken at ``stamp_s``; None if the stamp is skipped."""
        if not (math.isfinite(stamp_s) and stamp_s > self._prev_stamp):
            self.skipped += 1
            return None
        gray = _gray(image)
        if self.config.equalize:
            gray = self._clahe.apply(gray)
        if self._prev_img is not None and self._prev_img.shape == gray.shape and len(self._pts):
            self._flow(self._prev_img, gray)
        else:
            self._keep(np.zeros(len(self._ids), dtype=bool))
        self._len = self._len + 1
        self._thin_and_detect(gray)
        self._prev_img, self._prev_stamp = gray, stamp_s
        return self._keyframe(stamp_s)

    def _keep(self, mask: np.ndarray) -> None:
        self._ids, self._pts, self._len = self._ids[mask], self._pts[mask], self._len[mask]

    def _flow(self, prev: np.ndarray, cur: np.ndarray) -> None:
        c = self.config
        lk = {"winSize": (c.win_size_px, c.win_size_px), "maxLevel": c.pyramid_levels}
        p0 = self._pts.reshape(-1, 1, 2)
        p1, st, _ = cv2.calcOpticalFlowPyrLK(prev, cur, p0, None, **lk)
        back, st_b, _ = cv2.calcOpticalFlowPyrLK(cur, prev, p1, None, **lk)
        p1, back = p1.reshape(-1, 2), back.reshape(-1, 2)
        h, w = cur.shape
        ok = (st.ravel() == 1) & (st_b.ravel() == 1) & np.all(np.isfinite(p1), axis=1)
        ok &= np.linalg.norm(back - self._pts, axis=1) <= c.fb_max_px
        # One pixel of margin, as VINS-Mono's inBorder: LK's window is clipped at the edge.
        ok &= (p1[:, 0] >= 1) & (p1[:, 0] < w - 1) & (p1[:, 1] >= 1) & (p1[:, 1] < h - 1)
        if ok.sum() >= 8:
            idx = np.flatnonzero(ok)
            _, inl = cv2.findFundamentalMat(self._pts[idx], p1[idx], cv2.FM_RANSAC, c.ransac_px,
                                            c.ransac_confidence)
            if inl is not None and len(inl) == len(idx):
                ok[idx[inl.ravel() == 0]] = False
        self._pts = p1.astype(np.float32)
        self._keep(ok)

    def _thin_and_detect(self, gray: np.ndarray) -> None:
        c = self.config
        mask = np.full(gray.shape, 255, dtype=np.uint8)
        radius = int(round(c.min_distance_px))
        keep = np.zeros(len(self._ids), dtype=bool)
        for k in np.argsort(-self._len, kind="stable"):  # oldest tracks claim their area first
            x, y = (int(round(v)) for v in self._pts[k])
            if mask[y, x] == 255:
                keep[k] = True
                cv2.circle(mask, (x, y), radius, 0, -1)
        self._keep(keep)
        n_new = c.max_features - len(self._ids)
        if n_new <= 0 or gray.min() == gray.max():
            return
        corners = cv2.goodFeaturesToTrack(gray, n_new, c.quality_level, c.min_distance_px, mask=mask)
        if corners is None:
            return
        new = corners.reshape(-1, 2).astype(np.float32)
        ids = np.arange(self._next_id, self._next_id + len(new), dtype=np.int64)
        self._next_id += len(new)
        self._ids = np.concatenate([self._ids, ids])
        self._pts = np.vstack([self._pts, new])
        self._len = np.concatenate([self._len, np.ones(len(new), dtype=np.int64)])

    def _keyframe(self, stamp_s: float) -> TrackedFrame:
        c = self.config
        if self._kf is None:
            is_kf, parallax, n_shared = True, 0.0, 0
        else:
            shared = [(k, p) for k, p in zip(self._ids.tolist(), self._pts, strict=True) if k in self._kf]
            n_shared = len(shared)
            parallax = (float(np.mean([np.linalg.norm(p - self._kf[k]) for k, p in shared]))
                        if shared else math.nan)
            is_kf = n_shared < c.min_tracked or parallax >= c.keyframe_parallax_px
        if is_kf:
            self._kf = {k: p.copy() for k, p in zip(self._ids.tolist(), self._pts, strict=True)}
        return TrackedFrame(stamp_s, self._ids.copy(), self._pts.astype(float), self._len.copy(), is_kf,
                            parallax, n_shared)
