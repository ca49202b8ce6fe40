"""Glazing that is not flat: the overall bow and roller wave of toughened panes, for mirrored beams.

A flat pane mirrors the static world into a static virtual one. Real panes are not flat, and
the deviation is what a mirrored beam sees: tilting the surface by a slope ``s`` turns the
reflected beam by ``2 s``, so a ghost ``L`` metres beyond the pane moves by about ``2 s L``, and
moves differently as the viewer walks past (the slope differs from point to point of the pane).

Each glazing pane (a box geom of kind ``glass``; its thinnest axis is its normal ``e_n``, the
other two in-plane axes ``u``, ``v`` of half-widths ``a``, ``b``) has the surface offset along
``e_n`` (pane frame, origin at the pane's centre)::

    w(u, v) = delta * cos(pi u / 2a) * cos(pi v / 2b) + A * sin(2 pi t / lam + phi)

* overall bow: a bump of centre deflection ``delta = sign * bow * D`` (``bow`` the bow per
  metre, ``D`` the pane's diagonal; zero at the edges, held by the frame), sign +-1 per pane;
* roller wave: a sinusoid of peak-to-valley ``2 A`` and wavelength ``lam`` along ``t``, the
  direction the pane travelled over the furnace rollers (``u`` or ``v`` per pane), phase ``phi``.

Sign, roller direction and phase are drawn per pane from ``seed`` and the geom's name, so a pane
keeps its shape through a walk and across runs. At a hit the beam is mirrored about the local
normal ``sigma (e_n - grad w) / |e_n - grad w|`` (``sigma`` the side of the face hit, both faces
bend together); the hit point stays on the flat face (the offsets are millimetres). Only beams
mirrored or reflected at a pane see the shape: a bent pane of uniform thickness does not deviate
the beams crossing it. The published values behind ``bow`` and ``A`` are in
:mod:`exobench.models.materials`.
"""

from __future__ import annotations

import zlib

import numpy as np


class PaneShapes:
    """Bow and roller wave of the glass box geoms of a model (module docstring).

    Args:
        model: the MuJoCo model (box sizes and types).
        geom_names: names per geom id (per-pane draws are keyed by name).
        is_glass: bool per geom id, the panes to shape (non-box geoms are left flat).
        bow_per_m: overall bow, centre deflection per metre of the pane's diagonal (m/m).
        wave_pv_m: roller wave peak-to-valley, m.
        wave_length_m: roller wave wavelength, m.
        seed: draws of the per-pane sign, roller direction and phase.
        front_share: per geom id, the share of a double-glazed unit's reflection from its front
            pane (1: a single pane; default all 1).
    """

    def __init__(self, model: object, geom_names: list[str], is_glass: np.ndarray, bow_per_m: float, wave_pv_m: float,
                 wave_length_m: float, seed: int, front_share: np.ndarray | None = None) -> None:  # fmt: skip
        import mujoco

        gtype = np.asarray(model.geom_type)  # type: ignore[attr-defined]
        ids = np.flatnonzero(np.asarray(is_glass, dtype=bool) & (gtype == mujoco.mjtGeom.mjGEOM_BOX))
        size = np.asarray(model.geom_size)[ids]  # type: ignore[attr-defined]
        self.ids = ids
        self.row = np.full(len(gtype), -1, dtype=np.int64)
        self.row[ids] = np.arange(len(ids))
        self.normal_axis = np.argmin(size, axis=1)
        axes = np.array([[1, 2], [0, 2], [0, 1]])[self.normal_axis]  # the in-plane axes u, v
        self.u_axis, self.v_axis = axes[:, 0], axes[:, 1]
        rows = np.arange(len(ids))
        self.half = np.stack([size[rows, self.u_axis], size[rows, self.v_axis]], axis=1)
        draws = np.array([_draws(seed, geom_names[g]) for g in ids]).reshape(len(ids), 5)
        diag = 2.0 * np.hypot(self.half[:, 0], self.half[:, 1])
        # column 0: the pane on the +e_n side; column 1: a double-glazed unit's pane on the -e_n side,
        # bowed the other way (the cavity's pressure pushes both panes out, or both in)
        delta = np.where(draws[:, 0] < 0.5, -1.0, 1.0) * bow_per_m * diag
        self.delta = np.stack([delta, -delta], axis=1)
        self.wave_on_v = np.stack([draws[:, 1] < 0.5, draws[:, 3] < 0.5], axis=1)
        self.phase = 2.0 * np.pi * draws[:, [2, 4]]
        fs = np.ones(len(gtype)) if front_share is None else np.asarray(front_share, dtype=float)
        self.front_share = fs[ids]
        self.amp = 0.5 * wave_pv_m
        self.k = 2.0 * np.pi / wave_length_m

    def slopes(self, rows: np.ndarray, u: np.ndarray, v: np.ndarray, pane: np.ndarray | int = 0) -> tuple[np.ndarray, np.ndarray]:
        """(dw/du, dw/dv) of the panes ``rows`` at their in-plane coordinates ``u, v`` (m); ``pane`` 0
        the (single or) +e_n-side pane, 1 a double-glazed unit's -e_n-side pane."""
        a, b = self.half[rows, 0], self.half[rows, 1]
        cu, cv = np.pi / (2.0 * a), np.pi / (2.0 * b)
        d = self.delta[rows, pane]
        wu = -d * cu * np.sin(cu * u) * np.cos(cv * v)
        wv = -d * cv * np.cos(cu * u) * np.sin(cv * v)
        on_v = self.wave_on_v[rows, pane]
        wave = self.amp * self.k * np.cos(self.k * np.where(on_v, v, u) + self.phase[rows, pane])
        return wu + np.where(on_v, 0.0, wave), wv + np.where(on_v, wave, 0.0)

    def normals(self, data: object, geom: np.ndarray, hit_w: np.ndarray, normals_w: np.ndarray,
                pick: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
        """``normals_w`` with the local normal at the hits ``hit_w`` on shaped panes' faces (a copy
        where any changes; the flat normal where the hit is on a pane's edge). At a double-glazed
        unit the back pane (as seen from the side hit) is taken where the uniform ``pick`` is at
        least the unit's front share (None: the front pane)."""
        g = np.asarray(geom, dtype=np.int64)
        ok = g >= 0
        rows_all = np.where(ok, self.row[np.where(ok, g, 0)], -1)
        sel = np.flatnonzero(rows_all >= 0)
        if len(sel) == 0:
            return normals_w
        rows = rows_all[sel]
        gid = self.ids[rows]
        R = np.asarray(data.geom_xmat)[gid].reshape(-1, 3, 3)  # type: ignore[attr-defined]
        local = np.einsum("nji,nj->ni", R, hit_w[sel] - np.asarray(data.geom_xpos)[gid])  # type: ignore[attr-defined]
        n_idx = np.arange(len(sel))
        u = np.clip(local[n_idx, self.u_axis[rows]], -self.half[rows, 0], self.half[rows, 0])
        v = np.clip(local[n_idx, self.v_axis[rows]], -self.half[rows, 1], self.half[rows, 1])
        e_n = R[n_idx, :, self.normal_axis[rows]]
        nrm = normals_w[sel]
        side = np.einsum("ij,ij->i", nrm, e_n)
        back = np.zeros(len(sel), dtype=bool) if pick is None else np.asarray(pick)[sel] >= self.front_share[rows]
        # a single pane's two faces bend together; a unit's pane on the -e_n side is pane 1
        pane = np.where(self.front_share[rows] < 1.0, (side < 0.0) ^ back, False).astype(np.int64)
        wu, wv = self.slopes(rows, u, v, pane)
        grad = np.zeros((len(sel), 3))
        grad[n_idx, self.u_axis[rows]] = wu
        grad[n_idx, self.v_axis[rows]] = wv
        face = np.abs(side) > 0.5  # hits on a pane's edge keep their flat normal
        new = np.where(side < 0.0, -1.0, 1.0)[:, None] * (e_n - np.einsum("nij,nj->ni", R, grad))
        new /= np.linalg.norm(new, axis=1)[:, None]
        out = normals_w.copy()
        out[sel] = np.where(face[:, None], new, nrm)
        return out


def _draws(seed: int, name: str) -> np.ndarray:
    """Five uniforms for a pane: bow sign, roller direction and wave phase of its (+e_n side) pane,
    roller direction and wave phase of a double-glazed unit's other pane."""
    return np.random.default_rng([int(seed), zlib.crc32(name.encode())]).random(5)
