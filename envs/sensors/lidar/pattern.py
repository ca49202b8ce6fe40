"""LiDAR scan patterns: which rays a sensor fires in one sweep, in which direction and when.

A :class:`LidarPattern` is a validated, frozen description (channels, firing order and timing,
azimuth step, sweep rate, range limits); :meth:`LidarPattern.rays` expands it into a
:class:`RayTable` of unit directions in the sensor frame (x forward, y left, z up), each with its
channel (the ``ring`` of a scan) and its firing time relative to the start of the sweep.

Two kinds of pattern:

* ``"spinning"`` (Velodyne, Ouster, custom grids): firing blocks at ``k * firing_period_s``, block
  k at azimuth ``start_azimuth_deg -/+ k * azimuth_step_deg`` (clockwise seen from above, as the
  Velodyne and Ouster heads turn). Within a block the channels fire in ``firing_order``,
  ``lasers_per_slot`` at a time, one slot every ``slot_period_s``; the head keeps turning during a
  block, so each laser's azimuth is interpolated from its own firing time, as the Velodyne driver
  does. The sweep starts and ends behind the sensor (-x) [A], so the seam with the motion jump
  lies away from the walking direction.
* ``"rosette"`` (Livox-like, non-repetitive): two counter-rotating prisms at the frequencies
  ``rosette_hz`` deflect the beams by ``fov_deg / 4 * (e^{i w1 t} + e^{i w2 t})`` around +x; the
  phase follows the absolute time, so successive sweeps cover different rays while the pattern
  stays deterministic. ``vertical_angles_deg`` are the lasers' elevation offsets.

Sources (``docs/sensor-reference.md``): VLP-16 manual (16 lasers at -15..+15 deg in 2 deg steps, laser id
0:-15, 1:+1, 2:-13, 3:+3 ...; all 16 every 55.296 us, one every 2.304 us; 0.2 deg at 10 Hz; range
100 m, practical minimum 0.9 m). VLP-32C: laser table of the Velodyne calibration file (elevation
and azimuth offset per laser id), lasers firing in pairs [A: same 55.296 / 2.304 us timing].
Ouster OS1: uniform beams over 42.4 deg [A: OS1 Gen2 uniform], whole columns fire at once.
Livox Mid-40: one laser, 100 k points/s, 38.4 deg circular field of view; prism frequencies [A].
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from exobench.core import ConfigError, check_int, check_range

SCAN_KINDS = ("spinning", "rosette")

VLP16_FIRING_PERIOD_S = 55.296e-6
VLP16_SLOT_PERIOD_S = 2.304e-6

# VLP-32C (elevation deg, azimuth offset deg) by laser id, i.e. in firing order
_VLP32C_BY_LASER_ID = (
    (-25.0, 1.4), (-1.0, -4.2), (-1.667, 1.4), (-15.639, -1.4), (-11.31, 1.4), (0.0, -1.4),
    (-0.667, 4.2), (-8.843, -1.4), (-7.254, 1.4), (0.333, -4.2), (-0.333, 1.4), (-6.148, -1.4),
    (-5.333, 4.2), (1.333, -1.4), (0.667, 4.2), (-4.0, -1.4), (-4.667, 1.4), (1.667, -4.2),
    (1.0, 1.4), (-3.667, -4.2), (-3.333, 4.2), (3.333, -1.4), (2.333, 1.4), (-2.667, -1.4),
    (-3.0, 1.4), (7.0, -1.4), (4.667, 1.4), (-2.333, -4.2), (-2.0, 4.2), (15.0, -1.4),
    (10.333, 1.4), (-1.333, -1.4),
)  # fmt: skip


@dataclass(frozen=True, eq=False)
class RayTable:
    """All rays of one sweep, in firing-time order.

    Attributes:
        dirs_s: unit directions in the sensor frame, (N, 3).
        channel: channel index (into ``vertical_angles_deg``) of each ray, (N,).
        time_offset_s: firing time relative to the sweep start, s, (N,).
        firing: firing-block index of each ray, (N,); the rays of a block are contiguous.
        firing_time_s: start time of each firing block relative to the sweep start, s, (F,).
    """

    dirs_s: np.ndarray
    channel: np.ndarray
    time_offset_s: np.ndarray
    firing: np.ndarray
    firing_time_s: np.ndarray

    def __len__(self) -> int:
        return len(self.channel)


def _unit_dirs(azimuth_rad: np.ndarray, elevation_rad: np.ndarray) -> np.ndarray:
    ce = np.cos(elevation_rad)
    return np.column_stack([ce * np.cos(azimuth_rad), ce * np.sin(azimuth_rad), np.sin(elevation_rad)])


@dataclass(frozen=True)
class LidarPattern:
    """Channels, firing order and timing of a LiDAR; validated on construction.

    Attributes:
        name: label, e.g. ``"vlp16"``.
        vertical_angles_deg: elevation of each channel, deg (+ up), in [-90, 90]; the index is
            the channel (``ring``). The built-in Velodyne patterns list them from the lowest up.
        firing_order: the channels in the order they fire within one firing block (a
            permutation of ``range(len(vertical_angles_deg))``).
        azimuth_step_deg: azimuth advance between firing blocks, deg (spinning; 0 for rosette).
        rate_hz: sweeps per second.
        firing_period_s: time between firing blocks, s.
        slot_period_s: time between consecutive firing slots within a block, s (0: all at once).
        lasers_per_slot: lasers fired together in one slot.
        min_range_m / max_range_m: returns outside are dropped, m.
        fov_deg: horizontal field of view of a spinning pattern (360 = full turn), deg; full cone
            angle of a rosette, deg.
        start_azimuth_deg: azimuth of the first firing block, deg (0 = +x, counter-clockwise
            positive).
        clockwise: spin direction seen from above (Velodyne and Ouster turn clockwise).
        azimuth_offsets_deg: per-channel azimuth offset, deg (VLP-32C); empty = none.
        scan_kind: ``"spinning"`` or ``"rosette"``.
        rosette_hz: the two prism frequencies of a rosette, Hz (opposite signs).
    """

    name: str
    vertical_angles_deg: tuple[float, ...]
    firing_order: tuple[int, ...]
    azimuth_step_deg: float
    rate_hz: float
    firing_period_s: float
    slot_period_s: float = 0.0
    lasers_per_slot: int = 1
    min_range_m: float = 0.9
    max_range_m: float = 100.0
    fov_deg: float = 360.0
    start_azimuth_deg: float = 180.0
    clockwise: bool = True
    azimuth_offsets_deg: tuple[float, ...] = ()
    scan_kind: str = "spinning"
    rosette_hz: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        f = "lidar.pattern."
        if self.scan_kind not in SCAN_KINDS:
            raise ConfigError(f + "scan_kind", self.scan_kind, " or ".join(SCAN_KINDS))
        angles = _float_tuple(f + "vertical_angles_deg", self.vertical_angles_deg)
        if not angles:
            raise ConfigError(f + "vertical_angles_deg", self.vertical_angles_deg, "at least one channel")
        for a in angles:
            check_range(f + "vertical_angles_deg", a, -90.0, 90.0)
        object.__setattr__(self, "vertical_angles_deg", angles)
        n = len(angles)
        order = tuple(self.firing_order)
        if sorted(order) != list(range(n)) or any(not isinstance(i, (int, np.integer)) for i in order):
            raise ConfigError(f + "firing_order", self.firing_order, f"a permutation of 0..{n - 1}")
        object.__setattr__(self, "firing_order", tuple(int(i) for i in order))
        offsets = _float_tuple(f + "azimuth_offsets_deg", self.azimuth_offsets_deg)
        if offsets and len(offsets) != n:
            raise ConfigError(f + "azimuth_offsets_deg", self.azimuth_offsets_deg, f"empty or {n} values")
        for a in offsets:
            check_range(f + "azimuth_offsets_deg", a, -180.0, 180.0)
        object.__setattr__(self, "azimuth_offsets_deg", offsets)
        check_range(f + "rate_hz", self.rate_hz, 0.0, 1000.0, low_open=True)
        check_range(f + "firing_period_s", self.firing_period_s, 0.0, 1.0 / self.rate_hz, low_open=True)
        check_range(f + "slot_period_s", self.slot_period_s, 0.0, 1.0)
        object.__setattr__(self, "lasers_per_slot", check_int(f + "lasers_per_slot", self.lasers_per_slot, 1, n))
        if self.n_slots * self.slot_period_s > self.firing_period_s * (1.0 + 1e-9):
            raise ConfigError(
                f + "slot_period_s", self.slot_period_s, f"n_slots ({self.n_slots}) * slot_period_s <= firing_period_s"
            )
        check_range(f + "min_range_m", self.min_range_m, 0.0, 100.0)
        check_range(f + "max_range_m", self.max_range_m, self.min_range_m, 2000.0, low_open=True)
        check_range(f + "start_azimuth_deg", self.start_azimuth_deg, -360.0, 360.0)
        if self.scan_kind == "spinning":
            check_range(f + "fov_deg", self.fov_deg, 0.0, 360.0, low_open=True)
            check_range(f + "azimuth_step_deg", self.azimuth_step_deg, 0.0, self.fov_deg, low_open=True)
            if self.n_firings * self.firing_period_s > (1.0 + 1e-9) / self.rate_hz:
                raise ConfigError(
                    f + "firing_period_s",
                    self.firing_period_s,
                    f"n_firings ({self.n_firings}) * firing_period_s <= 1 / rate_hz (one sweep)",
                )
        else:
            check_range(f + "fov_deg", self.fov_deg, 0.0, 180.0, low_open=True, high_open=True)
            hz = _float_tuple(f + "rosette_hz", self.rosette_hz)
            if len(hz) != 2 or hz[0] == 0.0 or hz[1] == 0.0 or abs(hz[0]) > 1e5 or abs(hz[1]) > 1e5:
                raise ConfigError(f + "rosette_hz", self.rosette_hz, "two non-zero frequencies, |f| <= 1e5 Hz")
            object.__setattr__(self, "rosette_hz", hz)

    # ----------------------------------------------------------------- derived sizes

    @property
    def n_channels(self) -> int:
        return len(self.vertical_angles_deg)

    @property
    def n_slots(self) -> int:
        return -(-self.n_channels // self.lasers_per_slot)

    @property
    def n_firings(self) -> int:
        """Firing blocks per sweep."""
        if self.scan_kind == "rosette":
            return max(1, int(math.floor(1.0 / (self.rate_hz * self.firing_period_s) + 1e-9)))
        k = int(math.floor(self.fov_deg / self.azimuth_step_deg + 1e-6))
        return k if self.fov_deg >= 360.0 - 1e-9 else k + 1

    @property
    def sweep_period_s(self) -> float:
        return 1.0 / self.rate_hz

    # ----------------------------------------------------------------- rays

    def channel_slot_time_s(self) -> np.ndarray:
        """Firing time of each channel within its block, s, (C,)."""
        t = np.zeros(self.n_channels)
        for pos, ch in enumerate(self.firing_order):
            t[ch] = (pos // self.lasers_per_slot) * self.slot_period_s
        return t

    def rays(self, sweep_start_s: float = 0.0) -> RayTable:
        """Every ray of the sweep starting at ``sweep_start_s`` (only a rosette depends on it)."""
        order = np.asarray(self.firing_order)
        F, C = self.n_firings, self.n_channels
        firing_t = np.arange(F) * self.firing_period_s
        slot_t = self.channel_slot_time_s()[order]  # (C,) in firing order
        elev = np.radians(np.asarray(self.vertical_angles_deg))[order]
        t = (firing_t[:, None] + slot_t[None, :]).ravel()
        channel = np.tile(order, F)
        firing = np.repeat(np.arange(F), C)
        if self.scan_kind == "spinning":
            sign = -1.0 if self.clockwise else 1.0
            # the head turns azimuth_step_deg per firing period, also during a block
            steps = np.arange(F)[:, None] + slot_t[None, :] / self.firing_period_s
            az = self.start_azimuth_deg + sign * self.azimuth_step_deg * steps
            if self.azimuth_offsets_deg:
                az = az + np.asarray(self.azimuth_offsets_deg)[order][None, :]
            dirs = _unit_dirs(np.radians(az).ravel(), np.tile(elev, F))
        else:
            tau = float(sweep_start_s) + t
            w1, w2 = (2.0 * np.pi * f for f in self.rosette_hz)
            half = 0.25 * np.radians(self.fov_deg)
            ay = half * (np.cos(w1 * tau) + np.cos(w2 * tau))
            az = half * (np.sin(w1 * tau) + np.sin(w2 * tau)) + np.tile(elev, F)
            ang = np.hypot(ay, az)
            s = np.where(ang > 0.0, np.sin(ang) / np.where(ang > 0.0, ang, 1.0), 1.0)
            dirs = np.column_stack([np.cos(ang), s * ay, s * az])
        return RayTable(dirs, channel.astype(np.int64), t, firing, firing_t)

    # ----------------------------------------------------------------- constructors

    @classmethod
    def vlp16(cls, rate_hz: float = 10.0) -> LidarPattern:
        """Velodyne VLP-16 (Puck): 0.02 * rate_hz deg azimuth steps (0.2 deg at 10 Hz, 5-20 Hz)."""
        check_range("lidar.pattern.rate_hz", rate_hz, 5.0, 20.0)
        angles = tuple(float(a) for a in range(-15, 16, 2))  # ring 0 = lowest
        # laser id j fires j-th: even ids -15, -13, ..., -1 (rings 0..7), odd ids +1..+15 (rings 8..15)
        order = tuple(j // 2 if j % 2 == 0 else 8 + j // 2 for j in range(16))
        return cls(
            "vlp16", angles, order, azimuth_step_deg=0.02 * float(rate_hz), rate_hz=float(rate_hz),
            firing_period_s=VLP16_FIRING_PERIOD_S, slot_period_s=VLP16_SLOT_PERIOD_S, lasers_per_slot=1,
            min_range_m=0.9, max_range_m=100.0,
        )  # fmt: skip

    @classmethod
    def vlp32(cls, rate_hz: float = 10.0) -> LidarPattern:
        """Velodyne VLP-32C: 32 lasers -25..+15 deg, fired in pairs; range 200 m."""
        check_range("lidar.pattern.rate_hz", rate_hz, 5.0, 20.0)
        by_id = _VLP32C_BY_LASER_ID
        rank = sorted(range(32), key=lambda j: by_id[j][0])  # channel c = rank by elevation
        channel_of_id = {j: c for c, j in enumerate(rank)}
        return cls(
            "vlp32", tuple(by_id[j][0] for j in rank), tuple(channel_of_id[j] for j in range(32)),
            azimuth_step_deg=0.02 * float(rate_hz), rate_hz=float(rate_hz),
            firing_period_s=VLP16_FIRING_PERIOD_S, slot_period_s=VLP16_SLOT_PERIOD_S, lasers_per_slot=2,
            min_range_m=1.0, max_range_m=200.0, azimuth_offsets_deg=tuple(by_id[j][1] for j in rank),
        )  # fmt: skip

    @classmethod
    def ouster(
        cls, channels: int = 64, columns: int = 1024, rate_hz: float = 10.0, vfov_deg: float = 42.4
    ) -> LidarPattern:
        """Ouster OS1-like: ``channels`` beams uniform over ``vfov_deg``; whole columns fire at once."""
        if channels not in (16, 32, 64, 128):
            raise ConfigError("lidar.pattern.channels", channels, "16, 32, 64 or 128")
        if columns not in (512, 1024, 2048):
            raise ConfigError("lidar.pattern.columns", columns, "512, 1024 or 2048")
        check_range("lidar.pattern.rate_hz", rate_hz, 0.0, 20.0, low_open=True)
        check_range("lidar.pattern.vfov_deg", vfov_deg, 0.0, 180.0, low_open=True)
        angles = tuple(np.linspace(-0.5 * vfov_deg, 0.5 * vfov_deg, channels).tolist())
        return cls(
            f"ouster{channels}", angles, tuple(range(channels)), azimuth_step_deg=360.0 / columns,
            rate_hz=float(rate_hz), firing_period_s=1.0 / (rate_hz * columns), slot_period_s=0.0,
            lasers_per_slot=channels, min_range_m=0.5, max_range_m=120.0,
        )  # fmt: skip

    @classmethod
    def livox_like(
        cls,
        fov_deg: float = 38.4,
        points_per_s: float = 100_000.0,
        rate_hz: float = 10.0,
        rosette_hz: tuple[float, float] = (121.3, -74.97),
        lasers: int = 1,
    ) -> LidarPattern:
        """Livox-Mid-40-like forward rosette (non-repetitive, deterministic); ``lasers`` beams
        offset in elevation by 0.5 deg each [A], like the multi-line Avia."""
        check_range("lidar.pattern.points_per_s", points_per_s, 1.0, 1e7)
        lasers = check_int("lidar.pattern.lasers", lasers, 1, 16)
        angles = tuple(0.5 * (np.arange(lasers) - 0.5 * (lasers - 1)))
        return cls(
            "livox", tuple(float(a) for a in angles), tuple(range(int(lasers))), azimuth_step_deg=0.0,
            rate_hz=rate_hz, firing_period_s=1.0 / points_per_s, slot_period_s=0.0,
            lasers_per_slot=int(lasers), min_range_m=1.0, max_range_m=260.0, fov_deg=fov_deg,
            start_azimuth_deg=0.0, scan_kind="rosette", rosette_hz=rosette_hz,
        )  # fmt: skip

    @classmethod
    def grid(
        cls,
        vertical_angles_deg: Sequence[float],
        azimuth_step_deg: float,
        *,
        rate_hz: float = 10.0,
        fov_deg: float = 360.0,
        min_range_m: float = 0.1,
        max_range_m: float = 100.0,
        firing_period_s: float | None = None,
        name: str = "grid",
    ) -> LidarPattern:
        """A custom raster: all channels fire together per column, columns ``azimuth_step_deg``
        apart over ``fov_deg`` centred on +x (or a full turn starting behind), spread evenly over
        the sweep unless ``firing_period_s`` is given."""
        check_range("lidar.pattern.fov_deg", fov_deg, 0.0, 360.0, low_open=True)
        check_range("lidar.pattern.azimuth_step_deg", azimuth_step_deg, 0.0, fov_deg, low_open=True)
        check_range("lidar.pattern.rate_hz", rate_hz, 0.0, 1000.0, low_open=True)
        angles = tuple(vertical_angles_deg)
        full = fov_deg >= 360.0 - 1e-9
        n_cols = int(math.floor(fov_deg / azimuth_step_deg + 1e-6)) + (0 if full else 1)
        period = firing_period_s if firing_period_s is not None else 1.0 / (rate_hz * n_cols)
        return cls(
            name, angles, tuple(range(len(angles))), azimuth_step_deg=azimuth_step_deg, rate_hz=rate_hz,
            firing_period_s=period, slot_period_s=0.0, lasers_per_slot=max(1, len(angles)),
            min_range_m=min_range_m, max_range_m=max_range_m, fov_deg=fov_deg,
            start_azimuth_deg=180.0 if full else 0.5 * fov_deg,
        )  # fmt: skip


def _float_tuple(field: str, values: object) -> tuple[float, ...]:
    try:
        out = tuple(float(v) for v in values)  # type: ignore[attr-defined]
    except (TypeError, ValueError):
        raise ConfigError(field, values, "a sequence of numbers") from None
    if any(not math.isfinite(v) for v in out):
        raise ConfigError(field, values, "finite numbers")
    return out
