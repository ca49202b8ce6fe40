"""The OpenGL platform MuJoCo renders with, chosen before ``mujoco`` is first imported.

MuJoCo reads ``MUJOCO_GL`` once, when ``mujoco`` is imported, and cannot change platform
afterwards. Importing this module (``exobench.envs`` and the command line do it first) puts a
finder in front of ``sys.meta_path`` that, on the first ``import mujoco``, calls
:func:`choose_gl_platform` and steps aside. So every entry point (the command line, worker
processes, the gymnasium environments, a user's script) gets the choice before MuJoCo loads,
while importing exobench stays cheap: nothing is probed until MuJoCo is needed.

:func:`choose_gl_platform` respects an explicit ``MUJOCO_GL``. Otherwise it probes EGL, then
OSMesa, each in a short subprocess (a failed GL initialisation cannot be undone in-process), and
sets ``MUJOCO_GL`` and ``PYOPENGL_PLATFORM`` to the first that renders; child processes inherit
them. It never raises: when no platform works MuJoCo still imports (simulation needs no GL) and
the renderer reports the problem when one is made.

This module must not import mujoco.
"""

from __future__ import annotations

import importlib.abc
import os
import subprocess
import sys
from typing import Any

GL_BACKENDS = ("egl", "osmesa")
_PROBE = (
    "import mujoco\n"
    "m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom size=\"1\"/></worldbody></mujoco>')\n"
    "r = mujoco.Renderer(m, 8, 8)\n"
    "r.update_scene(mujoco.MjData(m))\n"
    "r.render()\n"
    "r.close()\n"
)
_state: dict[str, Any] = {"probed": False}


def _probe(backend: str) -> bool:
    env = dict(os.environ, MUJOCO_GL=backend, PYOPENGL_PLATFORM=backend)
    try:
        res = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, timeout=120)
    except (OSError, subprocess.SubprocessError):
        return False
    return res.returncode == 0


def choose_gl_platform() -> str:
    """``MUJOCO_GL`` after choosing it (EGL, else OSMesa) if it is unset and mujoco not loaded.

    Returns "" when it is unset and either ``mujoco`` is already imported (too late to choose)
    or no platform rendered in the probe (probed once per process).
    """
    backend = os.environ.get("MUJOCO_GL", "").strip().lower()
    if backend or "mujoco" in sys.modules or _state["probed"]:
        return backend
    _state["probed"] = True
    for candidate in GL_BACKENDS:
        if _probe(candidate):
            os.environ["MUJOCO_GL"] = candidate
            os.environ.setdefault("PYOPENGL_PLATFORM", candidate)
            return candidate
    return ""


class _ChooseBeforeMujoco(importlib.abc.MetaPathFinder):
    """On the first ``import mujoco``: choose the platform, leave ``sys.meta_path``, find nothing."""

    def find_spec(self, fullname: str, path: Any = None, target: Any = None) -> None:
        if fullname == "mujoco":
            uninstall()
            choose_gl_platform()
        return None


_FINDER = _ChooseBeforeMujoco()


def install() -> None:
    """Choose the GL platform on the first ``import mujoco`` (no-op if it is imported or set)."""
    if "mujoco" in sys.modules or os.environ.get("MUJOCO_GL", "").strip() or _FINDER in sys.meta_path:
        return
    sys.meta_path.insert(0, _FINDER)


def uninstall() -> None:
    """Remove the finder of :func:`install` (if present)."""
    while _FINDER in sys.meta_path:
        sys.meta_path.remove(_FINDER)


install()
