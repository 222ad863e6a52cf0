"""``mrexplore imitate``: behaviour cloning of a goal-level rule, a starting point for PPO.

Training the goal chooser from a random network gives policies whose quality swings by 8-40 s
between training seeds and between checkpoints 100k decisions apart (``docs/goal_policy.md``).
This starts it from a known-good rule instead: the teacher :func:`~mrexplore.policies.
goal_rules.keep_or_burgard` drives the goal-level env on training worlds (seeds below
``EVAL_SEED_BASE``), every robot's ``(observation, mask, chosen row, return)`` is recorded, and
the ``MaskablePPO`` network of the hyperparameter file is fitted to it: the policy head by
cross-entropy over the valid rows, the value head to the teacher's discounted returns (so PPO's
first advantages are not noise that pushes the policy off the teacher). The folder written
(``model.zip``, ``config.yaml``, ``imitation.json``) is a policy folder: ``mrexplore evaluate``
reads it, and ``mrexplore train --init-from`` continues it with PPO.

Returns are computed per robot within each episode, ``G_t = r_t + gamma * G_{t+1}``, and not
bootstrapped at the time limit (the few last decisions of a truncated episode are undervalued).
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray

from mrexplore.errors import ConfigError
from mrexplore.experiments.evaluate import EVAL_SEED_BASE
from mrexplore.experiments.train import load_hyperparams, save_for_inference, versions
from mrexplore.experiments.trained import algo_class
from mrexplore.io_safety import atomic_path, check_out_dir, write_text
from mrexplore.options import integer_argument, is_number
from mrexplore.policies.goal_rules import KeepOrBurgardTeam

ALGO = "maskable_ppo"
#: Share of the demonstrations (the last episodes) held out to measure the clone's agreement.
HOLDOUT = 0.1
#: The teacher's weights (:func:`~mrexplore.policies.goal_rules.keep_or_burgard`) unless the
#: hyperparameter file's ``teacher`` section sets them.
TEACHER_DEFAULTS = {"beta": 1.0, "size_weight": 0.0}


@dataclass(frozen=True)
class Demonstrations:
    """Recorded decisions of the teacher, one row per robot and decision.

    Attributes:
        observations: ``(N, K, F)`` float32 goal-level observations.
        masks: ``(N, K)`` int8 valid rows.
        actions: ``(N,)`` int64 rows the teacher chose.
        returns: ``(N,)`` float32 discounted returns from that decision on (reward units).
        episodes: ``(N,)`` int64 episode number of each row (0, 1, ... in collection order).
    """

    observations: NDArray[np.float32]
    masks: NDArray[np.int8]
    actions: NDArray[np.int64]
    returns: NDArray[np.float32]
    episodes: NDArray[np.int64]

    def __len__(self) -> int:
        return int(self.actions.size)


def discounted_returns(rewards: Sequence[float], gamma: float) -> NDArray[np.float32]:
    """``G_t = r_t + gamma * G_{t+1}`` for one robot's episode (no bootstrap at the end).

    >>> discounted_returns([1.0, 0.0, 2.0], 0.5).tolist()
    [1.5, 1.0, 2.0]
    """
    out = np.zeros(len(rewards), dtype=np.float32)
    g = 0.0
    for t in range(len(rewards) - 1, -1, -1):
        g = float(rewards[t]) + gamma * g
        out[t] = g
    return out


def collect(
    env_options: dict[str, Any],
    worlds: Sequence[str],
    decisions: int,
    seed: int,
    gamma: float,
    beta: float = 1.0,
    size_weight: float = 0.0,
) -> Demonstrations:
    """Run the teacher until at least ``decisions`` robot-decisions are recorded.

    Episode ``e`` is on ``worlds[e % len(worlds)]`` with a seed drawn from
    ``numpy.random.default_rng(seed)`` below ``EVAL_SEED_BASE`` (never an evaluation world).
    """
    import mrexplore

    if not worlds:
        raise ConfigError("imitate: no training world")
    rng = np.random.default_rng(seed)
    envs: dict[str, Any] = {}
    obs_rows: list[NDArray[np.float32]] = []
    mask_rows: list[NDArray[np.int8]] = []
    actions: list[int] = []
    returns: list[NDArray[np.float32]] = []
    episodes: list[int] = []
    episode = 0
    while len(actions) < decisions:
        world = worlds[episode % len(worlds)]
        if world not in envs:
            envs[world] = mrexplore.parallel_env(**{**env_options, "world": world})
        env = envs[world]
        team = KeepOrBurgardTeam(env.possible_agents, beta, size_weight)
        obs, _ = env.reset(seed=int(rng.integers(EVAL_SEED_BASE)))
        trace: dict[str, list[tuple[Any, int, float]]] = {a: [] for a in env.agents}
        while env.agents:
            chosen = team.act_obs(obs)
            nxt, rewards, _, _, _ = env.step(chosen)
            for a, row in chosen.items():
                trace[a].append((obs[a], row, float(rewards[a])))
            obs = nxt
        for steps in trace.values():
            for o, row, _ in steps:
                obs_rows.append(np.asarray(o["observation"], dtype=np.float32))
                mask_rows.append(np.asarray(o["action_mask"], dtype=np.int8))
                actions.append(row)
                episodes.append(episode)
            returns.append(discounted_returns([r for _, _, r in steps], gamma))
        episode += 1
    for env in envs.values():
        env.close()
    return Demonstrations(
        observations=np.stack(obs_rows),
        masks=np.stack(mask_rows),
        actions=np.asarray(actions, dtype=np.int64),
        returns=np.concatenate(returns),
        episodes=np.asarray(episodes, dtype=np.int64),
    )


def clone(
    policy: Any,
    demos: Demonstrations,
    epochs: int,
    rng: np.random.Generator,
    batch_size: int = 256,
    learning_rate: float = 1e-3,
    vf_coef: float = 0.5,
) -> list[dict[str, float]]:
    """Fit ``policy`` (a ``MaskableActorCriticPolicy``) to ``demos``; returns per-epoch figures.

    Loss per batch: cross-entropy of the teacher's row under the masked policy plus ``vf_coef``
    times the squared error of the value against the return. The last :data:`HOLDOUT` of the
    episodes is held out: each epoch reports the share of its decisions where the greedy choice
    equals the teacher's (``holdout_agreement``), the same over the held-out decisions with a
    choice (two valid rows or more: not a robot that can only wait or, with ``goal_turns``, is
    off turn; ``holdout_agreement_with_choice``) and, as the gap PPO will see, on the fitted
    part.
    """
    import torch

    n_ep = int(demos.episodes.max()) + 1
    first_held = max(1, round(n_ep * (1.0 - HOLDOUT)))
    fit = np.flatnonzero(demos.episodes < first_held)
    held = np.flatnonzero(demos.episodes >= first_held)
    held_choice = held[demos.masks[held].sum(axis=1) > 1]
    opt = torch.optim.Adam(policy.parameters(), lr=learning_rate)

    def tensors(idx: NDArray[np.int64]) -> tuple[dict[str, Any], Any, Any, Any]:
        obs = {
            "observation": torch.as_tensor(demos.observations[idx]),
            "action_mask": torch.as_tensor(demos.masks[idx].astype(np.float32)),
        }
        masks = torch.as_tensor(demos.masks[idx].astype(bool))
        return obs, torch.as_tensor(demos.actions[idx]), torch.as_tensor(demos.returns[idx]), masks

    def agreement(idx: NDArray[np.int64]) -> float:
        if idx.size == 0:
            return float("nan")
        hits = 0
        with torch.no_grad():
            for k in range(0, idx.size, 4096):
                obs, act, _, masks = tensors(idx[k : k + 4096])
                dist = policy.get_distribution(obs, action_masks=masks)
                hits += int((dist.distribution.probs.argmax(dim=1) == act).sum())
        return hits / idx.size

    history = []
    policy.set_training_mode(True)
    for epoch in range(epochs):
        order = rng.permutation(fit)
        ce_sum, v_sum, batches = 0.0, 0.0, 0
        for k in range(0, order.size, batch_size):
            obs, act, ret, masks = tensors(order[k : k + batch_size])
            values, log_prob, _ = policy.evaluate_actions(obs, act, action_masks=masks)
            ce = -log_prob.mean()
            v_loss = torch.nn.functional.mse_loss(values.flatten(), ret)
            loss = ce + vf_coef * v_loss
            opt.zero_grad()
            loss.backward()
            torch.nn.utils.clip_grad_norm_(policy.parameters(), 0.5)
            opt.step()
            ce_sum, v_sum, batches = ce_sum + ce.item(), v_sum + v_loss.item(), batches + 1
        policy.set_training_mode(False)
        history.append(
            {
                "epoch": epoch + 1,
                "cross_entropy": ce_sum / max(batches, 1),
                "value_mse": v_sum / max(batches, 1),
                "fit_agreement": agreement(fit),
                "holdout_agreement": agreement(held),
                "holdout_agreement_with_choice": agreement(held_choice),
            }
        )
        policy.set_training_mode(True)
    policy.set_training_mode(False)
    return history


def teacher_weights(cfg: dict[str, Any]) -> dict[str, float]:
    """The teacher's weights from a hyperparameter file's optional ``teacher`` section.

    >>> teacher_weights({})
    {'beta': 1.0, 'size_weight': 0.0}
    >>> teacher_weights({"teacher": {"size_weight": 2}})
    {'beta': 1.0, 'size_weight': 2.0}
    """
    section = cfg.get("teacher") or {}
    if not isinstance(section, dict):
        raise ConfigError("imitate: the hyperparameter file's teacher section must be a mapping")
    weights = dict(TEACHER_DEFAULTS)
    for key, value in section.items():
        if key not in weights:
            raise ConfigError(
                f"imitate: unknown teacher weight {key!r}; choose from {', '.join(weights)}"
            )
        if not (is_number(value) and value >= 0):
            raise ConfigError(
                f"imitate: teacher weight {key} must be a finite number >= 0, got {value!r}"
            )
        weights[key] = float(value)
    return weights


def imitate(
    out: str | Path,
    hyperparams_file: str | Path | None = None,
    decisions: int = 40_000,
    epochs: int = 20,
    seed: int = 0,
    force: bool = False,
    progress: bool = True,
) -> dict[str, Any]:
    """Collect the teacher's decisions, clone them into a ``MaskablePPO`` model, save the folder.

    The env options, training worlds, policy and network come from the hyperparameter file (as
    for ``mrexplore train --algo maskable_ppo``; default its shipped YAML); it must set
    ``action_mode: goal``; its optional ``teacher`` section sets the rule's weights
    (:func:`teacher_weights`). Returns the ``config.yaml`` written.

    Raises:
        ConfigError: a bad argument or a file without ``action_mode: goal``.
        OutputExistsError: ``out`` is a file or a non-empty folder (without ``force``).
    """
    for name, value, lo in (("decisions", decisions, 1), ("epochs", epochs, 1), ("seed", seed, 0)):
        integer_argument("imitate", name, value, lo)
    from mrexplore.experiments.threads import phase_threads

    cfg = load_hyperparams(ALGO, hyperparams_file)
    # the cloning's gradient steps are this command's update: update_threads, as in train
    collect_threads, update_threads = phase_threads(cfg, "imitate")
    env_opts = dict(cfg["env"])
    if env_opts.get("action_mode") != "goal":
        raise ConfigError(
            "imitate: the hyperparameter file's env must set action_mode: goal (the teacher "
            "chooses among candidate goals)"
        )
    worlds = [str(w) for w in cfg.get("worlds") or [env_opts.get("world", "")]]
    weights = teacher_weights(cfg)
    out = check_out_dir(out, force=force, what="mrexplore imitate")
    gamma = float(cfg["hyperparams"].get("gamma", 0.99))

    import torch

    torch.set_num_threads(collect_threads)
    t0 = time.perf_counter()
    demos = collect(env_opts, worlds, decisions, seed, gamma, **weights)
    collect_s = time.perf_counter() - t0
    if progress:
        print(f"recorded {len(demos)} decisions in {collect_s:.0f} s; cloning")

    from mrexplore.wrappers.action_masks import VecActionMasks
    from mrexplore.wrappers.sb3_vec import make_vec_env

    venv = VecActionMasks(make_vec_env(n_copies=1, seed=seed, **env_opts))
    model = algo_class(ALGO)(
        cfg["policy"],
        venv,
        seed=seed,
        device="cpu",
        verbose=0,
        policy_kwargs=cfg.get("policy_kwargs") or None,
        **cfg["hyperparams"],
    )
    venv.close()
    torch.set_num_threads(update_threads)
    t1 = time.perf_counter()
    history = clone(
        model.policy,
        demos,
        epochs,
        np.random.default_rng(seed),
        vf_coef=float(cfg["hyperparams"].get("vf_coef", 0.5)),
    )
    clone_s = time.perf_counter() - t1
    torch.set_num_threads(collect_threads)
    out.mkdir(parents=True, exist_ok=True)
    with atomic_path(out / "model.zip") as tmp:
        save_for_inference(model, tmp)
    record = {
        "teacher": "keep_or_burgard",
        "teacher_weights": weights,
        "decisions": len(demos),
        "episodes": int(demos.episodes.max()) + 1,
        "epochs": epochs,
        "collect_s": collect_s,
        "clone_s": clone_s,
        "final": history[-1],
    }
    config = {
        "algo": ALGO,
        "seed": seed,
        "policy": cfg["policy"],
        "env": env_opts,
        "worlds": worlds,
        "hyperparams": cfg["hyperparams"],
        "policy_kwargs": cfg.get("policy_kwargs", {}),
        "torch_threads": collect_threads,
        "update_threads": update_threads,
        "imitation": record,
        "versions": versions(),
    }
    write_text(out / "config.yaml", yaml.safe_dump(config, sort_keys=False))
    write_text(out / "imitation.json", json.dumps({**record, "history": history}, indent=2))
    if progress:
        final = history[-1]
        print(
            f"cloned in {clone_s:.0f} s: agreement with the teacher {final['fit_agreement']:.1%} "
            f"(fitted), {final['holdout_agreement']:.1%} (held-out episodes; "
            f"{final['holdout_agreement_with_choice']:.1%} where it had a choice); wrote {out}"
        )
    return config


def main(argv: Sequence[str] | None = None) -> int:
    """CLI: ``mrexplore imitate --out DIR [--hyperparams F] [--decisions N] [--epochs E]``."""
    p = argparse.ArgumentParser(prog="mrexplore imitate", description=__doc__)
    p.add_argument("--out", required=True, help="new folder for model.zip, config.yaml")
    p.add_argument("--force", action="store_true", help="replace the files of a non-empty --out")
    p.add_argument(
        "--hyperparams",
        default=None,
        help="a maskable_ppo YAML with action_mode: goal (default: the shipped one)",
    )
    p.add_argument("--decisions", type=int, default=40_000, help="robot-decisions to record")
    p.add_argument("--epochs", type=int, default=20)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    imitate(
        args.out,
        hyperparams_file=args.hyperparams,
        decisions=args.decisions,
        epochs=args.epochs,
        seed=args.seed,
        force=args.force,
    )
    return 0
