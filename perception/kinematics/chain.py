"""Kinematic chains of a pinocchio model compiled to straight-line Python.

The per-point path of :class:`~.tof_kinematics.TofKinematics` does not run pinocchio's
``forwardKinematics`` on numpy arrays: it walks, in plain Python floats, only the joint chain
between the base link and the link carrying a vector. This module reads such a chain from the
model once (:func:`chain_to_base`: the constant placements and, per joint, its motion) and writes
it out as a function with the constants inlined (:func:`compile_chain`), so mapping a vector
costs a few rotations of 3-vectors about the joint axes. Revolute (also continuous) and
prismatic joints are handled; any other joint type, or a base link that moves with the joints,
gives no chain (the caller falls back to pinocchio).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = ["Step", "chain_to_base", "compile_chain", "motion_step"]

# a chain step: ("c", R (9 floats, row-major) or None for identity, t (3 floats)) is a constant
# transform; ("r", joint name, axis (3 floats)) a revolute joint; ("a", joint name, (i, j, sign))
# a revolute joint about +-axis k (rotating coordinates i, j); ("p", joint name, axis) prismatic.
Step = tuple


def compile_chain(steps: list[Step], points: list[list[float]], dirs: list[list[float]]) -> Callable[..., tuple[float, ...]]:
    """Straight-line Python for mapping constant vectors through ``steps`` to the base frame.

    Returns ``f(angles)`` (joint positions by name, 0 when missing) -> the mapped ``points``
    (rotated and translated) then ``dirs`` (rotated), 3 floats each. The chain is written out
    once with its constants inlined because a generic loop over steps and vectors costs several
    times the arithmetic (the same reason ``dataclasses`` generates its methods).
    """
    vecs = [*points, *dirs]
    n_pts = len(points)
    lines = ["def chain(angles):"]
    for i, (x, y, z) in enumerate(vecs):
        lines.append(f"    x{i}, y{i}, z{i} = {float(x)!r}, {float(y)!r}, {float(z)!r}")
    for kind, a, b in steps:
        if kind == "c":
            tx, ty, tz = (float(v) for v in b)
            for i in range(len(vecs)):
                tr = (f" + {tx!r}", f" + {ty!r}", f" + {tz!r}") if i < n_pts else ("", "", "")
                if a is not None:
                    r = [repr(float(v)) for v in a]
                    lines.append(
                        f"    x{i}, y{i}, z{i} = {r[0]} * x{i} + {r[1]} * y{i} + {r[2]} * z{i}{tr[0]}, "
                        f"{r[3]} * x{i} + {r[4]} * y{i} + {r[5]} * z{i}{tr[1]}, "
                        f"{r[6]} * x{i} + {r[7]} * y{i} + {r[8]} * z{i}{tr[2]}"
                    )
                elif i < n_pts and (tx, ty, tz) != (0.0, 0.0, 0.0):
                    lines.append(f"    x{i}, y{i}, z{i} = x{i}{tr[0]}, y{i}{tr[1]}, z{i}{tr[2]}")
        elif kind == "a":  # about +-axis k: coordinates (i, j) rotate
            i_ax, j_ax, sign = b
            lines.append(f"    q = angles.get({a!r}, 0.0)")
            lines.append("    c, s = cos(q), sin(q)")
            for i in range(len(vecs)):
                u, w = ("xyz"[i_ax] + str(i)), ("xyz"[j_ax] + str(i))
                if sign > 0:
                    lines.append(f"    {u}, {w} = c * {u} - s * {w}, s * {u} + c * {w}")
                else:
                    lines.append(f"    {u}, {w} = c * {u} + s * {w}, c * {w} - s * {u}")
        elif kind == "r":  # Rodrigues about the unit axis k
            kx, ky, kz = (repr(float(v)) for v in b)
            lines.append(f"    q = angles.get({a!r}, 0.0)")
            lines.append("    c, s = cos(q), sin(q)")
            lines.append("    omc = 1.0 - c")
            for i in range(len(vecs)):
                x, y, z = f"x{i}", f"y{i}", f"z{i}"
                lines.append(f"    d = ({kx} * {x} + {ky} * {y} + {kz} * {z}) * omc")
                lines.append(
                    f"    {x}, {y}, {z} = c * {x} + s * ({ky} * {z} - {kz} * {y}) + d * {kx}, "
                    f"c * {y} + s * ({kz} * {x} - {kx} * {z}) + d * {ky}, "
                    f"c * {z} + s * ({kx} * {y} - {ky} * {x}) + d * {kz}"
                )
        else:  # prismatic along the unit axis k
            kx, ky, kz = (repr(float(v)) for v in b)
            lines.append(f"    qp = angles.get({a!r}, 0.0)")
            for i in range(n_pts):
                lines.append(f"    x{i}, y{i}, z{i} = x{i} + qp * {kx}, y{i} + qp * {ky}, z{i} + qp * {kz}")
    lines.append("    return (" + "".join(f"x{i}, y{i}, z{i}, " for i in range(len(vecs))) + ")")
    namespace: dict[str, Any] = {"cos": math.cos, "sin": math.sin}
    exec(compile("\n".join(lines), "<kinematic chain>", "exec"), namespace)  # noqa: S102
    return namespace["chain"]


def _se3(M: object) -> tuple[tuple[float, ...] | None, tuple[float, float, float]]:
    R = np.asarray(M.rotation, dtype=float)  # type: ignore[attr-defined]
    t = tuple(np.asarray(M.translation, dtype=float).tolist())  # type: ignore[attr-defined]
    return (None if np.array_equal(R, np.eye(3)) else tuple(R.reshape(9).tolist())), t  # type: ignore[return-value]


def motion_step(model: Any, j: int) -> Step | None:
    """The chain step of joint ``j`` of ``model``, None for a joint type not handled here."""
    jm = model.joints[j]
    if jm.nv != 1 or jm.nq not in (1, 2):
        return None
    jd = jm.createData()
    q0 = np.zeros(jm.nq)
    if jm.nq == 2:
        q0[0] = 1.0
    jm.calc(jd, q0)
    S = np.asarray(jd.S, dtype=float).ravel()  # (linear, angular)
    lin, ang = S[:3], S[3:]
    name = model.names[j]
    if np.all(lin == 0.0) and abs(np.linalg.norm(ang) - 1.0) < 1e-12:
        nz = np.flatnonzero(ang)
        if len(nz) == 1 and abs(ang[nz[0]]) == 1.0:
            k = int(nz[0])
            return ("a", name, ((k + 1) % 3, (k + 2) % 3, float(ang[k])))
        return ("r", name, tuple(ang.tolist()))
    if np.all(ang == 0.0) and abs(np.linalg.norm(lin) - 1.0) < 1e-12 and jm.nq == 1:
        return ("p", name, tuple(lin.tolist()))
    return None


def chain_to_base(model: Any, base_fid: int, joint: int) -> list[Step] | None:
    """Steps mapping vectors of joint ``joint``'s frame (after its motion) to the frame of the
    base link (frame ``base_fid``); None when a joint, or the base, is not handled."""
    base = model.frames[base_fid]
    if base.parentJoint != 0:
        return None  # the base moves with the joints: not handled by the fast path
    T_base_universe = base.placement.inverse()
    steps: list[Step] = []
    j = joint
    while j > 0:
        m = motion_step(model, j)
        if m is None:
            return None
        steps.append(m)
        placement = model.jointPlacements[j]
        j = model.parents[j]
        if j == 0:
            placement = T_base_universe * placement
        steps.append(("c", *_se3(placement)))
    if joint == 0:
        steps.append(("c", *_se3(T_base_universe)))
    return steps
