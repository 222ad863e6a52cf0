"""N worlds stepped in one call: the batched env for training (:func:`mrexplore.vector_env`).

>>> import numpy as np, mrexplore
>>> venv = mrexplore.vector_env(num_envs=3, world="small_office", n_robots=2, max_cycles=4)
>>> obs, infos = venv.reset(seed=0)
>>> obs.shape, infos["coverage"].shape
((3, 2, 8, 64, 64), (3, 2))
>>> obs, rewards, terms, truncs, infos = venv.step(np.zeros((3, 2), dtype=np.int64))
>>> rewards.dtype.name, terms.shape
('float32', (3, 2))
>>> venv.close()

Two faces over the same engine, :class:`BatchedExploreEnv` (any team size, arrays with a robot
axis) and :class:`ExploreVectorEnv` (one robot: a real ``gymnasium.vector.VectorEnv``, what
:func:`mrexplore.vector_env` returns for ``n_robots=1``); teams reach stable-baselines3 through
:class:`mrexplore.wrappers.sb3_vec.BatchedVecEnv` (``make_vec_env(..., batched=True)``).

=====================  ========================================================================
copies                 ``num_envs`` low-level envs (:func:`mrexplore.parallel_env` options), each
                       its own world (``world="random:<generator>"`` draws a new one per reset)
seeding                ``reset(seed=s)``: copy k is reset with ``s + k`` (as ``make_vec_env`` and
                       Gymnasium's ``SyncVectorEnv``); ``seed=None`` continues each copy's stream
actions                int (N, R) (``ExploreVectorEnv``: (N,)), each in ``Discrete(4)``
observations           (N, R, C, H, W) uint8 by default; ``obs_layout``/``obs_dtype`` respected
                       (``hwc``: (N, R, H, W, C)); a fresh array every call
rewards                float32 (N, R) (the team reward on every robot of a copy;
                       ``ExploreVectorEnv``: float64 (N,), as Gymnasium's vector envs)
terminations, truncs   bool (N, R) (a copy's robots end together)
infos                  a dict of arrays, Gymnasium's vector style: each flat info key
                       (:data:`~mrexplore.environment.infos.INFO_KEYS`) -> (N, R) array (bool,
                       int64 or float64; ``extra`` -> object array); every key is present for
                       every copy, so :class:`BatchedExploreEnv` adds no ``_key`` masks
                       (:class:`ExploreVectorEnv` does, as Gymnasium's own vector envs)
auto-reset             ``gymnasium.vector.AutoresetMode.SAME_STEP`` (stable-baselines3's
                       convention): a copy whose episode ends is reset inside the same
                       ``step``; the returned observation and infos are the new episode's first;
                       the last ones are in ``infos["final_obs"]`` (object (N,), None for copies
                       that go on, else the (R, C, H, W) observation) and ``infos["final_info"]``
                       (the same dict of (N, R) arrays; rows of copies that go on are zeros),
                       with masks ``infos["_final_obs"]`` / ``infos["_final_info"]`` (bool (N,))
merge worker           one single-thread executor for all copies' delayed merge attempts
                       (``merge_latency_steps`` > 0): the attempts of every world queue on one
                       worker thread off the step path; the schedule (applied 8 steps after the
                       start) does not depend on the worker, so the run is the same as N separate
                       envs with their own workers (``tests/environment/test_batched.py``)
threads                ``num_threads`` (default: the cores this process may run on, at most N)
                       threads step the worlds: the calling thread and ``num_threads - 1`` pool
                       threads each take the next world not yet stepped until all are
                       (OpenCV runs on one thread: every env sets ``cv2.setNumThreads(1)``)
=====================  ========================================================================

Why threads, and why the same run at any thread count: every kernel of a world-step (lidar
cast, own-map update, observation blocks, map accuracy; :mod:`mrexplore.kernels`) is compiled
``nogil``, and they hold ~70 % of a world-step; the Python around them holds the GIL. With
several threads, one world's kernels run on one core while another world's Python runs on the
other, so the worlds are stepped in parallel without copying any state between processes. Each
world owns everything it steps (its own random stream, simulator, maps, tracker, observation
builder); a thread steps one whole world at a time and writes only that world's rows of the
batch; the shared merge worker's results are applied on a schedule of steps, never of time.
Which thread steps which world is left to chance, what it computes is not
(``tests/environment/test_batched.py`` holds 1 and 3 threads to N separate envs, bit for bit).
A ``merger`` object (not a name) is shared by the copies: with ``merge_latency_steps=0`` it is
called from several threads at once and must be safe for that (the built-in mergers are).
What was measured: ``docs/speed.md`` ("Worlds stepped on every core").
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any, ClassVar, TypeVar

import gymnasium
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numpy.typing import NDArray

from mrexplore.environment.parallel_env import MultiRobotExplorationEnv
from mrexplore.errors import ConfigError


def check_num_envs(num_envs: Any, owner: str = "vector_env") -> int:
    """``num_envs`` as an int >= 1, else a :class:`ConfigError` naming the option."""
    if (
        isinstance(num_envs, (bool, np.bool_))
        or not isinstance(num_envs, (int, np.integer))
        or num_envs < 1
    ):
        raise ConfigError(f"{owner}: num_envs must be an integer >= 1, got {num_envs!r}")
    return int(num_envs)


_T = TypeVar("_T")


def usable_cores() -> int:
    """The number of cores this process may run on (its CPU affinity where the OS tells it)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def check_num_threads(num_threads: Any, num_envs: int, name: str = "num_threads") -> int:
    """``num_threads`` (None: :func:`usable_cores`) capped at ``num_envs``, else a
    :class:`ConfigError` naming the option (``name``: also the worker processes' count)."""
    if num_threads is None:
        return max(1, min(usable_cores(), num_envs))
    if (
        isinstance(num_threads, (bool, np.bool_))
        or not isinstance(num_threads, (int, np.integer))
        or num_threads < 1
    ):
        raise ConfigError(
            f"vector_env: {name} must be None or an integer >= 1, got {num_threads!r}"
        )
    return min(int(num_threads), num_envs)


def check_batch_options(render_mode: str | None, env_options: dict[str, Any]) -> None:
    """Refuse what a batch of worlds cannot do (the goal-level env, a human window); drops a
    ``"low"`` ``action_mode`` from ``env_options``."""
    if env_options.get("action_mode", "low") != "low":
        raise ConfigError(
            "vector_env: action_mode must be 'low' (the goal-level env is not batched), "
            f"got {env_options['action_mode']!r}"
        )
    env_options.pop("action_mode", None)
    if render_mode not in (None, "rgb_array"):
        raise ConfigError(
            f"vector_env: render_mode must be None or 'rgb_array', got {render_mode!r}"
        )


def _seeds(seed: int | Sequence[int | None] | None, n: int) -> list[int | None]:
    """Per-copy seeds: ``seed + k`` for an int, a list as given (length n), or n Nones."""
    if seed is None:
        return [None] * n
    if isinstance(seed, (int, np.integer)) and not isinstance(seed, (bool, np.bool_)):
        return [int(seed) + k for k in range(n)]
    seeds = list(seed)  # type: ignore[arg-type]
    if len(seeds) != n:
        raise ConfigError(f"reset: seed must be an int, None or {n} seeds, got {len(seeds)}")
    return seeds


@dataclass
class BatchStep:
    """One step of all copies, before it is shaped for a client (the engine's result).

    Attributes:
        obs: (N, R, *obs_shape) the current observations (new episodes' first after a reset).
        rewards: float64 (N, R).
        terminations, truncations: bool (N, R) of the step (before any reset).
        infos: per copy, per robot, the env's info dicts (reset infos after a reset).
        final: copy index -> (its last observations (R, *obs_shape), its last infos per robot),
            for the copies that ended in this step and were reset.
    """

    obs: NDArray[Any]
    rewards: NDArray[np.float64]
    terminations: NDArray[np.bool_]
    truncations: NDArray[np.bool_]
    infos: list[list[dict[str, Any]]]
    final: dict[int, tuple[NDArray[Any], list[dict[str, Any]]]] = field(default_factory=dict)


def info_arrays(rows: list[list[dict[str, Any]]]) -> dict[str, NDArray[Any]]:
    """Per-copy, per-robot flat info dicts -> key -> (N, R) array (object dtype for values that
    are not bool, int or float, e.g. ``extra``)."""
    n, r = len(rows), len(rows[0])
    out: dict[str, NDArray[Any]] = {}
    for key, first in rows[0][0].items():
        vals = [inf[key] for row in rows for inf in row]
        # an info key keeps its type on every step and copy (docs/clients.md): the first decides
        if isinstance(first, (bool, int, float, np.number, np.bool_)):
            out[key] = np.asarray(vals).reshape(n, r)
        else:
            arr = np.empty(n * r, dtype=object)
            arr[:] = vals
            out[key] = arr.reshape(n, r)
    return out


class BatchedExploreEnv:
    """``num_envs`` copies of the low-level env stepped as one; see the module docstring.

    Args:
        num_envs: N >= 1 copies (worlds).
        render_mode: passed to every copy (``"rgb_array"``: :meth:`render` gives N frames).
        num_threads: threads that step the worlds (None: the usable cores; capped at N); the
            run is the same at any number (module docstring).
        **env_options: :class:`~mrexplore.environment.EnvConfig` options of every copy (the
            goal-level ``action_mode="goal"`` is not batched).

    Attributes:
        envs: the N copies (:class:`MultiRobotExplorationEnv`), for inspection.
        num_threads: the threads that step them (1: the calling thread alone).
        possible_agents: the robots of one copy, the R axis of every array.
        single_observation_space / single_action_space: one robot's spaces.
        observation_space: ``Box`` of shape (N, R, *obs_shape); action_space:
            ``MultiDiscrete`` (N, R).

    Raises:
        ConfigError: a bad ``num_envs``, ``num_threads`` or env option.
    """

    metadata: ClassVar[dict[str, Any]] = {
        "autoreset_mode": AutoresetMode.SAME_STEP,
        "render_modes": ["rgb_array"],
    }

    def __init__(
        self,
        num_envs: int,
        render_mode: str | None = None,
        num_threads: int | None = None,
        **env_options: Any,
    ) -> None:
        self.num_envs = check_num_envs(num_envs)
        self.num_threads = check_num_threads(num_threads, self.num_envs)
        check_batch_options(render_mode, env_options)
        self.render_mode = render_mode
        # One worker for every copy's delayed merge attempts (threads start on first submit).
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="mrexplore-merge")
        # The stepping threads besides the caller's (threads start on first submit).
        self._pool: ThreadPoolExecutor | None = None
        if self.num_threads > 1:
            self._pool = ThreadPoolExecutor(
                max_workers=self.num_threads - 1, thread_name_prefix="mrexplore-step"
            )
        self.envs: list[MultiRobotExplorationEnv] = []
        try:
            for _ in range(self.num_envs):
                self.envs.append(
                    MultiRobotExplorationEnv(
                        render_mode=render_mode, merge_executor=self._executor, **env_options
                    )
                )
        except BaseException:
            self._executor.shutdown(wait=False)
            if self._pool is not None:
                self._pool.shutdown(wait=False)
            raise
        self._spaces_from(self.envs[0])
        self._running = False
        self.closed = False

    def _spaces_from(self, first: MultiRobotExplorationEnv) -> None:
        """The robots and the spaces of the batch, from one of its worlds."""
        self.possible_agents = list(first.possible_agents)
        self.n_robots = len(self.possible_agents)
        self.single_observation_space = first.observation_space(self.possible_agents[0])
        self.single_action_space = first.action_space(self.possible_agents[0])
        self.observation_space = batch_space(
            batch_space(self.single_observation_space, self.n_robots), self.num_envs
        )
        self.action_space = gymnasium.spaces.MultiDiscrete(
            np.full((self.num_envs, self.n_robots), int(self.single_action_space.n))
        )
        self._obs_shape = tuple(self.single_observation_space.shape)
        self._obs_dtype = self.single_observation_space.dtype

    # ------------------------------------------------------------------ engine
    def reset_copies(
        self,
        seed: int | Sequence[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[NDArray[Any], list[list[dict[str, Any]]]]:
        """Reset every copy (copy k with ``seed + k``); observations (N, R, ...) and the infos
        per copy and robot (the env's dicts)."""
        if options and "reset_mask" in options:
            # Gymnasium's partial reset serves the next-step and disabled autoreset modes; here a
            # finished world is reset inside the step that ends it.
            raise ConfigError(
                "reset: options['reset_mask'] is not supported (same-step auto-reset: every "
                "world is reset by the step that ends it)"
            )
        seeds = _seeds(seed, self.num_envs)
        agents = self.possible_agents
        obs = np.empty((self.num_envs, self.n_robots, *self._obs_shape), dtype=self._obs_dtype)
        infos: list[list[dict[str, Any]]] = [[] for _ in range(self.num_envs)]

        def reset_world(k: int) -> None:
            o, inf = self.envs[k].reset(seed=seeds[k], options=options)
            for j, a in enumerate(agents):
                obs[k, j] = o[a]
            infos[k] = [inf[a] for a in agents]

        self._each_world(reset_world)
        self._running = True
        return obs, infos

    def step_copies(self, actions: NDArray[Any] | Sequence[Any]) -> BatchStep:
        """Step every copy with its row of ``actions`` (int (N, R)); reset the copies that end
        (same-step auto-reset) and keep their last observations and infos in ``final``."""
        if not self._running:
            raise RuntimeError("step() called before reset()")
        act = self._checked_actions(actions)
        agents = self.possible_agents
        n, r = self.num_envs, self.n_robots
        obs = np.empty((n, r, *self._obs_shape), dtype=self._obs_dtype)
        rewards = np.empty((n, r), dtype=np.float64)
        terms = np.empty((n, r), dtype=bool)
        truncs = np.empty((n, r), dtype=bool)
        infos: list[list[dict[str, Any]]] = [[] for _ in range(n)]
        ended: list[tuple[NDArray[Any], list[dict[str, Any]]] | None] = [None] * n
        rows = act.tolist()  # plain ints: the env's fast path for actions

        def step_world(k: int) -> None:
            # writes only row k of the batch: any thread may step any world
            env = self.envs[k]
            o, rew, term, trunc, inf = env.step(dict(zip(agents, rows[k], strict=True)))
            for j, a in enumerate(agents):
                obs[k, j] = o[a]
                rewards[k, j] = rew[a]
                terms[k, j] = term[a]
                truncs[k, j] = trunc[a]
            step_infos = [inf[a] for a in agents]
            if not env.agents:  # the copy's episode ended (all robots end together)
                ended[k] = (obs[k].copy(), step_infos)
                o, inf = env.reset()  # None: the copy's own stream goes on
                for j, a in enumerate(agents):
                    obs[k, j] = o[a]
                step_infos = [inf[a] for a in agents]
            infos[k] = step_infos

        self._each_world(step_world)
        # in world order, whichever thread finished first
        final = {k: e for k, e in enumerate(ended) if e is not None}
        return BatchStep(obs, rewards, terms, truncs, infos, final)

    def _checked_actions(self, actions: NDArray[Any] | Sequence[Any]) -> NDArray[Any]:
        """``actions`` as an int (N, R) array in the action space, else a ``ValueError``;
        checked before any world steps, so that a bad action steps no world at all."""
        act = np.asarray(actions)
        if act.shape != (self.num_envs, self.n_robots):
            raise ValueError(
                f"actions must have shape ({self.num_envs}, {self.n_robots}) (copies, robots), "
                f"got {act.shape}"
            )
        n_act = int(self.single_action_space.n)
        if act.dtype.kind not in "iu" or ((act < 0) | (act >= n_act)).any():
            raise ValueError(
                f"actions must be integers in [0, {n_act}) (the action space "
                f"{self.single_action_space}), got {act.dtype} values "
                f"{np.unique(act)[:8].tolist()}"
            )
        return act

    def map_worlds(self, fn: Callable[[int, MultiRobotExplorationEnv], _T]) -> list[_T]:
        """``[fn(k, envs[k]) for every world k]``, computed on the stepping threads.

        For per-world work between steps, e.g. a team policy's decisions on world k's robot
        views (``team_k.act({a: env.robot_view(a) for a in env.agents})``): the worlds'
        decisions then run on every core as their steps do. ``fn`` must touch only world k's
        objects (its env, its policy); the results are in world order whichever thread
        computed them.

        >>> import mrexplore
        >>> venv = mrexplore.vector_env(num_envs=2, world="small_office", max_cycles=4)
        >>> _ = venv.reset(seed=0)
        >>> venv.map_worlds(lambda k, env: (k, env.agents))
        [(0, ['robot_0', 'robot_1']), (1, ['robot_0', 'robot_1'])]
        >>> venv.close()
        """
        out: list[Any] = [None] * self.num_envs

        def one(k: int) -> None:
            out[k] = fn(k, self.envs[k])

        self._each_world(one)
        return out

    def _each_world(self, fn: Callable[[int], None]) -> None:
        """``fn(k)`` for every world k, on :attr:`num_threads` threads: each thread takes the next
        world not yet taken (worlds differ in cost: resets, merges); returns when all are done
        and re-raises the first error of a world, in world order."""
        n = self.num_envs
        if self._pool is None:
            for k in range(n):
                fn(k)
            return
        ticket = itertools.count()  # next() on it is atomic under the GIL
        errors: list[tuple[int, BaseException]] = []

        def take() -> None:
            while (k := next(ticket)) < n:
                try:
                    fn(k)
                except BaseException as exc:  # re-raised below, in world order
                    errors.append((k, exc))

        futures: list[Future[None]] = [self._pool.submit(take) for _ in range(self.num_threads - 1)]
        take()  # the calling thread steps worlds too
        for f in futures:
            f.result()
        if errors:
            raise min(errors, key=lambda e: e[0])[1]

    # ------------------------------------------------------------------ array API
    def reset(
        self,
        *,
        seed: int | Sequence[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[NDArray[Any], dict[str, Any]]:
        """Reset every copy; ``(obs (N, R, ...), infos {key: (N, R)})``."""
        obs, infos = self.reset_copies(seed, options)
        return obs, dict(info_arrays(infos))

    def step(
        self, actions: NDArray[Any] | Sequence[Any]
    ) -> tuple[
        NDArray[Any], NDArray[np.float32], NDArray[np.bool_], NDArray[np.bool_], dict[str, Any]
    ]:
        """One step of every copy: ``(obs, rewards, terminations, truncations, infos)`` as in the
        module docstring's table (same-step auto-reset)."""
        b = self.step_copies(actions)
        infos: dict[str, Any] = dict(info_arrays(b.infos))
        if b.final:
            done = np.zeros(self.num_envs, dtype=bool)
            done[list(b.final)] = True
            final_obs = np.full(self.num_envs, None, dtype=object)
            for k, (o, _) in b.final.items():
                final_obs[k] = o
            zero = [{key: _zero_like(v) for key, v in b.infos[0][0].items()}] * self.n_robots
            rows = [b.final[k][1] if k in b.final else zero for k in range(self.num_envs)]
            infos["final_obs"] = final_obs
            infos["_final_obs"] = done
            infos["final_info"] = info_arrays(rows)
            infos["_final_info"] = done.copy()
        return b.obs, b.rewards.astype(np.float32), b.terminations, b.truncations, infos

    def render(self) -> tuple[Any, ...] | None:
        """One frame per copy (``render_mode="rgb_array"``), else None."""
        if self.render_mode is None:
            return None
        return tuple(env.render() for env in self.envs)

    def close(self) -> None:
        """Close every copy and stop the merge worker (an attempt under way finishes first)."""
        if self.closed:
            return
        for env in self.envs:
            env.close()
        self._executor.shutdown(wait=True, cancel_futures=True)
        if self._pool is not None:
            self._pool.shutdown(wait=True)
        self.closed = True


def _zero_like(v: Any) -> Any:
    """The zero of an info value's type (the rows of ``final_info`` for copies that go on)."""
    if isinstance(v, (bool, np.bool_)):
        return False
    if isinstance(v, (int, np.integer)):
        return 0
    if isinstance(v, (float, np.floating)):
        return 0.0
    return None


class ExploreVectorEnv(VectorEnv[NDArray[Any], NDArray[np.int64], NDArray[Any]]):
    """One robot in ``num_envs`` worlds as a ``gymnasium.vector.VectorEnv``.

    What :func:`mrexplore.vector_env` returns for ``n_robots=1``: observations (N, C, H, W),
    rewards float64 (N,), terminations/truncations bool (N,), infos a dict of (N,) arrays with
    Gymnasium's ``_key`` masks, same-step auto-reset with ``final_obs`` / ``final_info`` exactly
    as ``gymnasium.vector.SyncVectorEnv(..., autoreset_mode=AutoresetMode.SAME_STEP)`` over
    ``mrexplore/Explore-v0`` copies gives them (a test holds it to that), but stepped by the
    batched engine (:class:`BatchedExploreEnv`; ``num_threads`` as there).

    Raises:
        ConfigError: ``n_robots`` other than 1, a bad ``num_envs``, ``num_threads`` or env
            option.
    """

    metadata: dict[str, Any] = {  # noqa: RUF012 - gymnasium reads it from the class
        "autoreset_mode": AutoresetMode.SAME_STEP,
        "render_modes": ["rgb_array"],
    }

    def __init__(self, num_envs: int, render_mode: str | None = None, **env_options: Any) -> None:
        n = env_options.pop("n_robots", 1)
        if n != 1:
            raise ConfigError(
                f"ExploreVectorEnv has one robot per world, got n_robots={n!r}; "
                "BatchedExploreEnv (mrexplore.vector_env(n_robots=...)) batches teams"
            )
        self.batch = BatchedExploreEnv(num_envs, render_mode=render_mode, n_robots=1, **env_options)
        self.num_envs = self.batch.num_envs
        self.render_mode = render_mode
        self.single_observation_space = self.batch.single_observation_space
        self.single_action_space = self.batch.single_action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)

    @property
    def envs(self) -> list[MultiRobotExplorationEnv]:
        """The N copies (one-robot :class:`MultiRobotExplorationEnv`)."""
        return self.batch.envs

    def reset(
        self,
        *,
        seed: int | list[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[NDArray[Any], dict[str, Any]]:
        """Reset every copy (copy k with ``seed + k``; a list gives each its own)."""
        obs, rows = self.batch.reset_copies(seed, options)
        infos: dict[str, Any] = {}
        for k, row in enumerate(rows):
            infos = self._add_info(infos, row[0], k)
        return obs[:, 0], infos

    def step(
        self, actions: NDArray[np.int64]
    ) -> tuple[
        NDArray[Any], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], dict[str, Any]
    ]:
        """One step of every world: ``actions`` int (N,); same-step auto-reset."""
        act = np.asarray(actions)
        if act.shape != (self.num_envs,):
            raise ValueError(f"actions must have shape ({self.num_envs},), got {act.shape}")
        b = self.batch.step_copies(act.reshape(self.num_envs, 1))
        infos: dict[str, Any] = {}
        for k, row in enumerate(b.infos):
            if k in b.final:
                o, last = b.final[k]
                infos = self._add_info(infos, {"final_obs": o[0], "final_info": last[0]}, k)
            infos = self._add_info(infos, row[0], k)
        return b.obs[:, 0], b.rewards[:, 0], b.terminations[:, 0], b.truncations[:, 0], infos

    def render(self) -> tuple[Any, ...] | None:
        """One frame per world (``render_mode="rgb_array"``), else None."""
        return self.batch.render()

    def close_extras(self, **kwargs: Any) -> None:
        """Close the copies and the merge worker."""
        batch = getattr(self, "batch", None)  # None: the constructor raised
        if batch is not None:
            batch.close()
