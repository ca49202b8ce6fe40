"""A run's episodes on Ray (``exobench run --executor ray``): one machine or a cluster.

The unit of work is the pool's (:func:`exobench.benchmarks.runner._run_job`: simulate once, run
every pipeline, return the records and the figure); the driver alone writes the run folder, as
with the pool. The choices, and why:

- Workers are Ray actors, one per concurrent episode, kept for the whole run, so that the
  per-process caches (compiled worlds, meshes) stay warm across episodes. Each chooses the GL
  platform before it imports MuJoCo (:mod:`exobench.envs.gl_platform`), as the pool's do.
- Actors can be started, and made to import what the episodes will (the runner, the track's and
  the pipelines' modules), before the episodes are submitted (:meth:`RayExecutor.start_workers`):
  `run` starts them as soon as it is connected, while it prepares the run folder, and
  `bench executor` times that start-up apart from the episodes. A run takes them first.
- An actor runs one episode at a time, so an actor that dies names its episode without doubt
  (the pool has to retry suspects alone to know): that episode is retried once on a new actor,
  then recorded failed through ``on_lost`` with the pool's reason (:func:`.pool.lost_reason`;
  Ray's own out-of-memory killer is said as such).
- The address is tried (a TCP connection to the head) before Ray is asked: ``ray.init`` on an
  address nobody answers retries for minutes. An unreachable one is a :class:`ConfigError`,
  one line before anything runs. Without an address a local instance is started, small
  (``object_store_memory``, no dashboard), with ``num_cpus`` CPUs when given.
- Workers import exobench from where the driver does: its folder goes first on their
  ``PYTHONPATH`` (``runtime_env``), after which the driver's own ``PYTHONPATH`` follows. On a
  cluster, exobench must be installed (or at the same path) on every node.
- A cluster lost mid-run (the head gone, every node gone) raises :class:`ClusterLostError`:
  the episodes finished are on disk already and ``--resume`` completes the rest on any
  executor; none of the unfinished ones is recorded as failed for it.
"""

from __future__ import annotations

import contextlib
import os
import socket
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from exobench.core.errors import ConfigError, ExobenchError

from .pool import LOST_REASON, Death, longest_first, lost_reason

CONNECT_TIMEOUT_S = 5.0
LOST_GRACE_S = 30.0  # how long a failing Ray call waits for the health check before it is called a lost cluster
LOCAL_OBJECT_STORE_BYTES = 200 * 2**20  # episodes return records and small figures, not frames
OOM_REASON = "the worker process running the episode was killed twice by Ray's memory monitor, likely out of memory"


class ClusterLostError(ExobenchError):
    """The Ray cluster went away during a run; the episodes finished before are kept."""


def _exobench_root() -> str:
    import exobench

    return str(Path(exobench.__file__).resolve().parent.parent)


def split_address(address: str) -> tuple[str, int]:
    """``host:port`` of a Ray address (``host:port`` or ``ray://host:port``); ConfigError otherwise."""
    allowed = "host:port of a Ray head (or ray://host:port)"
    rest = address.removeprefix("ray://")
    host, sep, port = rest.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ConfigError("--address", address, allowed)
    return host.strip("[]"), int(port)


def check_reachable(address: str, timeout_s: float = CONNECT_TIMEOUT_S) -> None:
    """ConfigError, at once, unless something answers at the address (before ``ray.init``,
    which retries an unreachable one for minutes)."""
    host, port = split_address(address)
    try:
        with socket.create_connection((host, port), timeout=timeout_s):
            pass
    except OSError as e:
        why = "timed out" if isinstance(e, socket.timeout) else (e.strerror or type(e).__name__)
        raise ConfigError("--address", address, f"a reachable Ray head (host:port or ray://host:port); {host}:{port}: {why}") from None


@dataclass
class RayExecutor:
    """Where and how a run's episodes go on Ray (see the module doc).

    ``jobs``: concurrent episodes (None: the cluster's CPUs over ``cpus``); ``cpus`` and
    ``gpus``: what each episode reserves (a GPU fraction lets a GPU node's episodes render
    with hardware EGL); ``num_cpus``: CPUs of a local instance (None: Ray's count).
    """

    address: str | None = None
    jobs: int | None = None
    cpus: float = 1.0
    gpus: float = 0.0
    num_cpus: int | None = None
    object_store_bytes: int = LOCAL_OBJECT_STORE_BYTES
    started: bool = field(default=False, init=False)
    _warm: list[Any] = field(default_factory=list, init=False, repr=False)  # actors started ahead of a run

    def __post_init__(self) -> None:
        if self.jobs is not None and self.jobs < 1:
            raise ConfigError("--jobs", self.jobs, "--jobs >= 1")
        if not self.cpus > 0:
            raise ConfigError("--episode-cpus", self.cpus, "a number of CPUs > 0")
        if not 0 <= self.gpus:
            raise ConfigError("--episode-gpus", self.gpus, "a GPU fraction >= 0 (0: none)")
        if self.address is not None:
            split_address(self.address)

    def describe(self) -> dict[str, Any]:
        """What run_config.json records of it (it does not bind a resume)."""
        return {"name": "ray", "address": self.address, "jobs": self.jobs, "episode_cpus": self.cpus, "episode_gpus": self.gpus}

    def connect(self) -> None:
        """Join the cluster at ``address`` (tried first) or start a local instance."""
        import ray

        if self.address is not None:
            check_reachable(self.address)
        if ray.is_initialized():  # a caller (a test module, a notebook) started it: use it
            return
        paths = [_exobench_root(), *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))]
        runtime_env = {"env_vars": {"PYTHONPATH": os.pathsep.join(dict.fromkeys(paths))}}
        kw: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False, "runtime_env": runtime_env}
        try:
            if self.address is not None:
                ray.init(address=self.address, **kw)
            else:
                ray.init(num_cpus=self.num_cpus, object_store_memory=self.object_store_bytes, **kw)
        except ConnectionError as e:
            raise ConfigError("--address", self.address, f"a Ray head that accepts this driver ({str(e)[:160]})") from None
        self.started = True

    def start_workers(self, n: int, modules: Sequence[str] = ()) -> list[Any]:
        """Start actors for the next :meth:`run` now (``n``, at most :meth:`concurrency`, counting
        those started before) and have each import ``modules``; returns, without waiting, the
        refs of their imports (``ray.get`` them to wait until the actors are ready)."""
        cls = _make_actor_class().options(num_cpus=self.cpus, num_gpus=self.gpus or None)
        for _ in range(min(n, self.concurrency()) - len(self._warm)):
            actor = cls.remote()
            self._warm.append((actor, actor.ready.remote(tuple(modules))))
        return [ref for _, ref in self._warm]

    def close(self) -> None:
        """Leave the cluster (a local instance this executor started ends with it)."""
        import ray

        _kill([actor for actor, _ in self._warm])
        self._warm = []
        if self.started:
            ray.shutdown()
            self.started = False

    def concurrency(self) -> int:
        import ray

        if self.jobs is not None:
            return self.jobs
        return max(1, int(ray.cluster_resources().get("CPU", 1) // self.cpus))

    def run(
        self,
        jobs: Sequence[Any],
        work: Callable[[Any], tuple],
        finish: Callable[..., None],
        on_lost: Callable[[Any, str], tuple],
    ) -> None:
        """``finish(*work(job))`` for every job on Ray actors (the contract of :func:`.pool.run_pool`)."""
        if not jobs:
            return
        warm, self._warm = [actor for actor, _ in self._warm], []
        run_actors(jobs, min(self.concurrency(), len(jobs)), work, finish, on_lost, cpus=self.cpus, gpus=self.gpus, actors=warm)


def plan_modules(plan: Any) -> tuple[str, ...]:
    """The modules a run's episodes import in a worker: the runner, the track's and every
    pipeline's (what :meth:`RayExecutor.start_workers` has the actors import ahead)."""
    pipes = [p.entry_point.partition(":")[0] for p in plan.pipelines]
    return tuple(dict.fromkeys(["exobench.benchmarks.runner", type(plan.track).__module__, *pipes]))


def _kill(actors: Sequence[Any]) -> None:
    import ray

    for actor in actors:
        with contextlib.suppress(Exception):  # the cluster is gone: nothing left to end
            ray.kill(actor, no_restart=True)


def _make_actor_class() -> Any:
    import ray

    class EpisodeWorker:
        def __init__(self) -> None:
            from exobench.envs import gl_platform

            gl_platform.install()

        def ready(self, modules: tuple[str, ...]) -> int:
            import importlib

            for name in modules:
                importlib.import_module(name)
            return os.getpid()

        def run(self, work: Callable[[Any], tuple], job: Any) -> tuple:
            return work(job)

    return ray.remote(max_restarts=0, max_task_retries=0)(EpisodeWorker)


def run_actors(
    jobs: Sequence[Any],
    workers: int,
    work: Callable[[Any], tuple],
    finish: Callable[..., None],
    on_lost: Callable[[Any, str], tuple],
    *,
    cpus: float = 1.0,
    gpus: float = 0.0,
    wait_s: float = 0.5,
    health_every_s: float = 5.0,
    actors: Sequence[Any] = (),
) -> None:
    """Run ``jobs`` on ``workers`` actors of an initialised Ray (see the module doc): the
    ``actors`` already started first (those beyond ``workers`` are ended), new ones for the
    rest; results ready together are handed to ``finish`` in key order, as the pool does."""
    import ray
    from ray import exceptions as rx

    worker_cls = _make_actor_class().options(num_cpus=cpus, num_gpus=gpus or None)
    work_ref = ray.put(work)
    # popped from the end: submitted in the run's order, longest first with more than one actor (as the pool)
    todo = list(reversed(longest_first(jobs) if workers > 1 else list(jobs)))
    _kill(actors[workers:])
    idle = [*actors[:workers], *(worker_cls.remote() for _ in range(workers - len(actors[:workers])))]
    running: dict[Any, tuple[Any, Any, int]] = {}  # ref -> (actor, job, deaths so far)
    retry: list[tuple[Any, int]] = []

    def submit(job: Any, deaths: int) -> None:
        actor = idle.pop() if idle else worker_cls.remote()
        running[actor.run.remote(work_ref, job)] = (actor, job, deaths)

    checked = time.monotonic()
    try:
        while todo or retry or running:
            while idle and (retry or todo):
                job, deaths = retry.pop(0) if retry else (todo.pop(), 0)
                submit(job, deaths)
            ready, _ = ray.wait(list(running), num_returns=1, timeout=wait_s)
            if not ready:
                # with every node gone, nothing ever finishes and a new actor is never placed
                if time.monotonic() - checked > health_every_s:
                    checked = time.monotonic()
                    if not _cluster_alive():
                        raise ClusterLostError(_lost_text(RuntimeError("no node of the cluster is alive")))
                continue
            ready, _ = ray.wait(list(running), num_returns=len(running), timeout=0)
            results, lost = [], None
            for ref in ready:
                actor, job, deaths = running.pop(ref)
                try:
                    results.append(ray.get(ref))
                    idle.append(actor)
                except (rx.ActorDiedError, rx.ActorUnavailableError, rx.WorkerCrashedError, rx.OutOfMemoryError) as e:
                    with contextlib.suppress(Exception):  # with the node gone, killing it raises too
                        ray.kill(actor, no_restart=True)
                    if not _cluster_alive():
                        lost = ClusterLostError(_lost_text(e))
                        continue
                    idle.append(worker_cls.remote())  # a fresh process in its place
                    if deaths == 0:
                        retry.append((job, 1))
                    else:
                        results.append(on_lost(job, _death_reason(e)))
                except rx.RayTaskError as e:  # a bug of the harness itself: let it show
                    raise e.as_instanceof_cause() from None
                except (rx.RaySystemError, rx.GetTimeoutError, ConnectionError) as e:
                    lost = ClusterLostError(_lost_text(e))
            for result in sorted(results, key=lambda r: r[0]):  # what finished is kept, even now
                finish(*result)
            if lost is not None:
                raise lost
    except ClusterLostError:
        raise
    except Exception as e:
        # a Ray call (wait, get, remote, a new actor) that fails as the node goes, with whatever
        # error Ray's client gives then: the cluster is lost once Ray's health check says so; a
        # task's own error (RayTaskError) is the harness's, raised as it is
        if isinstance(e, rx.RayTaskError) or not _cluster_gone_within(LOST_GRACE_S):
            raise
        raise ClusterLostError(_lost_text(e)) from None
    finally:
        _kill([a for a, _, _ in running.values()] + idle)


def _death_reason(err: Exception) -> str:
    from ray import exceptions as rx

    if isinstance(err, rx.OutOfMemoryError):
        return OOM_REASON
    text = str(err)
    if "SIGKILL" in text or "killed" in text.lower():
        return lost_reason(Death(-9, None))
    return LOST_REASON


def _cluster_alive() -> bool:
    """Whether any node of the cluster still answers (an actor's death alone is an episode's)."""
    import ray

    try:
        return any(n.get("Alive") for n in ray.nodes())
    except Exception:
        return False


def _cluster_gone_within(grace_s: float) -> bool:
    """Whether no node answers within ``grace_s`` (Ray's health check takes a few periods to
    declare a killed node dead: 15 s with its defaults)."""
    deadline = time.monotonic() + grace_s
    while _cluster_alive():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.5)
    return True


def _lost_text(err: Exception) -> str:
    first = str(err).strip().splitlines()[0][:160] if str(err).strip() else type(err).__name__
    return f"the Ray cluster was lost ({first})"


def executor_from_options(executor: str, address: str | None, jobs: int | None, cpus: float | None, gpus: float | None) -> RayExecutor | None:
    """The Ray executor of `run`'s options (None for the local one, which takes none of them)."""
    if executor != "ray":
        for option, value in (("--address", address), ("--episode-cpus", cpus), ("--episode-gpus", gpus)):
            if value is not None:
                raise ConfigError(option, value, f"{option} with --executor ray")
        return None
    try:
        import ray  # noqa: F401
    except ImportError:
        raise ConfigError("--executor", "ray", "ray installed: pip install 'exobench[ray]'") from None
    return RayExecutor(address=address, jobs=jobs, cpus=1.0 if cpus is None else cpus, gpus=0.0 if gpus is None else gpus)


@contextlib.contextmanager
def connected(ray_ex: RayExecutor | None, plan: Any = None) -> Iterator[None]:
    """Connected to Ray for the block (an unreachable address is refused here, before any
    folder is made), and disconnected after it, however it ends. With ``plan``, the actors of
    its episodes are started at once (:meth:`RayExecutor.start_workers`), without waiting."""
    if ray_ex is None:
        yield
        return
    ray_ex.connect()
    try:
        if plan is not None:
            ray_ex.start_workers(len(plan.episodes), plan_modules(plan))
        yield
    finally:
        ray_ex.close()
