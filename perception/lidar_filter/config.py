"""The LiDAR filters' configs, one dataclass per filter, and the filter stage other pipelines hold.

Defaults: ``psi*_min = 16``: the thesis' experiment removes ``[0, 15]`` of the 0-255 byte
(section 5.2.2). ``psi*_max = 100``: the text leaves the upper bound open; 100 is the top of the
diffuse range of the calibrated intensity byte (core/frames.py), so specular glass glints and
blooming retro-reflectors are removed. ``ground_margin_m = 0.05`` (not in the text): the
footprint lies *on* the ground, so points of the ground scatter around z = 0 by the range noise
(VLP-16: +-3 cm) and a strict ``< 0`` would drop half of them. ``epsilon_eta = 0.05`` (normals
within 18 deg of the footprint z axis; open in the text): ramps (< 5 deg) pass, walls stay far
away. The range-image gates are set for the VLP-16's uniform 2 deg rings: sensors with wider
gaps between their lowest rings (VLP-32C) need a larger ``ri_ring_jump_rel`` (0.6 on the office
walk). See :mod:`.ground` and :mod:`.normals` for what each parameter does.
"""

from __future__ import annotations

from dataclasses import dataclass

from exobench.core.errors import ConfigError, check_int, check_range


@dataclass(frozen=True)
class NoFilterConfig:
    """The ``"none"`` filter has no parameters."""


@dataclass(frozen=True)
class IntensityBandConfig:
    """The kept intensity band ``psi* = [intensity_min, intensity_max]`` (bytes, inclusive)."""

    intensity_min: float = 16.0
    intensity_max: float = 100.0

    def __post_init__(self) -> None:
        lo = check_range("intensity_min", self.intensity_min, 0.0, 255.0)
        hi = check_range("intensity_max", self.intensity_max, 0.0, 255.0)
        if hi < lo:
            raise ConfigError("intensity_max", self.intensity_max, f"intensity_min ({lo}) <= intensity_max <= 255")


GROUND_TESTS = ("below", "band", "plane-band")


@dataclass(frozen=True)
class NaiveGroundConfig(IntensityBandConfig):
    """Naive ground-aware filter (eq. 4.16); see the module docstring for the ground tests.

    Attributes:
        ground_test: ``"below"`` (default, eq. 4.16 as written: footprint height below
            ``ground_margin_m``), ``"band"`` (footprint height in ``(-ground_depth_m,
            ground_margin_m)``) or ``"plane-band"`` (within ``plane_margin_m`` of the scan's own
            floor plane, found near the footprint plane; ``"band"`` when no plane is found; the
            default of :class:`FloorGroundFilter`).
        ground_margin_m: a point is ground when its footprint height is below this, m (0..0.5).
        ground_depth_m: ``"band"``: ... and above minus this, m (0..1].
        plane_margin_m: ``"plane-band"``: half-width of the band around the scan's floor plane, m
            (0..0.2].
        plane_search_m: ``"plane-band"``: the floor plane is fitted to the points within this of
            the footprint plane and may lie at most this far from it (at the footprint origin), m
            (0..0.5].
        use_full_transform: rotate into the footprint frame (True) or use only ``^l z_f``, the
            level-LiDAR form of eq. (4.16) (False).
    """

    ground_test: str = "below"
    ground_margin_m: float = 0.05
    ground_depth_m: float = 0.1
    plane_margin_m: float = 0.03
    plane_search_m: float = 0.1
    use_full_transform: bool = True

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.ground_test not in GROUND_TESTS:
            raise ConfigError("ground_test", self.ground_test, " or ".join(repr(m) for m in GROUND_TESTS))
        check_range("ground_margin_m", self.ground_margin_m, 0.0, 0.5)
        check_range("ground_depth_m", self.ground_depth_m, 0.0, 1.0, low_open=True)
        check_range("plane_margin_m", self.plane_margin_m, 0.0, 0.2, low_open=True)
        check_range("plane_search_m", self.plane_search_m, 0.0, 0.5, low_open=True)
        if not isinstance(self.use_full_transform, bool):
            raise ConfigError("use_full_transform", self.use_full_transform, "True or False")


@dataclass(frozen=True)
class FloorGroundConfig(NaiveGroundConfig):
    """The floor-plane ground-aware filter (:class:`FloorGroundFilter`): :class:`NaiveGroundConfig`
    with the ground test ``"plane-band"``."""

    ground_test: str = "plane-band"


NORMAL_METHODS = ("range-image", "knn")


@dataclass(frozen=True)
class NormalGroundConfig(IntensityBandConfig):
    """Normal ground-aware filter (eq. 4.17-4.19).

    Attributes:
        epsilon_eta: a point is ground when ``theta_eta > 1 - epsilon_eta`` (0 < eps < 1).
        normal_method: ``"range-image"`` (ring-organised scans; others fall back to knn) or
            ``"knn"`` (the thesis' PCL method); see the module docstring.
        normal_k: neighbours (query point included) of the knn PCA normal, 3..100.
        normal_radius_m: knn neighbours farther than this are not used, m.
        ri_col_halfwidth: range image: azimuth columns on each side of a point, 1..32.
        ri_azimuth_jump_rel: range image: an azimuth neighbour whose range differs by more than
            this fraction of the point's is skipped (0..1].
        ri_ring_jump_rel: range image: a ring neighbour whose range differs by more than this
            fraction of the nearer of the two ranges is across a depth jump, (0..2].
        ri_max_ring_skip: range image: rings without a return skipped to find the ring
            neighbour above / below, 1..4 (1 = only the adjacent ring).
    """

    epsilon_eta: float = 0.05
    normal_method: str = "range-image"
    normal_k: int = 10
    normal_radius_m: float = 0.5
    ri_col_halfwidth: int = 4
    ri_azimuth_jump_rel: float = 0.1
    ri_ring_jump_rel: float = 0.3
    ri_max_ring_skip: int = 2

    def __post_init__(self) -> None:
        super().__post_init__()
        check_range("epsilon_eta", self.epsilon_eta, 0.0, 1.0, low_open=True, high_open=True)
        if self.normal_method not in NORMAL_METHODS:
            raise ConfigError("normal_method", self.normal_method, " or ".join(repr(m) for m in NORMAL_METHODS))
        object.__setattr__(self, "normal_k", check_int("normal_k", self.normal_k, 3, 100))
        check_range("normal_radius_m", self.normal_radius_m, 0.0, 10.0, low_open=True)
        object.__setattr__(self, "ri_col_halfwidth", check_int("ri_col_halfwidth", self.ri_col_halfwidth, 1, 32))
        check_range("ri_azimuth_jump_rel", self.ri_azimuth_jump_rel, 0.0, 1.0, low_open=True)
        check_range("ri_ring_jump_rel", self.ri_ring_jump_rel, 0.0, 2.0, low_open=True)
        object.__setattr__(self, "ri_max_ring_skip", check_int("ri_max_ring_skip", self.ri_max_ring_skip, 1, 4))

    def range_image_params(self) -> dict[str, float | int]:
        """Keyword arguments of :func:`range_image_normal_candidates`."""
        return {"col_halfwidth": self.ri_col_halfwidth, "azimuth_jump_rel": self.ri_azimuth_jump_rel,
                "ring_jump_rel": self.ri_ring_jump_rel, "max_ring_skip": self.ri_max_ring_skip}  # fmt: skip


FILTER_KINDS = ("none", "threshold", "naive-ground", "normal-ground", "floor-ground")


@dataclass(frozen=True)
class FilterStageConfig:
    """A filter as a stage of another pipeline (e.g. ``KissIcpPipeline.Config.filter``).

    ``kind`` picks the filter (a name of :data:`FILTER_KINDS`, the names of
    :data:`~exobench.perception.lidar_filter.filters.FILTERS`); the parameters of each filter
    are the nested config of that name (``threshold.intensity_min``,
    ``naive_ground.ground_margin_m``, ...). Only the one of ``kind`` is used; all are saved.
    """

    kind: str = "none"
    threshold: IntensityBandConfig = IntensityBandConfig()
    naive_ground: NaiveGroundConfig = NaiveGroundConfig()
    normal_ground: NormalGroundConfig = NormalGroundConfig()
    floor_ground: FloorGroundConfig = FloorGroundConfig()

    def __post_init__(self) -> None:
        if self.kind not in FILTER_KINDS:
            raise ConfigError("kind", self.kind, " or ".join(repr(k) for k in FILTER_KINDS))

    def config(self) -> object:
        """The config of the chosen filter (:class:`NoFilterConfig` for ``"none"``)."""
        return NoFilterConfig() if self.kind == "none" else getattr(self, self.kind.replace("-", "_"))
