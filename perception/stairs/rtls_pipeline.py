"""The paper's RTLS pipelines of the stairs track: ``rtls`` (general planes) and ``rtls-htvr``.

Frame handling is shared with the other stairs pipelines (:mod:`.pipeline_base`); the
per-point work is :class:`~exobench.perception.stairs.staircase.StaircaseAlgorithm`.
"""


from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

from exobench.core.errors import ConfigError
from exobench.core.estimates import PlaneEstimate, StaircaseEstimate

from .pipeline_base import StairsPipeline, check_common_config
from .readout import RISER_AT, riser_height_m, tread_depth_m
from .staircase import StaircaseAlgorithm, StaircaseParams


class RtlsStairs(StairsPipeline):
    """The paper's Algorithm 1 with general planes (Sec. V-A), point by point, online.

    ``process`` returns the current estimate (planes with at least 3 points and the read-out;
    no per-point assignments or timings, which ``finalize`` adds) once a surface has points.
    """

    name: ClassVar[str] = "rtls"
    htvr: ClassVar[bool] = False

    @dataclass(frozen=True)
    class Config:
        """Parameters (SI units).

        Attributes:
            leg: climbing leg whose calf sensors ``tof_<leg>_med``/``tof_<leg>_lat`` are used.
            stance_side: supporting foot; origin of the ``stance_ground`` frame.
            imu_sensor_id: trunk IMU giving ``R_world_imu``.
            th_z_m, th_pl_m: the paper's thresholds (8e-3 m; 0.13 m in the paper, 0.08 m here).
            queue_q, buffer_b, reliable_n: ``q``, ``b``, ``N`` of Algorithm 1; not given by the
                paper, defaults 5, 10, 5 (see :mod:`exobench.perception.stairs.staircase`).
            riser_flat_low: ``"assign"`` (listing of Algorithm 1) or ``"discard"`` (prose of
                Sec. IV-A) for a flat queue below ``S_{id-1}.e_z + th_pl`` on a riser.
            reliable_n_riser, tread_gate_m, sensor_ids, riser_exit, tread_travel: options of
                Algorithm 1 beyond the listing (see :mod:`exobench.perception.stairs.staircase`;
                ``tread_travel`` is off for ``rtls-htvr``, whose horizontal treads it only thins).
            riser_at: where the riser height is read between two treads (see
                :mod:`exobench.perception.stairs.readout`).

        ``th_pl_m`` is "the minimum height which is expected for a riser" (Sec. IV-A): the
        paper's 0.13 m fits its staircases (0.153-0.175 m) but never leaves a riser lower than
        that; the default 0.08 m sits below the building codes' lowest riser (0.10 m). The
        paper's Algorithm 1 and read-out as published: ``th_pl_m=0.13, reliable_n_riser=0,
        tread_gate_m=0, sensor_ids="shared", riser_exit="paper", tread_travel=False,
        riser_at="midpoint"``.
        """

        leg: str = "r"
        stance_side: str = "l"
        imu_sensor_id: str = "imu_trunk"
        th_z_m: float = 8e-3
        th_pl_m: float = 0.08
        queue_q: int = 5
        buffer_b: int = 10
        reliable_n: int = 5
        riser_flat_low: str = "assign"
        reliable_n_riser: int = 2
        tread_gate_m: float = 8e-3
        sensor_ids: str = "per_sensor"
        riser_exit: str = "travel"
        tread_travel: bool = True
        riser_at: str = "parallel"

        def __post_init__(self) -> None:
            check_common_config(self)
            self.params(False)  # validates the algorithm's parameters
            if self.riser_at not in RISER_AT:
                raise ConfigError("riser_at", self.riser_at, " or ".join(map(repr, RISER_AT)))

        def params(self, htvr: bool) -> StaircaseParams:
            return StaircaseParams(
                th_z_m=self.th_z_m,
                th_pl_m=self.th_pl_m,
                queue_q=self.queue_q,
                buffer_b=self.buffer_b,
                reliable_n=self.reliable_n,
                htvr=htvr,
                riser_flat_low=self.riser_flat_low,
                reliable_n_riser=self.reliable_n_riser,
                tread_gate_m=self.tread_gate_m,
                sensor_ids=self.sensor_ids,
                riser_exit=self.riser_exit,
                tread_travel=self.tread_travel,
            )

    def _reset_estimator(self) -> None:
        self.algorithm = StaircaseAlgorithm(self.config.params(self.htvr))
        self._assign = self.algorithm.assign
        self._cache: StaircaseEstimate | None = None
        self._stale = True
        # read-outs kept between online estimates: per surface (version, ok) -> PlaneEstimate,
        # and the riser/tread read-out of the reliable planes it was computed from
        self._plane_memo: dict[int, tuple[tuple[int, bool], PlaneEstimate]] = {}
        self._readout_memo: tuple[tuple[PlaneEstimate, ...], tuple[float, float]] | None = None

    def _consume(self, uid: int, p: tuple[float, float, float], flag: str) -> None:
        # the algorithm numbers its points in arrival order, like the pipeline's used readings
        self._assign(p, flag)
        self._stale = True

    def _planes(self) -> list[PlaneEstimate]:
        out = []
        memo = self._plane_memo
        for S in self.algorithm.surfaces:
            if S.plane.n >= 3:
                key = (S.plane.version, S.ok)
                hit = memo.get(S.index)
                if hit is None or hit[0] != key:
                    hit = memo[S.index] = (key, self._plane(S.index, S.plane, S.n_by_flag, S.ok, S.reliable_uid))
                out.append(hit[1])
        return out

    def _readout(self, planes: list[PlaneEstimate]) -> tuple[float, float]:
        reliable = tuple(p for p in planes if p.reliable)
        memo = self._readout_memo
        if memo is None or len(memo[0]) != len(reliable) or any(a is not b for a, b in zip(memo[0], reliable, strict=True)):
            memo = self._readout_memo = (reliable, (riser_height_m(reliable, self.config.riser_at), tread_depth_m(reliable)))
        return memo[1]

    def _extra(self) -> dict[str, Any]:
        return {**self.algorithm.counts, "current_id": self.algorithm.current_id}

    def _online(self) -> StaircaseEstimate | None:
        if self._stale:
            self._stale = False
            planes = self._planes()
            self._cache = self._estimate(planes, None, self._extra(), self._readout(planes)) if planes else None
        return self._cache

    def _finalize(self) -> StaircaseEstimate:
        planes = self._planes()
        return self._estimate(planes, self.algorithm.point_surfaces(), self._extra(), self._readout(planes))


class RtlsHtvrStairs(RtlsStairs):
    """Algorithm 1 with horizontal treads and vertical risers (HTVR, Sec. V-B)."""

    name: ClassVar[str] = "rtls-htvr"
    htvr: ClassVar[bool] = True

    @dataclass(frozen=True)
    class Config(RtlsStairs.Config):
        """As :class:`RtlsStairs.Config`, with ``tread_travel`` off."""

        tread_travel: bool = False

