"""One ``ParallelEnv`` copy seen as a block of SB3 slots, and the subprocess worker that runs it.

Kept apart from :mod:`mrexplore.wrappers.sb3_vec` on purpose: this module imports neither
stable-baselines3 nor torch, so a worker process started with ``spawn``/``forkserver`` only
imports numpy, gymnasium and the env itself (seconds less per worker).

Per-agent episode ends (general ``ParallelEnv``; our env ends all robots together):

* an agent that terminates or truncates while others go on reports ``done=True`` once, with its
  ``terminal_observation``; until its env copy resets, its slot is *idle*: zero observation,
  reward 0, ``done=False``, ``info["idle"] = True``, and its actions are ignored;
* when no agent is left the copy resets at once (auto-reset) and every slot receives the first
  observation of the new episode.
"""

from __future__ import annotations

import multiprocessing.connection
from typing import Any

import gymnasium
import numpy as np
from numpy.typing import NDArray

from mrexplore.errors import ConfigError

#: One copy's step: per-slot observations, rewards (float32), dones, infos, and the reset infos
#: when the copy was auto-reset (else None).
StepResult = tuple[
    list[Any],
    NDArray[np.float32],
    NDArray[np.bool_],
    list[dict[str, Any]],
    "list[dict[str, Any]] | None",
]


def zeros_of(space: gymnasium.spaces.Space[Any]) -> Any:
    """An all-zero observation of a ``Box`` / ``MultiBinary`` / ``Discrete`` / ``Dict`` space."""
    if isinstance(space, gymnasium.spaces.Dict):
        return {k: zeros_of(s) for k, s in space.spaces.items()}
    if isinstance(space, gymnasium.spaces.Discrete):
        return np.zeros((), dtype=np.int64)
    if space.shape is None:
        raise ConfigError(f"observation space {space} is not supported by ParallelEnvVecEnv")
    return np.zeros(space.shape, dtype=space.dtype)


def copy_obs(obs: Any) -> Any:
    """A deep copy of an observation (array or dict of arrays): envs may reuse their buffers."""
    if isinstance(obs, dict):
        return {k: copy_obs(v) for k, v in obs.items()}
    return np.array(obs, copy=True)


def shared_spaces(
    env: Any,
) -> tuple[list[Any], gymnasium.spaces.Space[Any], gymnasium.spaces.Space[Any]]:
    """The agents of ``env`` and the one observation and action space they must all share.

    Raises:
        ConfigError: agents with different observation or action spaces (one shared policy
            cannot serve them), or an env without agents.
    """
    agents = list(env.possible_agents)
    if not agents:
        raise ConfigError("the ParallelEnv has no possible_agents")
    obs0 = env.observation_space(agents[0])
    act0 = env.action_space(agents[0])
    for a in agents[1:]:
        if env.observation_space(a) != obs0:
            raise ConfigError(
                f"agents {agents[0]!r} and {a!r} have different observation spaces "
                f"({obs0} vs {env.observation_space(a)}); a shared policy needs one space"
            )
        if env.action_space(a) != act0:
            raise ConfigError(
                f"agents {agents[0]!r} and {a!r} have different action spaces "
                f"({act0} vs {env.action_space(a)}); a shared policy needs one space"
            )
    return agents, obs0, act0


class CopyRunner:
    """Runs one env copy: dict-of-agents API in, per-slot lists out (slot j = ``agents[j]``)."""

    def __init__(self, env: Any) -> None:
        self.env = env
        self.agents, self.observation_space, self.action_space = shared_spaces(env)
        self._zero = zeros_of(self.observation_space)
        self._live: set[Any] = set()

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[list[Any], list[dict[str, Any]]]:
        """Reset the copy; returns per-slot observations and reset infos."""
        kwargs: dict[str, Any] = {"seed": seed}
        if options:
            kwargs["options"] = options
        obs, infos = self.env.reset(**kwargs)
        self._live = {a for a in self.agents if a in obs}
        return (
            [copy_obs(obs[a]) if a in obs else copy_obs(self._zero) for a in self.agents],
            [dict(infos.get(a, {})) for a in self.agents],
        )

    def step(
        self, actions: NDArray[Any] | list[Any]
    ) -> tuple[
        list[Any],
        NDArray[np.float32],
        NDArray[np.bool_],
        list[dict[str, Any]],
        list[dict[str, Any]] | None,
    ]:
        """Step the copy with one action per slot; auto-resets when no agent is left.

        Returns per-slot observations, rewards (float32), dones, infos, and the reset infos
        when the copy was reset (else None).
        """
        discrete = isinstance(self.action_space, gymnasium.spaces.Discrete)
        live_now = [a for a in self.agents if a in self._live]
        act = {
            a: (int(actions[j]) if discrete else actions[j])
            for j, a in enumerate(self.agents)
            if a in self._live
        }
        obs, rewards, terms, truncs, infos = self.env.step(act)
        n = len(self.agents)
        out_obs: list[Any] = [None] * n
        out_rew = np.zeros(n, dtype=np.float32)
        out_done = np.zeros(n, dtype=bool)
        out_info: list[dict[str, Any]] = [{} for _ in range(n)]
        for j, a in enumerate(self.agents):
            if a not in live_now:
                out_obs[j] = copy_obs(self._zero)
                out_info[j] = {"idle": True}
                continue
            term = bool(terms.get(a, False))
            trunc = bool(truncs.get(a, False))
            info = dict(infos.get(a, {}))
            # SB3's convention: a time-limit end that is not also a true end can be bootstrapped.
            info["TimeLimit.truncated"] = trunc and not term
            out_rew[j] = float(rewards.get(a, 0.0))
            o = copy_obs(obs[a]) if a in obs else copy_obs(self._zero)
            if term or trunc or a not in obs:
                out_done[j] = True
                info["terminal_observation"] = o
                self._live.discard(a)
            out_obs[j] = o
            out_info[j] = info
        # An agent the env no longer lists is gone, whatever it reported: end its slot now.
        listed = set(self.env.agents)
        for j, a in enumerate(self.agents):
            if a in self._live and a not in listed:
                out_done[j] = True
                out_info[j]["terminal_observation"] = out_obs[j]
                self._live.discard(a)
        reset_infos = None
        if not self._live:
            new_obs, reset_infos = self.reset()
            out_obs = new_obs
        return out_obs, out_rew, out_done, out_info, reset_infos

    def get_attr(self, name: str) -> Any:
        """``getattr`` on the env (PettingZoo wrappers forward public names to the env)."""
        return getattr(self.env, name)

    def set_attr(self, name: str, value: Any) -> None:
        """``setattr`` on the outermost env object."""
        setattr(self.env, name, value)

    def env_method(self, name: str, args: tuple[Any, ...], kwargs: dict[str, Any]) -> Any:
        """Call ``env.<name>(*args, **kwargs)``."""
        return getattr(self.env, name)(*args, **kwargs)

    def is_wrapped(self, wrapper_class: type) -> bool:
        """True when ``wrapper_class`` is in the chain of ``.env`` attributes."""
        e = self.env
        seen = 0
        while e is not None and seen < 100:
            if isinstance(e, wrapper_class):
                return True
            e = getattr(e, "env", None) if "env" in getattr(e, "__dict__", {}) else None
            seen += 1
        return False

    def render(self) -> Any:
        """The copy's frame (``render_mode="rgb_array"``) or None."""
        return self.env.render()

    def close(self) -> None:
        """Close the env."""
        self.env.close()


def answer(runner: CopyRunner, cmd: str, data: Any = None) -> Any:
    """One copy's answer to a ``VecEnv`` command other than ``step`` and ``close``: ``reset``,
    ``get_attr``, ``set_attr``, ``env_method``, ``is_wrapped``, ``render`` (``data``: the
    command's arguments, as the ``VecEnv`` sends them); a ``ValueError`` for any other."""
    if cmd == "reset":
        return runner.reset(*data)
    if cmd == "get_attr":
        return runner.get_attr(data)
    if cmd == "set_attr":
        runner.set_attr(*data)
        return None
    if cmd == "env_method":
        return runner.env_method(*data)
    if cmd == "is_wrapped":
        return runner.is_wrapped(data)
    if cmd == "render":
        return runner.render()
    raise ValueError(f"unknown worker command {cmd!r}")


def worker(
    remote: multiprocessing.connection.Connection,
    parent_remote: multiprocessing.connection.Connection,
    env_fn_pickled: bytes,
) -> None:
    """Subprocess loop: build the env from a cloudpickled factory, answer commands on the pipe.

    Every answer is ``("ok", value)`` or ``("error", exception)`` so that an exception in the
    env reaches the parent as an exception, not as a dead pipe.
    """
    import cloudpickle

    parent_remote.close()
    runner: CopyRunner | None = None
    try:
        runner = CopyRunner(cloudpickle.loads(env_fn_pickled)())
        remote.send(("ok", (runner.agents, runner.observation_space, runner.action_space)))
    except Exception as exc:
        remote.send(("error", exc))
        remote.close()
        return
    while True:
        try:
            cmd, data = remote.recv()
        except (EOFError, KeyboardInterrupt):
            break
        try:
            if cmd == "step":
                result: Any = runner.step(data)
            elif cmd == "close":
                runner.close()
                remote.send(("ok", None))
                break
            else:
                result = answer(runner, cmd, data)
        except Exception as exc:
            remote.send(("error", exc))
        else:
            remote.send(("ok", result))
    remote.close()
