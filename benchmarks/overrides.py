"""``--set KEY=VALUE`` overrides: parsing, and routing to the scenario or to a pipeline.

A key without a dot is a scenario parameter of the track (``riser_m``); a key with one is
``<pipeline>.<rest>``, where the pipeline is the longest name of the run that prefixes the key
followed by a dot and ``rest`` is handed to the pipeline registry whole, dots included, for
nested config fields (``kiss-icp.filter.band_m`` -> ``{"filter.band_m": ...}`` for ``kiss-icp``).
Values stay strings here; the track and the pipeline's config convert and validate them.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from exobench.core.errors import ConfigError, UnknownNameError

from .tracks.spec import Track


def parse_assignments(items: Sequence[str]) -> dict[str, str]:
    """``["KEY=VALUE", ...]`` -> dict; a malformed item raises ConfigError."""
    out: dict[str, str] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ConfigError("--set", item, "KEY=VALUE")
        out[key.strip()] = value.strip()
    return out


def split_overrides(
    overrides: Mapping[str, Any], pipelines: Sequence[str]
) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
    """``(scenario overrides, {pipeline: {rest: value}})`` of ``--set`` keys.

    A key with a dot is ``<pipeline>.<rest>``: the pipeline is the longest of ``pipelines`` that
    prefixes the key followed by a dot, and ``rest`` is kept whole, dots included
    (``kiss-icp.filter.band_m`` -> ``{"kiss-icp": {"filter.band_m": ...}}``); a dotted key that
    names none of them raises UnknownNameError. Keys without a dot are scenario parameters.
    """
    scenario: dict[str, Any] = {}
    per_pipeline: dict[str, dict[str, Any]] = {}
    for key, value in overrides.items():
        if "." not in key:
            scenario[key] = value
            continue
        name = max((n for n in pipelines if key.startswith(n + ".")), key=len, default=None)
        if name is None:
            raise UnknownNameError("pipeline (in --set)", key.partition(".")[0], pipelines)
        per_pipeline.setdefault(name, {})[key[len(name) + 1 :]] = value
    return scenario, per_pipeline


def check_scenario_overrides(track: Track, raw: Mapping[str, Any]) -> dict[str, Any]:
    """Check the names of scenario overrides; values stay as given (the track validates them)."""
    if not raw:
        return {}
    names = {p.name for p in track.params()}
    for key in raw:
        if key not in names:
            raise UnknownNameError("scenario parameter", key, names)
    return dict(raw)
