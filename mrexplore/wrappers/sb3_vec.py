"""A PettingZoo ``ParallelEnv`` as a stable-baselines3 ``VecEnv``: one slot per robot, one policy.

Parameter sharing: every robot of every env copy is one slot of the ``VecEnv``, so
``num_envs = n_copies * n_robots`` and all robots are trained by (and act from) one policy.
Slot ``k * n_robots + j`` is robot ``possible_agents[j]`` of copy ``k``.

>>> from mrexplore.wrappers import make_vec_env
>>> venv = make_vec_env(n_copies=1, seed=0, world="small_office", n_robots=2, max_cycles=3)
>>> venv.num_envs, venv.reset().shape
(2, (2, 8, 64, 64))
>>> venv.close()

SB3's ``VecEnv`` contract, as implemented here:

* ``reset()`` returns the stacked first observations; seeds set by :meth:`seed` and options set
  by ``set_options`` are used by that reset only (SB3 >= 2 semantics): copy ``k`` gets
  ``seed + k``.
* ``step_async(actions)`` / ``step_wait()``: ``actions`` has one entry per slot. When an env
  copy's episode ends, its finishing slots get ``done=True`` with ``infos[i]
  ["terminal_observation"]`` and ``infos[i]["TimeLimit.truncated"]`` (a time-limit end that is
  not a true end), and the copy is reset at once: the returned observation is the new
  episode's first one and ``reset_infos`` holds its infos (auto-reset). Per-agent ends (agents
  leaving early) are handled too, see :mod:`mrexplore.wrappers._vec_runner`.
* Rewards are float32, dones bool; ``VecMonitor`` on top gives per-robot episode statistics.
* ``get_attr`` / ``set_attr`` / ``env_method`` / ``env_is_wrapped`` take *slot* indices and act
  on the env copy that holds each slot (a value per slot; a copy is set/called once).
* ``get_images()`` returns one frame per env copy (the robots of a copy share a frame).
* ``use_subprocess=True`` runs each copy in its own process (a worker loop over a
  ``multiprocessing.Pipe``, like SB3's ``SubprocVecEnv``; the factories are cloudpickled).

Why not SuperSuit: it is the usual PettingZoo -> SB3 bridge and it works with our env (3.11,
``num_cpus`` 0 and 2 tried here; ``docs/guide/training.md`` has a tested recipe), but it calls
itself semi-maintained, its SB3 wrapper cannot be seeded the SB3 way (``seed()`` and
``reset(seed=)`` raise ``AttributeError``), and its tutorial's order (seed, then
``concat_vec_envs_v1``) gives every copy the same random stream. This adapter is small, has no
dependency beyond SB3, seeds copy ``k`` with ``seed + k``, and is tested against SB3's ``VecEnv``
contract here.

Bad input: agents with different observation or action spaces (one policy cannot serve them), or
copies whose spaces differ, raise :class:`~mrexplore.errors.ConfigError` at construction.
"""

from __future__ import annotations

import functools
import multiprocessing as mp
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import cloudpickle
import gymnasium
import numpy as np
from numpy.typing import NDArray
from stable_baselines3.common.vec_env.base_vec_env import (
    VecEnv,
    VecEnvIndices,
    VecEnvObs,
    VecEnvStepReturn,
)

from mrexplore.errors import ConfigError
from mrexplore.wrappers._vec_runner import CopyRunner, answer, worker

EnvFn = Callable[[], Any]


def _stack(obs: Sequence[Any], space: gymnasium.spaces.Space[Any]) -> VecEnvObs:
    """Stack per-slot observations: an array (N, ...) or, for a Dict space, a dict of arrays."""
    if isinstance(space, gymnasium.spaces.Dict):
        return {k: np.stack([o[k] for o in obs]) for k in space.spaces}
    return np.stack(obs)


def _slot_actions(actions: NDArray[Any], num_envs: int) -> NDArray[Any]:
    """``actions`` as an array with one entry per slot, else a ``ValueError`` (SB3's contract)."""
    actions = np.asarray(actions)
    if len(actions) != num_envs:
        raise ValueError(f"expected {num_envs} actions (one per slot), got {len(actions)}")
    return actions


class _RemoteCopy:
    """The parent's handle of one env copy running in a worker process (same API as CopyRunner)."""

    def __init__(self, env_fn: EnvFn, ctx: Any) -> None:
        self.remote, work_remote = ctx.Pipe()
        # daemon: a crashed parent must not leave workers behind.
        self.process = ctx.Process(
            target=worker, args=(work_remote, self.remote, cloudpickle.dumps(env_fn)), daemon=True
        )
        self.process.start()
        work_remote.close()
        self.agents, self.observation_space, self.action_space = self._recv()
        self._pending = False

    def _recv(self) -> Any:
        status, value = self.remote.recv()
        if status == "error":
            raise value
        return value

    def call(self, cmd: str, data: Any = None) -> Any:
        self.remote.send((cmd, data))
        return self._recv()

    def send(self, cmd: str, data: Any = None) -> None:
        self.remote.send((cmd, data))
        self._pending = True

    def recv(self) -> Any:
        self._pending = False
        return self._recv()

    def close(self) -> None:
        try:
            if self._pending:
                self.remote.recv()
            self.remote.send(("close", None))
            self.remote.recv()
        except (EOFError, BrokenPipeError, OSError):
            pass
        self.process.join(timeout=10)
        if self.process.is_alive():  # pragma: no cover - a worker stuck in C code
            self.process.terminate()
        self.remote.close()


class ParallelEnvVecEnv(VecEnv):
    """SB3 ``VecEnv`` over copies of a PettingZoo ``ParallelEnv``, one slot per agent.

    Args:
        env_fns: one factory per env copy, each returning a fresh ``ParallelEnv`` (picklable by
            cloudpickle when ``use_subprocess``).
        start_method: multiprocessing start method for ``use_subprocess`` (default
            ``"forkserver"`` where available, else ``"spawn"``, as SB3's ``SubprocVecEnv``).
        use_subprocess: run each copy in its own process.

    Raises:
        ConfigError: no factory, agents or copies with different spaces.
    """

    def __init__(
        self,
        env_fns: list[EnvFn],
        start_method: str | None = None,
        use_subprocess: bool = False,
    ) -> None:
        if not env_fns:
            raise ConfigError("ParallelEnvVecEnv needs at least one env factory")
        self.use_subprocess = bool(use_subprocess)
        self.closed = False
        self.waiting = False
        self._copies: list[Any] = []
        if self.use_subprocess:
            if start_method is None:
                start_method = (
                    "forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn"
                )
            ctx = mp.get_context(start_method)
            try:
                for fn in env_fns:
                    self._copies.append(_RemoteCopy(fn, ctx))
            except BaseException:
                for c in self._copies:
                    c.close()
                raise
        else:
            self._copies = [CopyRunner(fn()) for fn in env_fns]
        first = self._copies[0]
        for k, c in enumerate(self._copies[1:], start=1):
            if (
                c.observation_space != first.observation_space
                or c.action_space != first.action_space
                or len(c.agents) != len(first.agents)
            ):
                raise ConfigError(
                    f"env copy {k} differs from copy 0 in its agents or spaces; every copy must "
                    "have the same number of agents and the same observation/action spaces"
                )
        self.n_copies = len(self._copies)
        self.agents_per_copy = len(first.agents)
        self.possible_agents: list[Any] = list(first.agents)
        self._actions: NDArray[Any] | None = None
        super().__init__(
            self.n_copies * self.agents_per_copy, first.observation_space, first.action_space
        )

    # ------------------------------------------------------------------ slots
    def slot(self, copy: int, agent_index: int) -> int:
        """The slot index of agent ``possible_agents[agent_index]`` of env copy ``copy``."""
        return copy * self.agents_per_copy + agent_index

    def _copies_of(self, indices: VecEnvIndices) -> list[int]:
        """Env copies holding the given slots, in order, each once."""
        out: list[int] = []
        for i in self._get_indices(indices):
            if not 0 <= int(i) < self.num_envs:
                raise IndexError(f"slot {i} out of range 0..{self.num_envs - 1}")
            k = int(i) // self.agents_per_copy
            if k not in out:
                out.append(k)
        return out

    def _per_slot(self, indices: VecEnvIndices, per_copy: dict[int, Any]) -> list[Any]:
        return [per_copy[int(i) // self.agents_per_copy] for i in self._get_indices(indices)]

    def _call(self, k: int, cmd: str, data: Any = None) -> Any:
        c = self._copies[k]
        if self.use_subprocess:
            return c.call(cmd, data)
        return answer(c, cmd, data)

    # ------------------------------------------------------------------ VecEnv API
    def reset(self) -> VecEnvObs:
        """Reset every copy (copy ``k`` with ``seed + k`` after :meth:`seed`); stacked obs."""
        obs: list[Any] = []
        reset_infos: list[dict[str, Any]] = []
        args = []
        for k in range(self.n_copies):
            first_slot = self.slot(k, 0)
            args.append((self._seeds[first_slot], self._options[first_slot] or None))
        if self.use_subprocess:
            for c, a in zip(self._copies, args, strict=True):
                c.send("reset", a)
            results = [c.recv() for c in self._copies]
        else:
            results = [c.reset(*a) for c, a in zip(self._copies, args, strict=True)]
        for o, inf in results:
            obs.extend(o)
            reset_infos.extend(inf)
        self.reset_infos = reset_infos
        # Seeds and options are used by one reset only (SB3 >= 2).
        self._reset_seeds()
        self._reset_options()
        return _stack(obs, self.observation_space)

    def step_async(self, actions: NDArray[Any]) -> None:
        """Remember (or, with subprocesses, send) one action per slot."""
        actions = _slot_actions(actions, self.num_envs)
        if self.use_subprocess:
            n = self.agents_per_copy
            for k, c in enumerate(self._copies):
                c.send("step", actions[k * n : (k + 1) * n])
        self._actions = actions
        self.waiting = True

    def step_wait(self) -> VecEnvStepReturn:
        """Step every copy; auto-reset copies whose episode ended (see the module docstring)."""
        if self._actions is None:
            raise RuntimeError("step_wait() called without step_async()")
        n = self.agents_per_copy
        if self.use_subprocess:
            results = [c.recv() for c in self._copies]
        else:
            results = [
                c.step(self._actions[k * n : (k + 1) * n]) for k, c in enumerate(self._copies)
            ]
        self.waiting = False
        self._actions = None
        obs: list[Any] = []
        rews: list[NDArray[np.float32]] = []
        dones: list[NDArray[np.bool_]] = []
        infos: list[dict[str, Any]] = []
        for k, (o, r, d, inf, rinf) in enumerate(results):
            obs.extend(o)
            rews.append(r)
            dones.append(d)
            infos.extend(inf)
            if rinf is not None:
                self.reset_infos[k * n : (k + 1) * n] = rinf
        return (
            _stack(obs, self.observation_space),
            np.concatenate(rews).astype(np.float32, copy=False),
            np.concatenate(dones),
            infos,
        )

    def seed(self, seed: int | None = None) -> Sequence[int | None]:
        """Seed the next reset: copy ``k`` gets ``seed + k``; returns the seed of every slot."""
        if seed is None:
            # Draw one so that the copies still get distinct seeds (SB3's behaviour).
            seed = int(np.random.default_rng().integers(0, np.iinfo(np.uint32).max))
        self._seeds = [int(seed) + i // self.agents_per_copy for i in range(self.num_envs)]
        return list(self._seeds)

    def close(self) -> None:
        """Close every copy (and stop the worker processes)."""
        if self.closed:
            return
        for c in self._copies:
            c.close()
        self.closed = True

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """``getattr(env, attr_name)`` of the copy holding each slot (one value per slot)."""
        per_copy = {k: self._call(k, "get_attr", attr_name) for k in self._copies_of(indices)}
        return self._per_slot(indices, per_copy)

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Set the attribute on each copy holding one of the slots (once per copy)."""
        for k in self._copies_of(indices):
            self._call(k, "set_attr", (attr_name, value))

    def env_method(
        self,
        method_name: str,
        *method_args: Any,
        indices: VecEnvIndices = None,
        **method_kwargs: Any,
    ) -> list[Any]:
        """Call a method once per copy holding the slots; the copy's result for each slot."""
        per_copy = {
            k: self._call(k, "env_method", (method_name, method_args, method_kwargs))
            for k in self._copies_of(indices)
        }
        return self._per_slot(indices, per_copy)

    def env_is_wrapped(
        self, wrapper_class: type[gymnasium.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        """Whether each slot's copy has ``wrapper_class`` in its chain of ``.env`` wrappers."""
        per_copy = {k: self._call(k, "is_wrapped", wrapper_class) for k in self._copies_of(indices)}
        return self._per_slot(indices, per_copy)

    def get_images(self) -> Sequence[np.ndarray | None]:
        """One frame per env copy (needs ``render_mode="rgb_array"``), else Nones."""
        if self.render_mode != "rgb_array":
            return [None for _ in range(self.n_copies)]
        return [self._call(k, "render") for k in range(self.n_copies)]

    def _get_indices(self, indices: VecEnvIndices) -> Iterable[int]:
        if indices is None:
            return range(self.num_envs)
        if isinstance(indices, (int, np.integer)):
            return [int(indices)]
        return [int(i) for i in indices]


class BatchedVecEnv(ParallelEnvVecEnv):
    """The batched env (:class:`~mrexplore.environment.batched.BatchedExploreEnv`) as an SB3
    ``VecEnv``, with the contract of :class:`ParallelEnvVecEnv` (slot ``k * R + j`` = robot j
    of world k, ``terminal_observation``, ``TimeLimit.truncated``, ``reset_infos``, seeds
    ``seed + k``), so a run through it is the same run as through ``ParallelEnvVecEnv`` over
    separate copies (a test checks it). What differs: the worlds are stepped by one engine
    in this process and their delayed merge attempts share one worker thread.

    Args:
        batch: the batched env (closed with this ``VecEnv``).
    """

    def __init__(self, batch: Any) -> None:
        self.batch = batch
        self.use_subprocess = False
        self.closed = False
        self.waiting = False
        # The copies as CopyRunners serve get_attr / set_attr / env_method / render; worlds in
        # worker processes answer there, through handles (as use_subprocess copies do).
        handles = getattr(batch, "world_handles", None)
        if handles is not None:
            self._copies = handles()
            self.use_subprocess = True
        else:
            self._copies = [CopyRunner(e) for e in batch.envs]
        self.n_copies = batch.num_envs
        self.agents_per_copy = batch.n_robots
        self.possible_agents = list(batch.possible_agents)
        self._actions = None
        VecEnv.__init__(
            self,
            self.n_copies * self.agents_per_copy,
            batch.single_observation_space,
            batch.single_action_space,
        )

    def reset(self) -> VecEnvObs:
        """Reset every world (world ``k`` with ``seed + k`` after :meth:`seed`); stacked obs."""
        n = self.agents_per_copy
        seeds = [self._seeds[self.slot(k, 0)] for k in range(self.n_copies)]
        options = [self._options[self.slot(k, 0)] or None for k in range(self.n_copies)]
        if any(o != options[0] for o in options):
            raise ConfigError("BatchedVecEnv: set_options must give every world the same options")
        obs, infos = self.batch.reset_copies(seeds, options[0])
        self.reset_infos = [dict(i) for row in infos for i in row]
        self._reset_seeds()
        self._reset_options()
        return obs.reshape(self.n_copies * n, *obs.shape[2:])

    def step_async(self, actions: NDArray[Any]) -> None:
        """Remember one action per slot."""
        actions = _slot_actions(actions, self.num_envs)
        self._actions = actions
        self.waiting = True

    def step_wait(self) -> VecEnvStepReturn:
        """Step every world at once; a world whose episode ended is reset in the same step."""
        if self._actions is None:
            raise RuntimeError("step_wait() called without step_async()")
        n = self.agents_per_copy
        b = self.batch.step_copies(self._actions.reshape(self.n_copies, n))
        self.waiting = False
        self._actions = None
        terms, truncs = b.terminations.reshape(-1), b.truncations.reshape(-1)
        infos: list[dict[str, Any]] = []
        for k, row in enumerate(b.infos):
            last = b.final.get(k)
            for j in range(n):
                slot = k * n + j
                info = dict(row[j] if last is None else last[1][j])
                # SB3's convention: a time-limit end that is not also a true end bootstraps.
                info["TimeLimit.truncated"] = bool(truncs[slot] and not terms[slot])
                if last is not None:
                    info["terminal_observation"] = last[0][j]
                infos.append(info)
            if last is not None:
                self.reset_infos[k * n : (k + 1) * n] = [dict(i) for i in row]
        return (
            b.obs.reshape(self.num_envs, *b.obs.shape[2:]),
            b.rewards.reshape(-1).astype(np.float32),
            terms | truncs,
            infos,
        )

    def close(self) -> None:
        """Close the batched env (its copies and its merge worker)."""
        if not self.closed:
            self.batch.close()
            self.closed = True


def make_vec_env(
    n_copies: int = 1,
    use_subprocess: bool = False,
    seed: int | None = None,
    start_method: str | None = None,
    batched: bool = False,
    **env_options: Any,
) -> ParallelEnvVecEnv:
    """``n_copies`` copies of :func:`mrexplore.parallel_env` as one SB3 ``VecEnv``.

    Args:
        n_copies: env copies (``num_envs = n_copies * n_robots``).
        use_subprocess: one process per copy.
        seed: seeds the first ``reset()`` (copy ``k`` gets ``seed + k``); None = random.
        start_method: multiprocessing start method (see :class:`ParallelEnvVecEnv`).
        batched: step the copies as one batched env (:class:`BatchedVecEnv` over
            :func:`mrexplore.vector_env`: one engine, one merge worker for all copies); not with
            ``use_subprocess``. The same slots, seeds and results as the default. With
            ``num_workers`` among the env options, the batched copies are stepped in that many
            worker processes (:class:`~mrexplore.environment.processes.ProcessBatchedEnv`).
        **env_options: options of :func:`mrexplore.parallel_env` (``world``, ``n_robots``, ...).
            ``render_mode`` is accepted too.

    Raises:
        ConfigError: ``n_copies < 1`` or a bad env option (raised before any process starts).
    """
    if not isinstance(n_copies, int) or isinstance(n_copies, bool) or n_copies < 1:
        raise ConfigError(f"n_copies must be an integer >= 1, got {n_copies!r}")
    import mrexplore

    render_mode = env_options.pop("render_mode", None)
    if batched:
        if use_subprocess:
            raise ConfigError(
                "make_vec_env: batched=True steps every copy in this process; it cannot be "
                "combined with use_subprocess=True"
            )
        from mrexplore.environment.batched import BatchedExploreEnv
        from mrexplore.environment.processes import ProcessBatchedEnv

        # num_workers: the copies stepped in worker processes, each with its own GIL
        engine = ProcessBatchedEnv if "num_workers" in env_options else BatchedExploreEnv
        bvenv = BatchedVecEnv(engine(n_copies, render_mode=render_mode, **env_options))
        if seed is not None:
            bvenv.seed(seed)
        return bvenv
    if use_subprocess:
        # Build one copy here first, so that a typo fails in this process with its clear
        # ConfigError, before any worker starts.
        mrexplore.parallel_env(render_mode=render_mode, **env_options).close()
    fn = functools.partial(mrexplore.parallel_env, render_mode=render_mode, **env_options)
    venv = ParallelEnvVecEnv(
        [fn] * n_copies, start_method=start_method, use_subprocess=use_subprocess
    )
    if seed is not None:
        venv.seed(seed)
    return venv
