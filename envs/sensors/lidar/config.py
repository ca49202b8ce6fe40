"""Configuration of a scanning LiDAR (Velodyne VLP-16 by default): pattern, noise, detection, optics, casting."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from exobench.core import ConfigError, check_int, check_range
from exobench.models.materials import KINDS, LidarMaterial

from .pattern import LidarPattern

INTENSITY_MODES = ("signal", "reflectivity")
RETURN_MODES = ("sampled", "strongest", "last")
CASTERS = ("bvh", "mujoco")


@dataclass(frozen=True)
class LidarConfig:
    """A LiDAR's pattern, noise, detection, optics switches and casting options.

    Output: :class:`~exobench.core.LidarScan`, points in the sensor frame (x forward, y left,
    z up) at their firing time, m, with an intensity byte, ring and time offset; per point a
    :class:`~exobench.core.LidarTruth`. Sources: VLP-16 manual, VLP-32C calibration file, Ouster
    OS1 and Livox Mid-40 data sheets (docs/sensor-reference.md); [A] marks an assumption.

    Attributes:
        pattern: channels, timing and range limits (default VLP-16 at 10 Hz); its ``rate_hz``
            (sweeps per second, Hz) is the sensor's rate (also :attr:`rate_hz`).
        range_noise_m: standard deviation of the range noise, m [A: 0.015, reading the data
            sheet's +-3 cm accuracy as two sigma].
        resolution_m: range quantisation, m (0.002: the VLP-16 packet distance unit; 0 = off).
        detection_threshold: returns whose signal (intensity scale, unclipped) is below are
            dropped [A: 1.0, so white is seen frontally to 100 m, concrete to about 66 m].
        ref_reflectivity / ref_range_m: a surface of ``ref_reflectivity`` at ``ref_range_m``,
            frontal, has signal 100 (0.8 white at 10 m).
        intensity_mode: ``"signal"``: the byte is the Lambertian signal (cos / r^2; bright
            surfaces nearer than about 10 m saturate at 100); ``"reflectivity"``: the byte is the
            range-compensated calibrated reflectivity ``100 * G * rho * |cos(incidence)|`` (how the
            VLP-16 reports it; ``G`` < 1 only for ghosts and returns through glass, see
            :mod:`exobench.envs.sensors.lidar.optics`). Detection uses the signal in both.
        latency_s: delivery delay after the end of the sweep, s [A: 0].
        dropout_prob: probability a whole sweep is lost [A: 0].
        point_dropout_prob: probability a return is lost [A: 0].
        nan_point_prob: probability a return is reported as NaN (x, y, z NaN, intensity 0; its
            truth entry stays, of kind ``ReturnKind.NAN``), [0, 1] [A: 0].
        duplicate_prob: probability a delivered sweep is delivered twice (a second identical
            frame, same stamp, same truth), [0, 1] [A: 0].
        out_of_order_prob: probability a sweep is delivered late, after the next one: its
            ``stamp_s`` (delivery time) grows by 1.5 sweep periods, its ``sweep_start_s`` stays;
            the next sweep, which overtakes it, is on time (at 1, pairs swap), [0, 1] [A: 0].
        time_jump_prob: probability the sensor's clock steps by ``time_jump_s`` at a sweep; the
            step holds for that sweep and every later one (``stamp_s`` and ``sweep_start_s`` shift,
            the truth trajectory stays in true time), [0, 1] [A: 0].
        time_jump_s: size of one clock step, s, [-10, 10] (negative: back in time) [A: 1].
        glass: model glass (transmission, pane reflection, ghosts); off = panes are opaque
            weak reflectors (what most simulators do).
        mirrors: model specular reflection of mirror materials (ghosts); off = opaque.
        max_interactions: glass/mirror events followed per beam.
        pose_blocks: firing blocks share a pose in this many groups per sweep (0 = one pose per
            firing block, exact; fewer = fewer ``pose_at`` times, the motion within a group is
            ignored).
        cast_period_s: firings within this window are cast from one origin and their ranges
            moved to their own origins on the face hit (see :mod:`~exobench.envs.sensors.lidar.cast`)
            [A: 1 ms];
            0 = one ``mj_multiRay`` call per firing block.
        cast_threads: threads casting the rays (0 = one per available CPU, at most 8; 1 = the
            calling thread only); results do not depend on it.
        cast_near_m: rays are cast first against the geoms within this distance (``mj_multiRay``
            drops the farther ones before tracing), and those without a hit that near again
            against all: the same hits, faster where most returns are near (offices) [A: 8 m];
            0 = one pass.
        caster: ``"bvh"`` (the default) or ``"mujoco"``. ``"bvh"``: static boxes and planes by Embree (a BVH: the cost does not grow with
            the building), hits recomputed with MuJoCo's arithmetic, moving and curved geoms by
            MuJoCo, the nearer hit; secondary rays in batches (:mod:`~exobench.envs.sensors.lidar.bvh`);
            ``"mujoco"``: every ray by ``mj_multiRay`` / ``mj_ray`` (the reference). A scene the
            BVH cannot take (meshes, height fields, SDFs, flexes, skins) is cast by MuJoCo, with a
            ``RuntimeWarning`` once.
        zoned_cast: cast on a private copy of the ray-visible geoms grouped in spatial zones
            (:mod:`exobench.envs.sensors.lidar.ray_scene`; a quarter less casting time in the office, same hits);
            False = cast on the simulation's model.
        materials: extra or replacement materials by name (on top of ``models.materials``).
        return_mode: the echo reported when a pulse splits at glass (:mod:`~exobench.envs.sensors.lidar.optics`):
            ``"sampled"`` (one path drawn per beam), ``"strongest"`` (the VLP-16 manual's
            default) or ``"last"``.
        glass_bow_mm_per_m: overall bow of every glass pane, centre deflection in mm per metre
            of the pane's diagonal (:mod:`~exobench.envs.sensors.lidar.pane_shape`; 0 = flat;
            EN 12150-1 allows 3 for horizontally toughened float glass, see
            :mod:`exobench.models.materials`).
        glass_roller_wave_mm: roller wave of every glass pane, peak-to-valley, mm (0 = none).
        glass_roller_wave_length_m: the roller wave's wavelength, m [A: 0.35, the furnace's roll pitch].
        glass_shape_seed: seed of each pane's bow sign, roller direction and wave phase (a
            property of the building: the office's seed, not the run's).
    """

    pattern: LidarPattern = field(default_factory=LidarPattern.vlp16)
    range_noise_m: float = 0.015
    resolution_m: float = 0.002
    detection_threshold: float = 1.0
    ref_reflectivity: float = 0.8
    ref_range_m: float = 10.0
    intensity_mode: str = "reflectivity"
    latency_s: float = 0.0
    dropout_prob: float = 0.0
    point_dropout_prob: float = 0.0
    nan_point_prob: float = 0.0
    duplicate_prob: float = 0.0
    out_of_order_prob: float = 0.0
    time_jump_prob: float = 0.0
    time_jump_s: float = 1.0
    glass: bool = True
    mirrors: bool = True
    max_interactions: int = 3
    pose_blocks: int = 0
    cast_period_s: float = 1e-3
    cast_threads: int = 0
    cast_near_m: float = 8.0
    zoned_cast: bool = True
    caster: str = "bvh"
    materials: tuple[LidarMaterial, ...] = ()
    return_mode: str = "sampled"
    glass_bow_mm_per_m: float = 0.0
    glass_roller_wave_mm: float = 0.0
    glass_roller_wave_length_m: float = 0.35
    glass_shape_seed: int = 0

    def __post_init__(self) -> None:
        if not isinstance(self.pattern, LidarPattern):
            raise ConfigError("lidar.pattern", self.pattern, "a LidarPattern")
        check_range("lidar.range_noise_m", self.range_noise_m, 0.0, 1.0)
        check_range("lidar.resolution_m", self.resolution_m, 0.0, 0.1)
        check_range("lidar.detection_threshold", self.detection_threshold, 0.0, 255.0)
        check_range("lidar.ref_reflectivity", self.ref_reflectivity, 0.0, 1.0, low_open=True)
        check_range("lidar.ref_range_m", self.ref_range_m, 0.0, 1000.0, low_open=True)
        if self.intensity_mode not in INTENSITY_MODES:
            raise ConfigError("lidar.intensity_mode", self.intensity_mode, " or ".join(INTENSITY_MODES))
        check_range("lidar.latency_s", self.latency_s, 0.0, 1.0)
        check_range("lidar.cast_period_s", self.cast_period_s, 0.0, 1.0)
        check_range("lidar.cast_near_m", self.cast_near_m, 0.0, 1e4)
        check_range("lidar.dropout_prob", self.dropout_prob, 0.0, 1.0, high_open=True)
        check_range("lidar.point_dropout_prob", self.point_dropout_prob, 0.0, 1.0, high_open=True)
        for name in ("nan_point_prob", "duplicate_prob", "out_of_order_prob", "time_jump_prob"):
            check_range(f"lidar.{name}", getattr(self, name), 0.0, 1.0)
        check_range("lidar.time_jump_s", self.time_jump_s, -10.0, 10.0)
        for name in ("glass", "mirrors", "zoned_cast"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"lidar.{name}", getattr(self, name), "True or False")
        for name, high in (("max_interactions", 16), ("pose_blocks", 10**7), ("cast_threads", 64)):
            object.__setattr__(self, name, check_int(f"lidar.{name}", getattr(self, name), 0, high))
        mats = tuple(self.materials)
        for m in mats:
            if not isinstance(m, LidarMaterial) or m.kind not in KINDS:
                raise ConfigError("lidar.materials", m, f"LidarMaterial of kind {', '.join(KINDS)}")
            check_range(f"lidar.materials.{m.name}.reflectivity", m.reflectivity, 0.0, 1.0)
            check_range(f"lidar.materials.{m.name}.transmission", m.transmission, 0.0, 1.0)
            check_range(f"lidar.materials.{m.name}.specular", m.specular, 0.0, 1.0 - m.transmission)
        object.__setattr__(self, "materials", mats)
        if self.caster not in CASTERS:
            raise ConfigError("lidar.caster", self.caster, " or ".join(CASTERS))
        if self.return_mode not in RETURN_MODES:
            raise ConfigError("lidar.return_mode", self.return_mode, " or ".join(RETURN_MODES))
        check_range("lidar.glass_bow_mm_per_m", self.glass_bow_mm_per_m, 0.0, 20.0)
        check_range("lidar.glass_roller_wave_mm", self.glass_roller_wave_mm, 0.0, 5.0)
        check_range("lidar.glass_roller_wave_length_m", self.glass_roller_wave_length_m, 0.0, 10.0, low_open=True)
        object.__setattr__(self, "glass_shape_seed", check_int("lidar.glass_shape_seed", self.glass_shape_seed, 0, 2**31 - 1))

    @property
    def glass_shaped(self) -> bool:
        """Whether any pane is not flat (``glass_bow_mm_per_m`` or ``glass_roller_wave_mm`` above 0)."""
        return self.glass_bow_mm_per_m > 0.0 or self.glass_roller_wave_mm > 0.0

    @property
    def rate_hz(self) -> float:
        """Sweeps per second, Hz (the pattern's)."""
        return self.pattern.rate_hz

    def material_overrides(self) -> Mapping[str, LidarMaterial]:
        return {m.name: m for m in self.materials}

    def calibration_params(self) -> dict[str, object]:
        """What a pipeline may know about the sensor (for ``exo_calibration``)."""
        p = self.pattern
        return {
            "pattern": p.name, "vertical_angles_deg": list(p.vertical_angles_deg),
            "firing_order": list(p.firing_order), "azimuth_step_deg": p.azimuth_step_deg,
            "rate_hz": p.rate_hz, "firing_period_s": p.firing_period_s, "min_range_m": p.min_range_m,
            "max_range_m": p.max_range_m, "noise_sigma_m": self.range_noise_m,
            "resolution_m": self.resolution_m, "latency_s": self.latency_s,
            "intensity_mode": self.intensity_mode,
        }  # fmt: skip
