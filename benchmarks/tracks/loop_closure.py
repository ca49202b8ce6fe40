"""The loop-closure track: place recognition with SC++ and Gaussian Scan Context (seeds/003 4.2.3, 5.2.3).

A walker with a trunk LiDAR (VLP-16) and IMU walks the office ``"loop"`` route
(:mod:`exobench.envs.office_sim`: round the corridor ring and back to the start, then a second
lap through the meeting room) in offices with glass partitions (panes reflect, ghosts appear
behind them) and polished floors. Every keyframe of a pipeline is matched against the earlier
ones; the match is scored against the true LiDAR poses (``EpisodeTruth.trajectory_w``) as the
thesis does (:mod:`loop_closure_metrics`): a true loop exists when an earlier keyframe, at least
``exclude_recent_s`` older, lies within ``revisit_m`` = 5 m; a detection at threshold ``tau`` is a
true positive when its match is within 5 m. Metrics: the exact precision-recall curve over
``tau`` (stored with the record), its area (``pr_auc``), the maximum recall at 100 % precision
(Table 5.5's figure), best F1, time per keyframe, keyframes, revisits, invalid keyframes and the
relative-yaw error of the correct matches.

Scenario: the office walk's parameters plus the office's size and glazing (the office
parameters :class:`~exobench.models.office.OfficeParams` that ``OfficeScenario`` does not
expose) and the LiDAR's azimuth step; ``revisit_m`` and ``exclude_recent_s`` only score.

Suites (the run seed drives the sensor noise; the office layout is ``office_seed``):

- ``quick``: one short loop in a small glassy office (8 m corridors, one office, 60 % glass,
  polished floors), walked briskly (0.45 m steps, 0.5 s swings), cut 3 m after closing the ring;
  the LiDAR fires every 0.6 deg instead of 0.2 deg (a third of the rays, for speed).
- ``paper``: the whole loop route (two laps) in the default office (24 m corridors, 3 offices),
  as built (40 % glass, 30 % polished) and fully glazed and polished ("reflective").
- ``full``: the paper cases, two more office layouts, an office without glass, and a VLP-32.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from exobench.core.episode import Episode
from exobench.core.errors import UnknownNameError
from exobench.core.estimates import PlaceRecognitionEstimate
from exobench.models.world_params import ParamSpec

from .base import Case, ParamInfo, Reference, SummaryRow
from .loop_closure_metrics import (
    best_f1,
    keyframe_poses,
    max_recall_at_full_precision,
    pr_auc,
    pr_curve,
    yaw_errors,
)
from .office_common import office_params, validate_office_scenario

PIPELINES = ("sc++", "gsc-height", "gsc-huber", "gsc-intensity")
OFFICE_KEYS = ("corridor_length_m", "room_depth_m", "meeting_room_m", "glass_fraction", "polished_fraction")
SCORING_KEYS = ("revisit_m", "exclude_recent_s")
EXTRA: dict[str, ParamSpec] = {
    "corridor_length_m": ParamSpec(24.0, 8.0, 80.0, "m", "inside length of the building (office.corridor_length_m)"),
    "room_depth_m": ParamSpec(4.0, 1.5, 10.0, "m", "depth of the offices and meeting room; the two corridors are this + 2 m apart"),
    "meeting_room_m": ParamSpec(6.0, 1.5, 30.0, "m", "length of the meeting room (office.meeting_room_m)"),
    "glass_fraction": ParamSpec(0.4, 0.0, 1.0, "", "share of corridor partitions that are glass"),
    "polished_fraction": ParamSpec(0.3, 0.0, 1.0, "", "share of floor areas that are polished (reflective)"),
    "lidar_azimuth_step_deg": ParamSpec(0.0, 0.0, 2.0, "deg", "azimuth step of the spinning LiDAR (0 = the pattern's own; coarser = fewer rays, faster)"),
    "revisit_m": ParamSpec(5.0, 0.5, 50.0, "m", "a revisit: an earlier keyframe within this distance (scoring)", low_open=True),
    "exclude_recent_s": ParamSpec(20.0, 0.0, 600.0, "s", "keyframes younger than this are no revisit (scoring; the thesis' xi)"),
}
BRISK = {"step_length_m": 0.45, "swing_s": 0.5}
QUICK = {
    "route": "loop", "max_distance_m": 33.0, "n_offices": 1, "corridor_length_m": 8.0, "meeting_room_m": 2.5,
    "glass_fraction": 0.6, "polished_fraction": 0.6, "lidar_azimuth_step_deg": 0.6, **BRISK,
}  # fmt: skip
PAPER = {
    "office-loop": {"route": "loop", "max_distance_m": 500.0, **BRISK},
    "reflective-loop": {"route": "loop", "max_distance_m": 500.0, "glass_fraction": 1.0, "polished_fraction": 1.0, **BRISK},
}
FULL_EXTRA = {
    "office-loop/layout1": {**PAPER["office-loop"], "office_seed": 1},
    "office-loop/layout2": {**PAPER["office-loop"], "office_seed": 2},
    "no-glass-loop": {**PAPER["office-loop"], "glass_fraction": 0.0, "polished_fraction": 0.0},
    "reflective-loop/vlp32": {**PAPER["reflective-loop"], "lidar": "vlp32"},
}

TABLE_5_5 = {  # sequence -> (SC++, GSC height, GSC Huber) max recall at 100 % precision, %
    "KITTI 02": (57.8, 59.4, 69.7), "KITTI 05": (81.2, 82.6, 83.1), "KITTI 00": (80.8, 81.2, 83.7),
    "VBR Pincio": (36.1, 42.3, 49.3), "VBR Colosseo": (18.4, 16.2, 14.5),
}  # fmt: skip

SUMMARY_ROWS = [
    SummaryRow("max_recall_at_full_precision", "max recall at 100 % precision (%)", scale=100, digits=1),
    SummaryRow("pr_auc", "PR AUC", digits=3),
    SummaryRow("best_f1", "best F1", digits=3),
    SummaryRow("time_per_keyframe_ms", "time per keyframe (ms)", digits=1),
    SummaryRow("n_keyframes", "keyframes", digits=0),
    SummaryRow("n_revisits", "keyframes with a true loop", digits=0),
    SummaryRow("invalid_keyframes", "invalid keyframes", digits=0, terminal=False),
    SummaryRow("correct_match_fraction", "best match within 5 m, of revisits (%)", scale=100, digits=1, terminal=False),
    SummaryRow("yaw_error_deg", "yaw error of correct matches, median (deg)", digits=1, terminal=False),
    SummaryRow("tau_best_f1", "tau at best F1 (1 - sim)", digits=3, terminal=False),
]


def _scenario_class() -> type:
    from exobench.envs.office_sim import OfficeScenario

    @dataclasses.dataclass(frozen=True)
    class LoopOfficeScenario(OfficeScenario):
        """``OfficeScenario`` with the office's size and glazing and the LiDAR's azimuth step."""

        corridor_length_m: float = EXTRA["corridor_length_m"].default
        room_depth_m: float = EXTRA["room_depth_m"].default
        meeting_room_m: float = EXTRA["meeting_room_m"].default
        glass_fraction: float = EXTRA["glass_fraction"].default
        polished_fraction: float = EXTRA["polished_fraction"].default
        lidar_azimuth_step_deg: float = EXTRA["lidar_azimuth_step_deg"].default

        def office_params(self) -> object:
            from exobench.models.office import OfficeParams

            return OfficeParams(seed=self.office_seed, n_offices=self.n_offices,
                                **{k: getattr(self, k) for k in OFFICE_KEYS})  # fmt: skip

        def lidar_config(self) -> Any:
            cfg = super().lidar_config()
            pat = cfg.pattern
            step = float(self.lidar_azimuth_step_deg)
            if step <= 0 or pat.scan_kind != "spinning" or step <= pat.azimuth_step_deg:
                return cfg
            f = step / pat.azimuth_step_deg  # same sweep time: firing blocks further apart
            pat = dataclasses.replace(pat, azimuth_step_deg=step, firing_period_s=pat.firing_period_s * f)
            return dataclasses.replace(cfg, pattern=pat)

    return LoopOfficeScenario


def simulate_loop(scenario: Mapping[str, Any], seed: int) -> Episode:
    """One office walk of a validated scenario (the scoring keys dropped)."""
    from exobench.envs.office_sim import simulate_office

    values = {k: v for k, v in scenario.items() if k not in SCORING_KEYS}
    episode = simulate_office(_scenario_class()(**values), seed)
    scoring = {k: scenario[k] for k in SCORING_KEYS if k in scenario}
    return dataclasses.replace(episode, scenario={**episode.scenario, **scoring})


def _nan_metrics() -> dict[str, Any]:
    keys = ("max_recall_at_full_precision", "pr_auc", "best_f1", "tau_best_f1", "time_per_keyframe_ms",
            "yaw_error_deg", "correct_match_fraction")  # fmt: skip
    return {k: math.nan for k in keys}


def failure_metrics(episode: Episode | None, reason: str) -> dict[str, Any]:
    """Metrics of a failed pipeline or simulation."""
    return {"failed": True, "failed_reason": reason, **_nan_metrics()}


def score_place_recognition(episode: Episode, estimate: PlaceRecognitionEstimate) -> dict[str, Any]:
    """Every metric of one estimate (see the module docstring); never raises on a bad estimate."""
    sc = episode.scenario
    revisit = float(sc.get("revisit_m", EXTRA["revisit_m"].default))
    exclude = float(sc.get("exclude_recent_s", EXTRA["exclude_recent_s"].default))
    stamps = np.asarray(estimate.stamps_s, dtype=float).reshape(-1)
    K = len(stamps)
    arrays = [np.asarray(a).reshape(-1) for a in (estimate.match_index, estimate.distance, estimate.yaw_rad, estimate.time_per_keyframe_s)]
    if any(len(a) != K for a in arrays):
        return failure_metrics(episode, "estimate arrays of different lengths")
    match, dist, yaw_est, times = arrays
    pos, yaw, found = keyframe_poses(episode.truth.trajectory_w, stamps)
    if K and not np.all(found):
        return failure_metrics(episode, f"{int(np.sum(~found))} keyframe stamps match no scan start")
    curve = pr_curve(pos, stamps, match, dist, revisit_m=revisit, exclude_recent_s=exclude)
    f1, tau = best_f1(curve)
    yerr = yaw_errors(yaw, match, yaw_est, curve.correct)
    has_loop = curve.n_loops
    correct_frac = float(np.sum(curve.correct) / has_loop) if has_loop else math.nan
    stats = estimate.stats or {}
    return {
        "failed": False,
        "max_recall_at_full_precision": max_recall_at_full_precision(curve),
        "pr_auc": pr_auc(curve),
        "best_f1": f1,
        "tau_best_f1": tau,
        "time_per_keyframe_ms": float(np.mean(times) * 1000.0) if K else math.nan,
        "n_keyframes": K,
        "n_revisits": has_loop,
        "n_detectable": curve.n_detectable,
        "invalid_keyframes": int(stats.get("invalid_keyframes", int(np.sum(match < 0)))),
        "correct_match_fraction": correct_frac,
        "yaw_error_deg": float(np.degrees(np.median(yerr))) if len(yerr) else math.nan,
        "pr_tau": np.round(curve.tau, 6).tolist(),
        "pr_precision": np.round(curve.precision, 6).tolist(),
        "pr_recall": np.round(curve.recall, 6).tolist(),
    }


def _ref(metric: str, text: str, source: str, pipelines: tuple[str, ...] = (), value: float | None = None) -> Reference:
    return Reference(metric, text, source, (), pipelines, value=value)


def published_references() -> list[Reference]:
    """Table 5.5 (max recall at 100 % precision) and section 5.2.3's time per keyframe."""
    refs = []
    for col, pipe in enumerate(("sc++", "gsc-height", "gsc-huber")):
        v = [vals[col] for vals in TABLE_5_5.values()]
        text = f"KITTI 02/05/00 {v[0]:g}/{v[1]:g}/{v[2]:g}, VBR Pincio/Colosseo {v[3]:g}/{v[4]:g}"
        refs.append(_ref("max_recall_at_full_precision", text, "Tab. 5.5", (pipe,)))
    refs.append(_ref("time_per_keyframe_ms", "54", "Sec. 5.2.3, i9-11950H", ("sc++",), 54.0))
    refs.append(_ref("time_per_keyframe_ms", "67", "Sec. 5.2.3, i9-11950H", ("gsc-huber",), 67.0))
    return refs


# ------------------------------------------------------------------------- figures


def figure_arrays(episode: Episode, estimates: Mapping[str, Any]) -> dict[str, Any]:
    """Arrays of the trajectory figure: true path, and per pipeline the keyframe positions, matches
    and the detections at its best-F1 threshold (correct or not)."""
    tr = np.asarray(episode.truth.trajectory_w, dtype=float).reshape(-1, 8)
    out: dict[str, Any] = {"trajectory_xyz": tr[:, 1:4], "pipelines": np.array(sorted(estimates), dtype=str)}
    sc = episode.scenario
    for name, est in sorted(estimates.items()):
        est = _final(est)
        if not isinstance(est, PlaceRecognitionEstimate):
            continue
        pos, _, _ = keyframe_poses(tr, est.stamps_s)
        curve = pr_curve(pos, est.stamps_s, est.match_index, est.distance,
                         revisit_m=float(sc.get("revisit_m", 5.0)), exclude_recent_s=float(sc.get("exclude_recent_s", 20.0)))  # fmt: skip
        _, tau = best_f1(curve)
        m = np.asarray(est.match_index, dtype=np.int64)
        d = np.asarray(est.distance, dtype=float)
        t = np.asarray(est.stamps_s, dtype=float)
        eligible = (m >= 0) & ((t - t[np.where(m >= 0, m, 0)]) >= float(sc.get("exclude_recent_s", 20.0)))
        detected = eligible & np.isfinite(d) & (d <= tau if math.isfinite(tau) else np.zeros(len(d), dtype=bool))
        out[f"{name}__keyframes_xyz"] = pos
        out[f"{name}__match"] = m
        out[f"{name}__detected"] = detected
        out[f"{name}__correct"] = curve.correct
        out[f"{name}__tau"] = np.array(tau)
    return out


def _final(est: Any) -> Any:
    """The final estimate of a time series ``[(stamp, estimate), ...]`` or the estimate itself."""
    if isinstance(est, (list, tuple)) and est and isinstance(est[-1], (list, tuple)):
        return est[-1][1]
    return est


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_pr_curves(records: list[dict[str, Any]], pipelines: list[str], path: Path, title: str) -> Path:
    """PR curves (recall x, precision y) of each pipeline's records of one episode."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(5.2, 4.2))
    for p in pipelines:
        for r in records:
            m = r["metrics"]
            if r["pipeline"] != p or not m.get("pr_recall"):
                continue
            rec = np.concatenate([[0.0], np.asarray(m["pr_recall"], dtype=float)])
            prec = np.concatenate([[1.0], np.asarray(m["pr_precision"], dtype=float)])
            mr = m.get("max_recall_at_full_precision")
            label = f"{p} (R@P=1 {100 * mr:.1f} %)" if isinstance(mr, (int, float)) else p
            ax.plot(rec, prec, drawstyle="steps-post", label=label)
    ax.set_xlim(0, 1.02)
    ax.set_ylim(0, 1.02)
    ax.set_xlabel("recall")
    ax.set_ylabel("precision")
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_matches(data: Mapping[str, Any], path: Path, title: str) -> Path:
    """One panel per pipeline: the true path, and the detections at best F1 (green correct, red false)."""
    plt = _pyplot()
    names = [str(n) for n in np.atleast_1d(data["pipelines"])]
    fig, axes = plt.subplots(1, max(1, len(names)), figsize=(4.0 * max(1, len(names)), 3.6), squeeze=False)
    tr = np.asarray(data["trajectory_xyz"], dtype=float)
    for ax, name in zip(axes[0], names or [""], strict=True):
        if len(tr):
            ax.plot(tr[:, 0], tr[:, 1], color="0.6", lw=1)
        key = f"{name}__keyframes_xyz"
        if key in data:
            pos = np.asarray(data[key], dtype=float)
            m = np.asarray(data[f"{name}__match"], dtype=int)
            det = np.asarray(data[f"{name}__detected"], dtype=bool)
            ok = np.asarray(data[f"{name}__correct"], dtype=bool)
            for k in np.flatnonzero(det):
                a, b = pos[k], pos[m[k]]
                ax.plot([a[0], b[0]], [a[1], b[1]], color="tab:green" if ok[k] else "tab:red", lw=1.2 if ok[k] else 1.5)
            ax.plot(pos[:, 0], pos[:, 1], ".", color="0.3", ms=2)
            good = np.flatnonzero(det & ok)  # a retraced path makes true segments very short: mark the queries
            ax.plot(pos[good, 0], pos[good, 1], "o", mfc="none", color="tab:green", ms=4, mew=0.8)
            ax.set_title(f"{name}: {int(np.sum(det & ok))} true / {int(np.sum(det & ~ok))} false", fontsize=9)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
    axes[0][0].set_ylabel("y (m)")
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


# ------------------------------------------------------------------------- the track


class LoopClosureTrack:
    """Track protocol implementation for place recognition (see the module docstring)."""

    name: ClassVar[str] = "loop-closure"
    suites: ClassVar[tuple[str, ...]] = ("quick", "paper", "full")
    default_suite: ClassVar[str] = "quick"
    report_intro: ClassVar[str] = (
        "Published figures: Table 5.5 and section 5.2.3 of seeds/003 (KITTI and VBR sequences, "
        "i9-11950H); ours from simulated office loops with a trunk VLP-16."
    )

    def params(self) -> list[ParamInfo]:
        return office_params(EXTRA)

    def validate_scenario(self, values: Mapping[str, Any]) -> dict[str, Any]:
        out = validate_office_scenario(dict(values), EXTRA)
        self._check_office(out)
        return out

    @staticmethod
    def _check_office(values: Mapping[str, Any]) -> None:
        from exobench.models.office import OfficeParams

        OfficeParams(seed=values["office_seed"], n_offices=values["n_offices"], **{k: values[k] for k in OFFICE_KEYS})

    def cases(self, suite: str) -> list[Case]:
        if suite == "quick":
            return [Case("small-loop", "small-loop", dict(QUICK), figure=True)]
        paper = [Case(n, n, dict(v), figure=True) for n, v in PAPER.items()]
        if suite == "paper":
            return paper
        if suite == "full":
            return paper + [Case(n, n, dict(v), figure=False) for n, v in FULL_EXTRA.items()]
        raise UnknownNameError("suite", suite, self.suites)

    def simulate(self, scenario: dict[str, Any], seed: int) -> Episode:
        return simulate_loop(scenario, seed)

    def score(self, episode: Episode, estimate: Any) -> dict[str, Any]:
        if not isinstance(estimate, PlaceRecognitionEstimate):
            return failure_metrics(episode, f"finalize() returned {type(estimate).__name__}, not PlaceRecognitionEstimate")
        try:
            return score_place_recognition(episode, estimate)
        except Exception as e:  # a malformed estimate is a failed result, never a crash
            return failure_metrics(episode, f"scoring raised {type(e).__name__}: {e}")

    def failed_metrics(self, episode: Episode | None, reason: str) -> dict[str, Any]:
        return failure_metrics(episode, reason)

    def references(self) -> list[Reference]:
        return published_references()

    def summary_rows(self) -> list[SummaryRow]:
        return list(SUMMARY_ROWS)

    def figure_data(self, episode: Episode, estimates: dict[str, Any]) -> dict[str, Any]:
        return figure_arrays(episode, estimates)

    def report_sections(self, records: list[dict[str, Any]], pipelines: list[str], out: Path) -> list[str]:
        """PR curves per episode (up to 12) and the figure cases' trajectories with their matches."""
        lines = ["## Precision-recall curves", ""]
        episodes: list[str] = []
        for r in records:
            if r["episode"] not in episodes:
                episodes.append(r["episode"])
        for ep in episodes[:12]:
            png = out / f"pr_{ep.replace('/', '__')}.png"
            plot_pr_curves([r for r in records if r["episode"] == ep], pipelines, png, ep)
            lines += [f"### {ep}", "", f"![PR {ep}]({png.name})", ""]
        figures = sorted((out / "figures").glob("*.npz")) if (out / "figures").exists() else []
        if figures:
            lines += ["## Loop matches at the best-F1 threshold (green true, red false)", ""]
            for f in figures:
                key = f.stem.replace("__", "/")
                with np.load(f) as data:
                    png = plot_matches(dict(data), f.with_suffix(".png"), key)
                lines += [f"### {key}", "", f"![{key}](figures/{png.name})", ""]
        return lines

    def write_recording(self, episode: Episode, estimates_by_pipeline: dict[str, Any], path: Path) -> Path:
        """Scans (every 5th, by intensity and by true return kind), true surfaces and trajectory,
        and each pipeline's detections at its best-F1 threshold as segments between the true
        keyframe positions (green true, red false), shown from the query's time."""
        import rerun as rr
        import rerun.blueprint as rrb

        from .office_common import log_office_world, log_scans, log_trajectory

        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        rec = rr.RecordingStream("exobench", recording_id=f"loop-closure-{episode.seed}")
        blueprint = rrb.Blueprint(rrb.Spatial3DView(origin="/world", name="office"), collapse_panels=True)
        rec.save(path, default_blueprint=blueprint)
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        log_office_world(rr, rec, episode)
        tr = np.asarray(episode.truth.trajectory_w, dtype=float).reshape(-1, 8)
        log_trajectory(rr, rec, "world/trajectory/true", tr[:, 1:4], (240, 200, 60))
        log_scans(rr, rec, episode, every=5)
        finals = {n: _final(e) for n, e in estimates_by_pipeline.items()}
        data = figure_arrays(episode, finals)
        for name, est in sorted(finals.items()):
            if not isinstance(est, PlaceRecognitionEstimate) or f"{name}__keyframes_xyz" not in data:
                continue
            pos = data[f"{name}__keyframes_xyz"]
            ent = name.replace("+", "p")  # "sc++" -> "scpp": no escapes in entity paths
            m, det, ok = data[f"{name}__match"], data[f"{name}__detected"], data[f"{name}__correct"]
            segs_ok: list = []
            segs_bad: list = []
            for k in np.flatnonzero(det):
                (segs_ok if ok[k] else segs_bad).append([pos[k], pos[m[k]]])
                rec.set_time("sim_time", duration=float(est.stamps_s[k]))
                if segs_ok:
                    rec.log(f"world/loops/{ent}/true", rr.LineStrips3D(segs_ok, colors=[(40, 200, 60)], radii=0.03))
                if segs_bad:
                    rec.log(f"world/loops/{ent}/false", rr.LineStrips3D(segs_bad, colors=[(230, 40, 40)], radii=0.03))
            log_trajectory(rr, rec, f"world/keyframes/{ent}", pos, (120, 120, 255))
        rec.flush()
        rec.disconnect()
        return path
