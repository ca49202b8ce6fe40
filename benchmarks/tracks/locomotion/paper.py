"""The published figures of the locomotion-mode paper (seeds/002, Sec. IV) and the grid they index.

- :data:`TABLE_II`: mean prediction accuracy (%) of each of the 180 condition combinations of
  the generality test: height group (I-V) x walking pattern (rows) x terrain x mount (columns).
- :data:`TABLE_III`: mean ± std accuracy (%) per terrain, terrain kind, pattern and mount.
- Sec. IV-A: 99.00 ± 0.95 % over all conditions; IV-B unconventional camera views 99.07 ± 1.41 %;
  IV-C multi-direction 98.18 ± 1.76 %; IV-D external disturbances 98.59 ± 1.91 %.
- Time: 31 ms per frame for the D-VIO (Tab. IV, average on EuRoC) and "the prediction time
  consumption can be constrained within 34 ms" (Sec. III-A).

The figures come from real subjects and a real D455; they are printed beside ours.
"""

from __future__ import annotations

from ..spec import Reference

# terrain levels of the generality test, in Table II's column order: (terrain, value, label)
TERRAIN_LEVELS: tuple[tuple[str, float, str], ...] = (
    ("stairs", 0.15, "stairs 0.15 m"),
    ("stairs", 0.20, "stairs 0.20 m"),
    ("stairs", 0.25, "stairs 0.25 m"),
    ("ramp", 11.8, "ramp 11.8 deg"),
    ("ramp", 15.8, "ramp 15.8 deg"),
    ("ramp", 17.8, "ramp 17.8 deg"),
)
TERRAIN_GROUPS = tuple(label for _, _, label in TERRAIN_LEVELS)
MOUNTS = ("head", "chest")
PATTERNS = ("wander", "walk", "jog")
# mean standing height of the five subject groups (Sec. III-A: 165.13, 171.30, 175.03, 181.80,
# 187.70 cm), rounded to the centimetre
HEIGHT_GROUPS: tuple[tuple[str, float], ...] = (("I", 1.65), ("II", 1.71), ("III", 1.75), ("IV", 1.82), ("V", 1.88))

# Table II: rows (group, pattern) in HEIGHT_GROUPS x PATTERNS order; 12 columns: for each terrain
# of TERRAIN_LEVELS, head then chest
TABLE_II: tuple[tuple[float, ...], ...] = (
    (100.00, 100.00, 100.00, 98.15, 100.00, 98.21, 100.00, 97.73, 98.44, 98.46, 98.63, 98.67),
    (97.83, 98.00, 97.73, 100.00, 97.73, 100.00, 100.00, 100.00, 98.25, 100.00, 100.00, 100.00),
    (97.96, 100.00, 97.87, 100.00, 97.96, 100.00, 96.97, 100.00, 100.00, 98.18, 98.11, 98.28),
    (100.00, 100.00, 100.00, 100.00, 100.00, 98.08, 98.63, 100.00, 98.08, 100.00, 98.68, 98.68),
    (100.00, 100.00, 100.00, 100.00, 100.00, 97.14, 98.55, 100.00, 100.00, 98.11, 98.33, 100.00),
    (100.00, 97.74, 97.14, 98.31, 97.72, 97.78, 100.00, 98.59, 100.00, 100.00, 100.00, 98.18),
    (99.06, 98.17, 97.75, 98.06, 98.25, 100.00, 100.00, 97.18, 100.00, 98.51, 96.77, 98.46),
    (100.00, 98.99, 98.94, 98.97, 100.00, 100.00, 100.00, 100.00, 98.46, 98.33, 98.18, 98.36),
    (98.72, 100.00, 100.00, 100.00, 100.00, 97.87, 97.72, 100.00, 98.15, 100.00, 100.00, 98.18),
    (98.15, 98.02, 98.15, 99.07, 98.04, 96.36, 99.23, 99.38, 98.59, 98.67, 98.46, 100.00),
    (100.00, 99.07, 100.00, 98.99, 100.00, 100.00, 99.10, 99.17, 98.36, 100.00, 98.44, 98.46),
    (100.00, 98.88, 98.86, 100.00, 100.00, 100.00, 97.30, 99.12, 100.00, 97.96, 100.00, 98.31),
    (99.07, 98.25, 100.00, 99.02, 100.00, 98.11, 97.66, 100.00, 100.00, 100.00, 97.50, 98.39),
    (100.00, 98.11, 98.86, 98.55, 100.00, 98.11, 98.55, 100.00, 98.31, 100.00, 100.00, 98.21),
    (98.90, 97.78, 100.00, 98.86, 97.56, 97.50, 98.15, 98.78, 100.00, 98.04, 97.50, 97.78),
)

# Table III (and Sec. IV): pooled group name -> (mean %, std %, source)
TABLE_III: dict[str, tuple[float, float, str]] = {
    "stairs 0.15 m": (99.09, 0.88, "Tab. III"),
    "stairs 0.20 m": (99.11, 0.89, "Tab. III"),
    "stairs 0.25 m": (98.82, 1.24, "Tab. III"),
    "ramp 11.8 deg": (99.06, 1.00, "Tab. III"),
    "ramp 15.8 deg": (99.09, 1.11, "Tab. III"),
    "ramp 17.8 deg": (98.63, 0.95, "Tab. III"),
    "stairs": (99.03, 1.21, "Tab. III"),
    "ramp": (98.98, 1.14, "Tab. III"),
    "wander": (98.88, 1.02, "Tab. III"),
    "walk": (99.29, 0.87, "Tab. III"),
    "jog": (98.79, 1.17, "Tab. III"),
    "head": (99.03, 1.04, "Tab. III"),
    "chest": (98.90, 1.04, "Tab. III"),
    "all": (99.00, 0.95, "Sec. IV-A"),
}
# the other protocols: summary group -> (mean %, std %, source)
PROTOCOLS: dict[str, tuple[float, float, str]] = {
    "unconventional view": (99.07, 1.41, "Sec. IV-B"),
    "multi-direction": (98.18, 1.76, "Sec. IV-C"),
    "disturbance": (98.59, 1.91, "Sec. IV-D"),
}
METHOD_PIPELINE = "terrain-recon"  # the paper's method; the published figures apply to it
# and to the same method on its own odometry, D-VIO, as the paper's system ran (issue 27)
METHOD_DVIO_PIPELINE = "terrain-recon-dvio"


def table_ii_value(height_group: str, pattern: str, terrain_label: str, mount: str) -> float:
    """One cell of Table II (%)."""
    row = [g for g, _ in HEIGHT_GROUPS].index(height_group) * len(PATTERNS) + PATTERNS.index(pattern)
    col = TERRAIN_GROUPS.index(terrain_label) * len(MOUNTS) + MOUNTS.index(mount)
    return TABLE_II[row][col]


def published_references() -> list[Reference]:
    """The figures above that apply to a summary group of the track (the six terrains and the
    three other protocols) as References (accuracy values as fractions, like the metric). The
    pooled rows of Table III that no summary group holds (``stairs``, ``ramp``, the patterns, the
    mounts, ``all``) are in :func:`table_iii_text`, for the report's Table III section.
    """
    pipes = (METHOD_PIPELINE, METHOD_DVIO_PIPELINE)
    refs = [
        Reference("accuracy", f"{mean:.2f} ± {std:.2f}", src, (group,), pipes, value=mean / 100.0)
        for group, (mean, std, src) in {**TABLE_III, **PROTOCOLS}.items()
        if group in TERRAIN_GROUPS or group in PROTOCOLS
    ]
    refs += [
        Reference("latency_ms_median", "31", "Tab. IV, D-VIO time per frame", (), pipes, value=31.0),
        Reference("latency_ms_median", "< 34", "Sec. III-A, prediction time", (), pipes, value=34.0, bound="<"),
    ]
    return refs


def table_iii_text(row: str) -> str:
    """Table III's figure for one of its rows (a terrain level, ``stairs``, ``ramp``, a pattern,
    a mount or ``all``) with its source, e.g. ``"99.03 ± 1.21 (Tab. III)"``; empty for another row."""
    if row not in TABLE_III:
        return ""
    mean, std, src = TABLE_III[row]
    return f"{mean:.2f} ± {std:.2f} ({src})"
