"""RGB-D camera configuration (Intel RealSense D455 defaults) and its pinhole intrinsics.

Defaults come from ``docs/sensor-reference.md`` (RGB-D section); [A] marks an assumption, [D] a derived value.
Pixel convention: pixel (u, v) = (column, row) has its centre at integer coordinates, so the
principal point of a centred sensor is ((W - 1) / 2, (H - 1) / 2); a point (x, y, z) in the
optical frame (z forward, x right, y down) projects to u = fx x / z + cx, v = fy y / z + cy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from exobench.core import ConfigError, check_int, check_range

# D455 depth intrinsics per resolution (docs/sensor-reference.md): (fx, fy, cx, cy) in pixels; None = centred
_D455_INTRINSICS: dict[tuple[int, int], tuple[float, float, float | None, float | None]] = {
    (640, 480): (384.0, 384.0, 319.5, 236.4),
    (848, 480): (424.0, 424.0, None, None),  # [D]
}
_D455_REF_WIDTH_PX, _D455_REF_FX_PX = 848, 424.0


@dataclass(frozen=True)
class RgbdConfig:
    """One RGB-D camera (depth registered to colour, both with the same intrinsics).

    Output: :class:`~exobench.core.RgbdFrame` in the camera's optical frame (z forward, x right,
    y down): ``rgb`` (H, W, 3) uint8, ``depth_m`` z-depth (H, W) float32 m (0 = invalid), ``K``.
    Sources: docs/sensor-reference.md (RGB-D: D455 data sheet; librealsense issues #3904, #6697, #7996, #9241).

    Attributes:
        width_px / height_px: image size, pixels (640 x 480; the D455 is best at 848 x 480).
        fx_px / fy_px / cx_px / cy_px: pinhole intrinsics, pixels. ``None`` = the D455 value for
            the resolution: 640x480 -> fx = fy = 384, cx = 319.5, cy = 236.4; 848x480 -> fx =
            fy = 424, centred; other sizes -> fx = fy = 424 * width / 848 (the 848x480 field of
            view) [A], centred.
        rate_hz: frame rate, Hz (30).
        latency_s: delivery delay after the measurement, s [A: 0].
        min_depth_m: no depth closer than this, m (``None`` = 0.4, or 0.34 at 848x480).
        max_depth_m: no depth farther than this, m (6).
        subpixel: stereo matching accuracy s in pixels; the depth noise is zero-mean Gaussian
            with sigma(z) = z^2 * s / (fx * baseline) (0.08; 0.032 well calibrated; 0 = off).
        baseline_m: stereo baseline, m (0.095).
        edge_threshold_rel: a pixel is invalid when the true depth of a 4-neighbour differs by
            more than this fraction of the nearer depth (stereo matching fails at depth
            discontinuities) [A: 0.05; 0 = off].
        resolution_m: depth quantisation, m (1e-3, the D4xx default depth unit [A]; 0 = off).
        dropout_prob: probability a frame is lost [A: 0].
        pixel_dropout_prob: probability a pixel is invalid at random (dark or specular
            surfaces) [A: 0].
        shadows: render shadows in the colour image (off by default: with software OpenGL
            they make a frame about five times slower; depth is not affected).
        segmentation: render the per-pixel geom ids of every frame (the capture truth's
            ``geom_id``) even when nothing in the recording reads them. Off by default: a
            recording renders them only for a consumer (``segmentation_truth``, or the image
            share of watched geoms such as pedestrians); without them ``geom_id`` is -1
            everywhere. Read with the depth, they cost about a tenth of a frame.
        segmentation_truth: keep a :class:`~exobench.core.SegmentationTruth` of every emitted
            frame (geom, surface and object of each pixel; ``EpisodeTruth.segmentation``); renders
            the geom ids. Off by default.
        exposure_s: colour exposure time, s; > 0 blurs each colour image with the camera's
            motion during it (:mod:`.blur`; at most one frame period). 0 (default): sharp, as
            before. Indoors a D455's auto exposure runs about 5-33 ms [A].
        depth_through_glass: the depth image looks through transparent geoms (glass, drawn
            see-through in the colour image) to the surface behind them, as a D455's active IR
            stereo does through clear glass (docs/vio-realism.md, "Depth through glass"); the
            geom ids then name that surface too. False: the depth and ids are the pane's, as
            before (True by default).
    """

    width_px: int = 640
    height_px: int = 480
    fx_px: float | None = None
    fy_px: float | None = None
    cx_px: float | None = None
    cy_px: float | None = None
    rate_hz: float = 30.0
    latency_s: float = 0.0
    min_depth_m: float | None = None
    max_depth_m: float = 6.0
    subpixel: float = 0.08
    baseline_m: float = 0.095
    edge_threshold_rel: float = 0.05
    resolution_m: float = 1e-3
    dropout_prob: float = 0.0
    pixel_dropout_prob: float = 0.0
    shadows: bool = False
    segmentation: bool = False
    segmentation_truth: bool = False
    exposure_s: float = 0.0
    depth_through_glass: bool = True

    def __post_init__(self) -> None:
        w = check_int("rgbd.width_px", self.width_px, 1, 4096)
        h = check_int("rgbd.height_px", self.height_px, 1, 4096)
        object.__setattr__(self, "width_px", w)
        object.__setattr__(self, "height_px", h)
        fx0, fy0, cx0, cy0 = _D455_INTRINSICS.get((w, h), (None, None, None, None))
        f_scaled = _D455_REF_FX_PX * w / _D455_REF_WIDTH_PX
        defaults = {
            "fx_px": fx0 if fx0 is not None else f_scaled,
            "fy_px": fy0 if fy0 is not None else f_scaled,
            "cx_px": cx0 if cx0 is not None else 0.5 * (w - 1),
            "cy_px": cy0 if cy0 is not None else 0.5 * (h - 1),
            "min_depth_m": 0.34 if (w, h) == (848, 480) else 0.4,
        }
        for name, value in defaults.items():
            if getattr(self, name) is None:
                object.__setattr__(self, name, float(value))
        check_range("rgbd.fx_px", self.fx_px, 0.0, 1e5, low_open=True)
        check_range("rgbd.fy_px", self.fy_px, 0.0, 1e5, low_open=True)
        check_range("rgbd.cx_px", self.cx_px, -0.5, w - 0.5)
        check_range("rgbd.cy_px", self.cy_px, -0.5, h - 0.5)
        check_range("rgbd.rate_hz", self.rate_hz, 0.0, 1000.0, low_open=True)
        check_range("rgbd.latency_s", self.latency_s, 0.0, 1.0)
        check_range("rgbd.max_depth_m", self.max_depth_m, 0.0, 1000.0, low_open=True)
        check_range("rgbd.min_depth_m", self.min_depth_m, 0.0, self.max_depth_m, high_open=True)
        check_range("rgbd.subpixel", self.subpixel, 0.0, 10.0)
        check_range("rgbd.baseline_m", self.baseline_m, 0.0, 1.0, low_open=True)
        check_range("rgbd.edge_threshold_rel", self.edge_threshold_rel, 0.0, 10.0)
        check_range("rgbd.resolution_m", self.resolution_m, 0.0, 0.05)
        check_range("rgbd.dropout_prob", self.dropout_prob, 0.0, 1.0, high_open=True)
        check_range("rgbd.pixel_dropout_prob", self.pixel_dropout_prob, 0.0, 1.0)
        check_range("rgbd.exposure_s", self.exposure_s, 0.0, 1.0 / self.rate_hz)
        for name in ("shadows", "segmentation", "segmentation_truth", "depth_through_glass"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise ConfigError(f"rgbd.{name}", getattr(self, name), "True or False")


def intrinsics(config: RgbdConfig) -> np.ndarray:
    """The 3x3 pinhole matrix K of a camera config (pixels)."""
    return np.array([[config.fx_px, 0.0, config.cx_px], [0.0, config.fy_px, config.cy_px], [0.0, 0.0, 1.0]])


def depth_noise_sigma_m(depth_m: np.ndarray | float, config: RgbdConfig) -> np.ndarray:
    """Standard deviation of the depth noise at depth z: z^2 * s / (fx * baseline), m."""
    z = np.asarray(depth_m, dtype=float)
    return z * z * (config.subpixel / (config.fx_px * config.baseline_m))
