"""exobench.benchmarks: tracks, runner, result store, reports, the `exobench` command, rerun bridge.

Modules (nothing is imported here, so `exobench --help` stays fast):

- ``registry``: pipeline names -> classes (built-ins and the ``exobench.pipelines`` entry points).
- ``tracks``: one module per perception problem (``tracks.stairs``: suites, scorer, published
  figures), behind the protocol of ``tracks.base``.
- ``runner``: validate a run (``plan_run``), then run it (``execute``) with per-episode atomic
  results, a process pool and resume. ``results``: the run folder's files.
- ``report`` and ``plots``: the summary table and ``report.md`` with PNG figures.
- ``bench``: `exobench bench rtls|sim`. ``rerun_bridge``: ``.rrd`` recordings. ``cli``: the command.
"""
