"""The OpenGL platform is chosen before MuJoCo is imported, in every entry point, when MUJOCO_GL is unset."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.long(seconds=12)  # the workers take it first (tests/conftest.py); 12: the file at -n 0 in one run at load 12-15, scaled to that run's CPU

ROOT = Path(__file__).resolve().parents[2]
TINY = ["--set", "width_px=64", "--set", "height_px=48", "--set", "rate_hz=5", "--set", "duration_cap_s=3"]


def _clean_env():
    return {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}


def _python(script, timeout=120):
    return subprocess.run([sys.executable, "-c", script], env=_clean_env(), cwd=ROOT, capture_output=True, text=True, timeout=timeout)


def test_cli_run_locomotion_without_mujoco_gl(tmp_path):
    # the CLI's `run` on the quick suite's first locomotion case only (one pipeline, tiny images)
    script = (
        "from exobench.benchmarks.tracks.locomotion import track as t\n"
        "first = t.quick_cases()[:1]\n"
        "t.quick_cases = lambda: first\n"
        "from exobench.benchmarks.cli import main\n"
        f"main(['run', '--track', 'locomotion', '--pipeline', 'terrain-recon', *{TINY!r}, '--out', {str(tmp_path / 'run')!r}, '--no-report'])\n"
    )
    res = _python(script)
    assert res.returncode == 0, res.stderr[-2000:]
    assert "1 records (0 failed)" in res.stdout, res.stdout[-2000:]


def test_cli_record_locomotion_without_mujoco_gl(tmp_path):
    script = (
        "from exobench.benchmarks.cli import main\n"
        f"main(['record', {str(tmp_path / 's')!r}, '--track', 'locomotion', *{TINY!r}])\n"
    )
    res = _python(script)
    assert res.returncode == 0, res.stderr[-2000:]
    assert "session:" in res.stdout


def test_gym_render_without_mujoco_gl():
    script = (
        "import gymnasium, os\n"
        "import exobench.envs\n"
        "env = gymnasium.make('exobench/StairClimb-v0', render_mode='rgb_array')\n"
        "env.reset(seed=0)\n"
        "img = env.render()\n"
        "print(img.shape, os.environ['MUJOCO_GL'])\n"
    )
    res = _python(script)
    assert res.returncode == 0, res.stderr[-2000:]
    shape, backend = res.stdout.rsplit(" ", 1)
    assert backend.strip() in ("egl", "osmesa") and shape.endswith(", 3)")


def test_worker_processes_choose_before_importing_mujoco():
    # the runner's pool: a worker that imports mujoco first has MUJOCO_GL set by then
    script = (
        "from exobench.benchmarks.pool import make_pool\n"
        "with make_pool(1) as pool:\n"
        "    print(pool.submit(eval, \"[__import__('mujoco'), __import__('os').environ.get('MUJOCO_GL')][1]\").result())\n"
    )
    res = _python(script)
    assert res.returncode == 0, res.stderr[-2000:]
    assert res.stdout.strip() in ("egl", "osmesa")


def test_importing_exobench_envs_stays_light():
    res = _python("import sys, exobench.envs\nprint('mujoco' in sys.modules)")
    assert res.returncode == 0 and res.stdout.strip() == "False", res.stderr
