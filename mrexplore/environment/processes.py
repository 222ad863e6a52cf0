"""The batched env stepped in worker processes: every core, each with its own GIL.

>>> import numpy as np, mrexplore
>>> venv = mrexplore.vector_env(num_envs=3, world="small_office", max_cycles=4, num_workers=2)
>>> obs, infos = venv.reset(seed=0)
>>> obs.shape, venv.worker_sizes
((3, 2, 8, 64, 64), [2, 1])
>>> obs, rewards, terms, truncs, infos = venv.step(np.zeros((3, 2), dtype=np.int64))
>>> venv.close()

:class:`ProcessBatchedEnv` is :class:`~mrexplore.environment.batched.BatchedExploreEnv`'s API
(the engine's ``reset_copies`` / ``step_copies`` and the array API on top, so
:class:`~mrexplore.wrappers.sb3_vec.BatchedVecEnv` takes it as it is) over ``num_workers``
processes. Worker w holds a contiguous block of the worlds (block sizes differ by at most one)
as a one-thread :class:`BatchedExploreEnv` with its own merge worker, and steps it when told;
the observations come back through one shared-memory array, the rest (rewards, flags, infos,
finished episodes' last observations) through a pipe.

Why processes: threads over whole worlds (the batched env's ``num_threads``) are bounded by
the GIL, since ~30 % of a world-step is Python; measured on a quiet 2-core machine they gave
1.04-1.07x the robot-steps per wall second of the worlds stepped alone (``docs/speed.md``).
A process per core has its own interpreter, so the Python of two blocks runs at once.

The run is the same as one :class:`BatchedExploreEnv` of the N worlds (and so as N separate
envs): world k is world k of the batch whichever worker steps it, reset with ``seed + k``, with
its own random stream; ``tests/environment/test_processes.py`` holds them bit for bit over
auto-resets and merges. What a process cannot do: :meth:`map_worlds` (a function of the
parent's objects) and ``envs`` (the worlds live in the workers); a ``merger`` object must be
picklable. Workers start with the ``spawn`` method (no fork of a process with threads).
"""

from __future__ import annotations

import contextlib
import multiprocessing
import pickle
import time
import traceback
from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection
from multiprocessing.shared_memory import SharedMemory
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mrexplore.environment.batched import (
    BatchedExploreEnv,
    BatchStep,
    _seeds,
    check_batch_options,
    check_num_envs,
    check_num_threads,
)
from mrexplore.environment.parallel_env import MultiRobotExplorationEnv
from mrexplore.errors import ConfigError, MrexploreError

__all__ = ["ProcessBatchedEnv", "check_num_workers"]


def check_num_workers(num_workers: Any, num_envs: int) -> int:
    """``num_workers`` (None: the usable cores) capped at ``num_envs``, else a
    :class:`ConfigError` naming the option."""
    return check_num_threads(num_workers, num_envs, "num_workers")


#: What talking to a worker that has exited raises.
_GONE = (EOFError, ConnectionResetError, BrokenPipeError)


def _died(p: Any, cmd: str) -> MrexploreError:
    """The error for worker ``p`` gone while answering ``cmd``; one that dies while starting
    most often ran the parent's unguarded script again (the ``spawn`` start method)."""
    p.join(timeout=5.0)
    msg = f"a worker process died (exit code {p.exitcode})"
    if cmd == "make":
        msg += (
            " while starting. Workers start with multiprocessing's 'spawn' method, which imports "
            "the main module again: a script that makes vector_env(num_workers=...) must make it "
            'under `if __name__ == "__main__":`. The worker\'s own error is printed above.'
        )
    return MrexploreError(msg)


def _blocks(n: int, k: int) -> list[tuple[int, int]]:
    """``k`` contiguous blocks ``(start, size)`` of ``n`` worlds, sizes differing by at most 1
    (the larger first)."""
    base, extra = divmod(n, k)
    out, start = [], 0
    for w in range(k):
        size = base + (1 if w < extra else 0)
        out.append((start, size))
        start += size
    return out


def _worker(
    conn: Connection,
    start: int,
    size: int,
    shm_name: str,
    shape: tuple[int, ...],
    dtype: str,
    render_mode: str | None,
    env_options: dict[str, Any],
) -> None:
    """A worker process: worlds ``start .. start + size - 1`` as a one-thread batched env,
    stepped on the parent's commands; observations written into its rows of the shared array."""
    shm = SharedMemory(name=shm_name)
    obs: NDArray[Any] | None = None
    try:
        obs = np.ndarray(shape, dtype=np.dtype(dtype), buffer=shm.buf)[start : start + size]
        batch: BatchedExploreEnv | None = None
        while True:
            cmd, arg = conn.recv()
            if cmd == "close":
                break
            try:
                if cmd == "make":
                    batch = BatchedExploreEnv(
                        size, render_mode=render_mode, num_threads=1, **env_options
                    )
                    out: Any = None
                elif batch is None:
                    raise RuntimeError(f"worker: {cmd!r} before the worlds were made")
                elif cmd == "reset":
                    seeds, options = arg
                    o, infos = batch.reset_copies(seeds, options)
                    obs[:] = o
                    out = infos
                elif cmd == "step":
                    b = batch.step_copies(arg)
                    obs[:] = b.obs
                    final = {start + k: v for k, v in b.final.items()}
                    out = (b.rewards, b.terminations, b.truncations, b.infos, final)
                elif cmd == "render":
                    out = batch.render()
                elif cmd == "cpu":
                    for env in batch.envs:  # the merge attempts started so far, finished
                        if env.fusion.tracker is not None:
                            env.fusion.tracker.wait_idle()
                    out = time.process_time()
                elif cmd == "world":
                    local, what, data = arg
                    out = _world_command(batch.envs[local], what, data)
                else:
                    raise RuntimeError(f"worker: unknown command {cmd!r}")
                conn.send(("ok", out))
            except BaseException as exc:  # sent to the parent, which raises it
                tb = traceback.format_exc()
                try:
                    conn.send(("error", (exc, tb)))
                except Exception:  # the exception does not pickle: its text does
                    conn.send(("error", (RuntimeError(f"{type(exc).__name__}: {exc}"), tb)))
        if batch is not None:
            batch.close()
    finally:
        obs = None  # the view must go before the shared memory it looks at
        shm.close()
        conn.close()


def _world_command(env: MultiRobotExplorationEnv, what: str, data: Any) -> Any:
    """An SB3 ``VecEnv`` query of one world (``get_attr``, ``set_attr``, ``env_method``,
    ``is_wrapped``, ``render``), answered as the in-process copies answer it."""
    from mrexplore.wrappers._vec_runner import CopyRunner, answer

    if what == "reset":  # the batch resets its worlds itself
        raise RuntimeError("worker: a world is reset by the batch, not alone")
    return answer(CopyRunner(env), what, data)


class _WorldHandle:
    """World k of a :class:`ProcessBatchedEnv` as an SB3 ``VecEnv`` copy handle (``call``)."""

    def __init__(self, owner: ProcessBatchedEnv, k: int) -> None:
        self.owner, self.k = owner, k

    def call(self, what: str, data: Any = None) -> Any:
        return self.owner.call_world(self.k, what, data)


class ProcessBatchedEnv(BatchedExploreEnv):
    """``num_envs`` worlds stepped in ``num_workers`` processes; see the module docstring.

    Args:
        num_envs: N >= 1 worlds.
        render_mode: passed to every world (``"rgb_array"``: :meth:`render` gives N frames).
        num_workers: worker processes (None: the usable cores; capped at N).
        **env_options: :class:`~mrexplore.environment.EnvConfig` options of every world;
            ``num_threads`` is not one (each worker steps its block on one thread).

    Attributes:
        num_workers: the worker processes.
        worker_sizes: the worlds each worker steps, in world order.
        possible_agents: the robots of one world (and ``n_robots``, the spaces: as
            :class:`BatchedExploreEnv`'s).

    Raises:
        ConfigError: a bad ``num_envs``, ``num_workers`` or env option (checked in this
            process, before any worker starts).
    """

    def __init__(
        self,
        num_envs: int,
        render_mode: str | None = None,
        num_workers: int | None = None,
        **env_options: Any,
    ) -> None:
        self.num_envs = check_num_envs(num_envs)
        self.num_workers = check_num_workers(num_workers, self.num_envs)
        if "num_threads" in env_options:
            raise ConfigError(
                "vector_env: num_threads and num_workers exclude each other (each worker "
                "process steps its worlds on one thread)"
            )
        check_batch_options(render_mode, env_options)
        self.render_mode = render_mode
        self.num_threads = 1
        self.closed = True  # until the workers run: close() has nothing to stop
        self._running = False
        try:  # the options travel to the workers
            pickle.dumps(env_options)
        except Exception as exc:
            raise ConfigError(
                f"vector_env: with num_workers every env option must pickle (a merger object "
                f"too), and one does not: {exc}"
            ) from exc
        # one world here checks every option at the door and gives the spaces
        probe = MultiRobotExplorationEnv(**env_options)
        try:
            self._spaces_from(probe)
        finally:
            probe.close()
        shape = (self.num_envs, self.n_robots, *self._obs_shape)
        nbytes = int(np.prod(shape)) * np.dtype(self._obs_dtype).itemsize
        self._shm: SharedMemory | None = SharedMemory(create=True, size=max(1, nbytes))
        self._obs = np.ndarray(shape, dtype=self._obs_dtype, buffer=self._shm.buf)
        self._blocks = _blocks(self.num_envs, self.num_workers)
        self.worker_sizes = [size for _, size in self._blocks]
        ctx = multiprocessing.get_context("spawn")
        self._conns: list[Connection] = []
        self._procs: list[Any] = []
        self.closed = False
        try:
            for start, size in self._blocks:
                parent, child = ctx.Pipe()
                p = ctx.Process(
                    target=_worker,
                    args=(
                        child,
                        start,
                        size,
                        self._shm.name,
                        shape,
                        np.dtype(self._obs_dtype).str,
                        render_mode,
                        env_options,
                    ),
                    daemon=True,
                )
                p.start()
                child.close()
                self._conns.append(parent)
                self._procs.append(p)
            self._all("make", [None] * self.num_workers)
        except BaseException:
            self.close()
            raise

    @property
    def envs(self) -> list[MultiRobotExplorationEnv]:  # type: ignore[override]
        """Not here: the worlds live in the worker processes."""
        raise AttributeError(
            "ProcessBatchedEnv.envs: the worlds live in the worker processes (use "
            "num_threads instead of num_workers to inspect them)"
        )

    def _all(self, cmd: str, args: Sequence[Any]) -> list[Any]:
        """Send ``(cmd, args[w])`` to every worker, then collect their answers in order;
        re-raise the first worker's error (with its traceback's text)."""
        if self.closed:
            raise RuntimeError("ProcessBatchedEnv is closed")
        sent = []
        for conn, arg in zip(self._conns, args, strict=True):
            try:
                conn.send((cmd, arg))
                sent.append(True)
            except _GONE:
                sent.append(False)
        answers = []
        error: tuple[BaseException, str] | None = None
        for conn, p, ok in zip(self._conns, self._procs, sent, strict=True):
            try:
                status, out = conn.recv() if ok else ("error", (_died(p, cmd), ""))
            except _GONE:
                status, out = "error", (_died(p, cmd), "")
            if status == "error" and error is None:
                error = out
            answers.append(out)
        if error is not None:
            exc, tb = error
            if isinstance(exc, (MrexploreError, ValueError, RuntimeError)):
                raise exc
            raise MrexploreError(f"a worker process failed:\n{tb}") from exc
        return answers

    def reset_copies(
        self,
        seed: int | Sequence[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[NDArray[Any], list[list[dict[str, Any]]]]:
        """Reset every world (world k with ``seed + k``); observations (N, R, ...) and the
        infos per world and robot."""
        if options and "reset_mask" in options:
            raise ConfigError(
                "reset: options['reset_mask'] is not supported (same-step auto-reset: every "
                "world is reset by the step that ends it)"
            )
        seeds = _seeds(seed, self.num_envs)
        parts = self._all("reset", [(seeds[s : s + n], options) for s, n in self._blocks])
        self._running = True
        return self._obs.copy(), [row for part in parts for row in part]

    def step_copies(self, actions: NDArray[Any] | Sequence[Any]) -> BatchStep:
        """Step every world with its row of ``actions`` (int (N, R)); as
        :meth:`BatchedExploreEnv.step_copies` (checked here, so a bad action steps no world)."""
        if not self._running:
            raise RuntimeError("step() called before reset()")
        act = self._checked_actions(actions)
        parts = self._all("step", [act[s : s + n] for s, n in self._blocks])
        rewards = np.concatenate([p[0] for p in parts])
        terms = np.concatenate([p[1] for p in parts])
        truncs = np.concatenate([p[2] for p in parts])
        infos = [row for p in parts for row in p[3]]
        final: dict[int, tuple[NDArray[Any], list[dict[str, Any]]]] = {}
        for p in parts:
            final.update(p[4])
        return BatchStep(
            self._obs.copy(), rewards, terms, truncs, infos, dict(sorted(final.items()))
        )

    def map_worlds(self, fn: Callable[[int, MultiRobotExplorationEnv], Any]) -> list[Any]:
        """Not in worker processes: ``fn`` is a function of this process's objects."""
        raise ConfigError(
            "ProcessBatchedEnv.map_worlds: the worlds live in the worker processes; use "
            "num_threads instead of num_workers to run per-world work beside the steps"
        )

    def render(self) -> tuple[Any, ...] | None:
        """One frame per world (``render_mode="rgb_array"``), else None."""
        if self.render_mode is None:
            return None
        return tuple(f for part in self._all("render", [None] * self.num_workers) for f in part)

    def call_world(self, k: int, what: str, data: Any = None) -> Any:
        """An SB3 ``VecEnv`` query (``get_attr``, ``set_attr``, ``env_method``, ``is_wrapped``,
        ``render``) of world k, answered in its worker."""
        if self.closed:
            raise RuntimeError("ProcessBatchedEnv is closed")
        w = next(i for i, (s, n) in enumerate(self._blocks) if s <= k < s + n)
        self._conns[w].send(("world", (k - self._blocks[w][0], what, data)))
        status, out = self._conns[w].recv()
        if status == "error":
            raise out[0]
        return out

    def world_handles(self) -> list[_WorldHandle]:
        """One handle per world for :class:`~mrexplore.wrappers.sb3_vec.BatchedVecEnv`."""
        return [_WorldHandle(self, k) for k in range(self.num_envs)]

    def worker_cpu_s(self) -> float:
        """The CPU seconds the worker processes have used so far, summed, once the merge
        attempts they started have finished (for benchmarks; nothing is applied early)."""
        return float(sum(self._all("cpu", [None] * self.num_workers)))

    def close(self) -> None:
        """Stop the workers (each closes its worlds) and free the shared observations."""
        if getattr(self, "closed", True) and not getattr(self, "_procs", None):
            return
        for conn in getattr(self, "_conns", []):
            with contextlib.suppress(OSError):  # a worker that died took its pipe with it
                conn.send(("close", None))
        for p in getattr(self, "_procs", []):
            p.join(timeout=30)
            if p.is_alive():
                p.terminate()
                p.join()
        for conn in getattr(self, "_conns", []):
            conn.close()
        self._conns, self._procs = [], []
        shm = getattr(self, "_shm", None)
        if shm is not None:
            self._obs = np.empty(0)
            shm.close()
            shm.unlink()
            self._shm = None
        self.closed = True
