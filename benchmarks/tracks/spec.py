"""What a track is: the :class:`Track` protocol and the records it hands the harness.

A track is one perception problem of the source papers (the README's table of tracks; one page
each in ``docs/tracks/``) and lives in its own folder, ``benchmarks/tracks/<name>/``:
``track.py`` (the class below: scenario type and how to simulate it, the streams its pipelines
receive, the estimate type they return, its scoring settings, the scorer, the published
references, summary rows, timing metrics, suites and cases), ``metrics.py`` (pure scoring
functions), ``report.py`` (its report sections and figures) and, where it has one,
``recording.py`` (its rerun recording).
The runner, the report writer and the command line know only this protocol; tracks are found
through :mod:`exobench.benchmarks.tracks.registry`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Protocol, runtime_checkable

from exobench.core.episode import Episode


@dataclass(frozen=True)
class ParamInfo:
    """One scenario parameter as `exobench list` shows it (SI units)."""

    name: str
    default: Any
    low: Any
    high: Any
    unit: str
    doc: str
    low_open: bool = False
    choices: tuple = ()
    """The allowed values of a parameter that takes one of a list (empty: a range or free)."""

    def range_text(self) -> str:
        """E.g. ``(0, 0.3]`` or ``[0.15, 0.6]``, the choices as ``plain|windows|curtain`` (booleans
        ``false|true``, as ``--set`` takes them); empty when the parameter takes any string."""
        if self.choices:
            return "|".join(str(c).lower() if isinstance(c, bool) else str(c) for c in self.choices)
        if self.low is None and self.high is None:
            return ""
        return f"{'(' if self.low_open else '['}{self.low:g}, {self.high:g}]"


def param_infos(table: Mapping[str, Any]) -> list[ParamInfo]:
    """Rows of a scenario parameter table (name -> a row with ``default``, ``low``, ``high``,
    ``unit``, ``doc`` and optionally ``low_open`` and ``choices``, such as ``ParamSpec``) as
    :class:`ParamInfo`, in the table's order; :class:`ParamInfo` rows are kept as they are."""
    out = []
    for name, row in table.items():
        if isinstance(row, ParamInfo):
            out.append(row)
        else:
            low_open = bool(getattr(row, "low_open", False))
            choices = tuple(getattr(row, "choices", ()))
            out.append(ParamInfo(name, row.default, row.low, row.high, row.unit, row.doc, low_open, choices))
    return out


def scoring_of(track: Any, scenario: Mapping[str, Any]) -> dict[str, Any]:
    """The scoring settings of a validated scenario: its values of ``track.scoring_keys``."""
    return {k: scenario[k] for k in sorted(track.scoring_keys) if k in scenario}


@dataclass(frozen=True)
class Case:
    """One scenario of a suite, before a run seed is applied.

    Attributes:
        name: unique within the suite, e.g. ``"A"`` or ``"0.153-0.294/pose07"``.
        group: rows of the summary pool the cases of one group, e.g. ``"A"``, ``"0.153/0.294"``.
        scenario: scenario parameters that differ from the defaults.
        figure: whether the runner keeps the points of this case for the report's side view.
    """

    name: str
    group: str
    scenario: dict[str, Any]
    figure: bool = False


@dataclass(frozen=True)
class EpisodePlan:
    """One episode to run: a case with its run seed and the derived simulation seed."""

    key: str
    suite: str
    case: Case
    scenario: dict[str, Any]
    run_seed: int
    seed: int


@dataclass(frozen=True)
class Reference:
    """A published figure to print beside ours.

    Attributes:
        metric: metric key it compares with (e.g. ``"riser_error_pct"``).
        text: how the paper states it, e.g. ``"2.61 ± 1.83"`` or ``"< 3"``.
        source: where, e.g. ``"Tab. III"``.
        groups: the summary groups it applies to (empty: all).
        pipelines: the pipelines it applies to (empty: all).
        value: a number to compare against, when the paper gives one.
        bound: ``"<"`` when the figure is an upper bound on the absolute value.
    """

    metric: str
    text: str
    source: str
    groups: tuple[str, ...] = ()
    pipelines: tuple[str, ...] = ()
    value: float | None = None
    bound: str | None = None

    def applies(self, group: str, pipeline: str) -> bool:
        return (not self.groups or group in self.groups) and (not self.pipelines or pipeline in self.pipelines)


@dataclass(frozen=True)
class SummaryRow:
    """A metric row of the summary table.

    ``scale`` converts the stored SI value to the shown unit; ``absolute`` shows |x|.
    ``better`` marks the row of a headline metric (one of ``track.headline_metrics``):
    ``"higher"`` or ``"lower"``, said of the value shown (|x| for an ``absolute`` row); empty
    for every other row. ``exobench compare`` and ``exobench leaderboard`` rank and gate on
    these rows (:func:`headline_rows`).
    """

    metric: str
    label: str
    scale: float = 1.0
    absolute: bool = False
    digits: int = 2
    terminal: bool = True
    better: str = ""

    def __post_init__(self) -> None:
        if self.better not in BETTER:
            raise ValueError(f"SummaryRow {self.metric!r}: better={self.better!r}, allowed: {', '.join(map(repr, BETTER))}")

    def shown(self, value: float) -> float:
        """A stored value in the row's unit and sign (what the table shows)."""
        return abs(value * self.scale) if self.absolute else value * self.scale


BETTER = ("", "higher", "lower")


def headline_rows(track: Any) -> list[SummaryRow]:
    """The summary rows marked ``better`` of the track's ``headline_metrics``, in that order;
    a headline metric without such a row is left out (the conformance tests require one)."""
    marked = {r.metric: r for r in track.summary_rows() if r.better}
    return [marked[m] for m in getattr(track, "headline_metrics", ()) if m in marked]


@runtime_checkable
class Track(Protocol):
    """Protocol of a track (see the module docstring).

    Optional member (not required of a track class, so tracks written before it still load):
    ``headline_metrics: ClassVar[tuple[str, ...]]``, the metric keys that say how good an
    estimate is, each with one summary row that says whether higher or lower is better
    (:attr:`SummaryRow.better`). A record with none of them finite scored nothing, and the
    runner fails it with that reason (:func:`exobench.benchmarks.runner.unscored_reason`), so
    an estimate that could not be scored is never counted as a result.
    """

    name: ClassVar[str]
    suites: ClassVar[tuple[str, ...]]
    default_suite: ClassVar[str]
    streams: ClassVar[tuple[str, ...]]
    """Frame kinds its episodes carry (keys of ``exobench.core.kinds.FRAME_TYPES``)."""
    estimate_type: ClassVar[type]
    """The estimate class its pipelines return from ``finalize()`` (from ``exobench.core.estimates``).
    The runner checks it once, before scoring: any other value (None included) is recorded as
    failed with the type in its reason, and :meth:`score` only ever sees an instance."""
    scoring_keys: ClassVar[frozenset[str]]
    """Scenario keys that set how an estimate is scored, not what is simulated (loop-closure's
    ``revisit_m``): listed and validated with the scenario, stored with the plan and every record
    (``scenario``), handed by the runner to :meth:`score`, :meth:`figure_data` and
    :meth:`write_recording` as ``scoring`` and never put into the simulated episode. Empty
    when the track has none."""
    smoke_scenario: ClassVar[Mapping[str, Any]]
    """Scenario values (over the defaults) of a tiny episode that simulates in a few seconds: the
    episode every registered pipeline of the track is checked on (``tests/test_conformance.py``)."""
    timing_metrics: ClassVar[frozenset[str]]
    """Metric keys that are wall-clock timings: the only ones allowed to differ between two runs
    of the same plan."""

    def params(self) -> list[ParamInfo]:
        """The scenario parameters with default, range, unit and doc."""

    def validate_scenario(self, values: Mapping[str, Any]) -> dict[str, Any]:
        """Validated, typed scenario values (raises ConfigError / UnknownNameError)."""

    def cases(self, suite: str, run_seed: int = 0) -> list[Case]:
        """The cases of a suite, deterministic. A suite drawn at random (so that nobody tunes
        on a fixed list, such as the stairs track's ``general``) draws from ``run_seed``; the
        other suites ignore it."""

    def group_label(self, case: Case, scenario: Mapping[str, Any]) -> str:
        """The summary group of a case's records given the scenario that was run (the case's
        values with the ``--set`` overrides): ``case.group`` unless the overrides change what
        the group names (e.g. the staircase), so no published figure of another setting is
        printed beside them."""

    def simulate(self, scenario: dict[str, Any], seed: int) -> Episode:
        """Simulate one episode. A track may also have ``stream(scenario, seed)``, returning an
        :class:`~exobench.core.episode.EpisodeStream` of the same frames and an episode that
        :meth:`score` and :meth:`figure_data` score alike: the runner then hands the frames to
        its pipelines as they are produced, so a long walk is never held whole."""

    def score(self, episode: Episode, estimate: Any, scoring: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """Metrics of one estimate (an instance of :attr:`estimate_type`) against the episode's
        truth, under the scoring settings ``scoring`` (values of :attr:`scoring_keys`; a key not
        given, or None, takes its default). Never raises on a malformed estimate."""

    def failed_metrics(self, episode: Episode | None, reason: str) -> dict[str, Any]:
        """Metrics of a pipeline that raised (or of every pipeline when the simulation raised,
        ``episode`` None): the failure is scored, the run goes on."""

    def references(self) -> list[Reference]:
        """Published figures."""

    def summary_rows(self) -> list[SummaryRow]:
        """Metric rows of the summary table."""

    def figure_data(self, episode: Episode, estimates: dict[str, Any],
                    scoring: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """Arrays the report's per-case figure needs (saved as .npz); ``scoring`` as for :meth:`score`."""

    report_intro: ClassVar[str]
    """One line under the report's title: where the published figures come from."""

    def report_sections(self, records: list[dict[str, Any]], pipelines: list[str], out_dir: Path) -> list[str]:
        """The track's report sections after the summary table: markdown lines; figures are
        written into ``out_dir`` (figure data saved by the runner is in ``out_dir/figures``)."""

    def write_recording(self, episode: Episode, estimates_by_pipeline: dict[str, Any], path: Path,
                        scoring: Mapping[str, Any] | None = None) -> Path:
        """Write a rerun recording (``.rrd``) of the episode and the estimates (a final estimate,
        or a time series ``[(stamp_s, estimate), ...]`` per pipeline); returns the path.
        ``scoring`` as for :meth:`score`."""

