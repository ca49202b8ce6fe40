"""exobench.benchmarks: tracks, runner, result store, reports, the `exobench` command.

Modules (nothing is imported here, so `exobench --help` stays fast):

- ``entry_points``: the string-entry-point registry that both registries below are built on.
- ``registry``: pipeline names -> classes (built-ins and the ``exobench.pipelines`` entry points).
- ``tracks``: one folder per perception problem (``tracks/stairs/``: spec, metrics, report,
  recording), behind the protocol of ``tracks.spec``, found through ``tracks.registry``
  (built-ins and the ``exobench.tracks`` entry points).
- ``runner``: validate a run (``plan_run``), then run it (``execute``) with per-episode atomic
  results, a process pool and resume. ``overrides``: ``--set`` parsing and routing.
  ``results``: the run folder's files.
- ``report``: the summary table and ``report.md`` (each track adds its sections and figures);
  ``plots``: matplotlib on the Agg backend. ``trajectory``: trajectory metrics as evo computes them.
- ``bench``: `exobench bench rtls|sim|lidar|locomotion`. ``cli``: the command.
"""
