"""Micro-benchmarks behind `exobench bench`, one module per subject; they report figures
(medians and ratios measured in the same run), never pass or fail.

- :mod:`.stairs`: :func:`bench_rtls` (the recursive plane update against batch refits) and
  :func:`bench_sim` (the stairs simulator's real-time factor);
- :mod:`.lidar`: :func:`bench_lidar` (a VLP-16 sweep of the office against mujoco-lidar);
- :mod:`.locomotion`: :func:`bench_locomotion` (rendering, TSDF, pipeline latency at 640x480);
- :mod:`.sim`: :func:`~.sim.bench_sim_tracks` (per track, a paper episode's time per stage and
  pipeline, and its peak memory; part of `bench sim`) and :func:`~.sim.bench_episode_alone`
  (one paper case whole: its wall time and peak memory; `bench sim --track T --case NAME`);
- :mod:`.multisession`: :func:`~.multisession.bench_multisession` (LT-Exosense's peak memory
  merging two and ten sessions of one office, and the ratio; `bench multisession`).
"""

from .lidar import bench_lidar
from .locomotion import bench_locomotion
from .stairs import bench_rtls, bench_sim, case_a_episode

__all__ = ["bench_lidar", "bench_locomotion", "bench_rtls", "bench_sim", "case_a_episode"]
