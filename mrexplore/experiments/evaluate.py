"""``mrexplore evaluate <policy folder>``: a trained policy side by side with the baselines.

``mrexplore evaluate --team-factory package.module:function`` does the same for any team policy
(a TorchRL or hand-written policy, an SB3 or RLlib checkpoint loaded your way): ``function(agents)``
returns the team policy :func:`evaluate_team` runs; ``--env KEY=VALUE`` sets the env it acts in.

Runs the trained policy and ``random``, ``nearest-frontier``, ``cost-frontier`` and
``coordinated-frontier`` on the same held-out seeds (never used in training: training env copies
are seeded from the training seed, evaluation from ``EVAL_SEED_BASE`` up), and reports task time
(mean, spread, success rate), the simulated time to 90 % and 95 % team coverage (mean and 95 %
confidence interval; an episode that never gets there counts with its end time, and the count
that got there is printed), team coverage at fixed times, and a paired comparison of the
trained policy with ``coordinated-frontier`` on the same worlds (mean difference of the time to
95 % and its 95 % confidence interval), as a table, JSON and a plot. ``--worlds`` evaluates on
several world families (generator specs or world files, e.g. ``tb3_office``), the same seeds on
each; a goal-level policy (``action_mode: goal``) is run both greedily and sampling its actions.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from mrexplore.errors import ConfigError
from mrexplore.experiments.episode import EpisodeResult, run_episode
from mrexplore.experiments.trained import (
    RLLIB_MODULE,
    TrainedTeamPolicy,
    load_team_policy,
    read_config,
)
from mrexplore.io_safety import atomic_path, check_out_dir, write_text

EVAL_SEED_BASE = 1_000_000
BASELINES = ("random", "nearest-frontier", "cost-frontier", "coordinated-frontier")
COVERAGE_TIMES_S = (15.0, 30.0, 60.0, 90.0, 120.0)
#: Coverage levels whose first-reaching times are reported (shares).
COVERAGE_LEVELS = (0.90, 0.95)
#: The baseline the paired comparison is made against.
PAIRED_BASELINE = "coordinated-frontier"


def t_quantile_975(df: int) -> float:
    """The 97.5 % quantile of Student's t with ``df`` degrees of freedom (two-sided 95 %).

    Exact table values up to 10 degrees of freedom, then the Cornish-Fisher expansion (error
    below 1e-3 from there on), so no scipy is needed.

    >>> round(t_quantile_975(1), 3), round(t_quantile_975(49), 3)
    (12.706, 2.01)
    """
    table = (12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228)
    if df < 1:
        return math.inf
    if df <= len(table):
        return table[df - 1]
    z = 1.959963984540054
    return float(
        z
        + (z**3 + z) / (4 * df)
        + (5 * z**5 + 16 * z**3 + 3 * z) / (96 * df**2)
        + (3 * z**7 + 19 * z**5 + 17 * z**3 - 15 * z) / (384 * df**3)
    )


#: Fewer values than this and the printed tables say "n too small" instead of an interval
#: (with 2 the t quantile is 12.7: the interval says little but that more seeds are needed).
MIN_N_FOR_CI = 3


def mean_ci(
    values: Sequence[float], low: float | None = None, high: float | None = None
) -> dict[str, Any]:
    """Mean and 95 % confidence interval (Student's t) of ``values``: ``mean``, ``ci_low``,
    ``ci_high``, ``std`` (sample), ``n``. With fewer than two values the interval is unknown
    (None). ``low`` / ``high``: the range the quantity can take (0 for a time, 0 and 1 for a
    coverage); the interval is clipped to it, never reaching below what the data allow.

    >>> r = mean_ci([1.0, 2.0, 3.0])
    >>> r["mean"], round(r["ci_low"], 3), round(r["ci_high"], 3)
    (2.0, -0.484, 4.484)
    >>> mean_ci([1.0, 2.0, 3.0], low=0.0)["ci_low"]
    0.0
    """
    v = [float(x) for x in values]
    n = len(v)
    mean = statistics.fmean(v) if v else math.nan
    if n < 2:
        return {"mean": mean, "ci_low": None, "ci_high": None, "std": 0.0, "n": n}
    sd = statistics.stdev(v)
    half = t_quantile_975(n - 1) * sd / math.sqrt(n)
    ci_low, ci_high = mean - half, mean + half
    if low is not None:
        ci_low = max(ci_low, low)
    if high is not None:
        ci_high = min(ci_high, high)
    return {"mean": mean, "ci_low": ci_low, "ci_high": ci_high, "std": sd, "n": n}


def time_to_coverage(result: EpisodeResult, level: float) -> float | None:
    """The first simulated time the team coverage reached ``level`` (None: never)."""
    for t, c in zip(result.times_s, result.coverages, strict=True):
        if c >= level - 1e-9:
            return float(t)
    return None


def paired(a: Sequence[float], b: Sequence[float]) -> dict[str, Any]:
    """Paired comparison of ``a`` and ``b`` (same worlds, same order): ``a - b`` with its mean
    and 95 % CI, and how often ``a`` was lower (``a_lower``), equal or higher."""
    d = [float(x) - float(y) for x, y in zip(a, b, strict=True)]
    out = mean_ci(d)
    out["a_lower"] = sum(x < 0 for x in d)
    out["equal"] = sum(x == 0 for x in d)
    out["a_higher"] = sum(x > 0 for x in d)
    return out


def coverage_at(result: EpisodeResult, t_s: float) -> float:
    """Team coverage at simulated time ``t_s`` (after the episode's end: its final coverage)."""
    return float(np.interp(t_s, result.times_s, result.coverages))


def summarise(results: Sequence[EpisodeResult], times_s: Sequence[float]) -> dict[str, Any]:
    """Mean/std task time, success rate and coverage at ``times_s`` of a list of episodes."""
    tt = [r.task_time_s for r in results]
    out: dict[str, Any] = {
        "task_time_s": {"mean": statistics.fmean(tt), "std": statistics.pstdev(tt), "values": tt},
        "success_rate": float(np.mean([r.success for r in results])),
        "final_coverage": {"mean": statistics.fmean(r.coverage for r in results)},
        "coverage_at": {},
        "time_to": {},
    }
    for t in times_s:
        cov = [coverage_at(r, t) for r in results]
        out["coverage_at"][f"{t:g}"] = {
            **mean_ci(cov, low=0.0, high=1.0),
            "std": statistics.pstdev(cov),
        }
    for level in COVERAGE_LEVELS:
        # Censored at the episode's end when the level was never reached (counted apart).
        reached = [time_to_coverage(r, level) for r in results]
        values = [r.task_time_s if x is None else x for x, r in zip(reached, results, strict=True)]
        out["time_to"][f"{level:g}"] = {
            **mean_ci(values, low=0.0),
            "reached": sum(x is not None for x in reached),
            "values": values,
        }
    return out


def evaluate_policies(
    policies: Mapping[str, Any],
    env_options: Mapping[str, Any],
    seeds: Sequence[int],
    times_s: Sequence[float] = COVERAGE_TIMES_S,
    progress: bool = True,
) -> dict[str, Any]:
    """Run every ``name -> team policy factory(agents)`` on every seed; returns summaries."""
    n = int(env_options.get("n_robots", 2))
    agents = [f"robot_{i}" for i in range(n)]
    summaries: dict[str, Any] = {}
    bar = tqdm(total=len(policies) * len(seeds), desc="evaluate", unit="ep", disable=not progress)
    for name, factory in policies.items():
        results = []
        for seed in seeds:
            results.append(run_episode(dict(env_options), factory(agents), seed))
            bar.update(1)
        summaries[name] = summarise(results, times_s)
    bar.close()
    return summaries


def eval_env_options(config: Mapping[str, Any]) -> dict[str, Any]:
    """The env options of a training config, as used for evaluation (exploration task)."""
    opts = dict(config.get("env", {}))
    opts["task"] = "explore"
    return opts


def default_eval_dir(folder: str | Path) -> Path:
    """Where ``mrexplore evaluate FOLDER`` writes by default: ``eval/<folder name>`` in the
    current directory, never the policy folder itself (it may be a shipped policy)."""
    return Path("eval") / Path(folder).resolve().name


def evaluate_folder(
    folder: str | Path,
    n_seeds: int = 20,
    out: str | Path | None = None,
    progress: bool = True,
    force: bool = False,
    worlds: Sequence[str] | None = None,
    max_time_s: float | None = None,
) -> dict[str, Any]:
    """Evaluate ``folder`` (model.zip + config.yaml) against the baselines.

    Writes ``eval.json`` and ``eval.png`` to ``out`` when given (refused when ``out`` is the
    policy folder, a file, or a non-empty folder without ``force``); with ``out=None`` it only
    returns the document. Everything is checked and the model loaded before any episode runs.

    Args:
        worlds: world specs to evaluate on, the same seeds on each (default: the config's
            world); ``doc["results"]`` and ``doc["paired"]`` are the first world's,
            ``doc["worlds"]`` has every world's.
        max_time_s: the episodes' time limit (default: the config's), so times to 95 % are
            measured rather than censored.

    Raises:
        ConfigError: not a policy folder, ``n_seeds < 1``, broken config.yaml or model.zip.
        OutputExistsError: ``out`` is refused (see above).
    """
    from mrexplore.environment.goal_actions import split_options

    folder = Path(folder)
    if isinstance(n_seeds, bool) or not isinstance(n_seeds, (int, np.integer)) or n_seeds < 1:
        raise ConfigError(f"evaluate needs at least 1 seed, got {n_seeds!r}")
    if max_time_s is not None and not max_time_s > 0:
        raise ConfigError(f"evaluate: max_time_s must be > 0, got {max_time_s!r}")
    has_model = (folder / "model.zip").is_file() or (folder / RLLIB_MODULE).is_dir()
    if not (folder / "config.yaml").is_file() or not has_model:
        raise ConfigError(
            f"{folder} is not a trained policy folder (it needs config.yaml and model.zip, or "
            "an RLlib checkpoint/, as written by `mrexplore train`)"
        )
    out_dir = (
        None
        if out is None
        else check_out_dir(out, force=force, what="mrexplore evaluate", protect=[folder])
    )
    config = read_config(folder)
    env_options = eval_env_options(config)
    if max_time_s is not None:
        env_options["max_time_s"] = float(max_time_s)
    mode, _, low_options = split_options(env_options)  # the planners act on the low level
    world_list = [str(w) for w in worlds] if worlds else [str(env_options.get("world"))]
    seeds = list(range(EVAL_SEED_BASE, EVAL_SEED_BASE + int(n_seeds)))
    agents = [f"robot_{i}" for i in range(int(env_options.get("n_robots", 2)))]
    trained = load_team_policy(folder, agents)
    rllib = " rllib" if config.get("backend") == "rllib" else ""
    name = f"trained ({config.get('algo', 'ppo')}{rllib})"
    learned: dict[str, Any] = {}
    if mode == "goal" and isinstance(trained, TrainedTeamPolicy):
        # Goal-level policies choose among a few goals: both the arg-max and sampled choices.
        greedy = TrainedTeamPolicy(trained.model, agents, deterministic=True)
        learned[f"{name}, greedy"] = lambda agents: greedy
        learned[f"{name}, sampled"] = lambda agents: trained
    else:
        learned[name] = lambda agents: trained
    if progress:
        n_eps = (len(learned) + len(BASELINES)) * len(seeds) * len(world_list)
        print(
            f"evaluating {folder} and {len(BASELINES)} baselines on {len(seeds)} held-out "
            f"seed(s) x {len(world_list)} world(s): {n_eps} episodes"
        )
    by_world = _against_baselines(learned, env_options, low_options, world_list, seeds, progress)
    actions = (
        "greedy and sampled"
        if len(learned) > 1
        else ("deterministic" if trained.deterministic else "sampled")
    )
    head = {"policy_folder": str(folder), "env": env_options, "seeds": seeds}
    return _report({**head, "trained_actions": actions}, by_world, world_list[0], out_dir)


def _report(
    head: Mapping[str, Any], by_world: dict[str, Any], first_world: str, out_dir: Path | None
) -> dict[str, Any]:
    """The evaluation's document (``head``, then the first world's results and pairing and
    every world's), written to ``out_dir`` (None: not written) and printed."""
    first = by_world[first_world]
    doc: dict[str, Any] = {
        **head,
        "paired_baseline": PAIRED_BASELINE,
        "results": first["results"],
        "paired": first["paired"],
        "worlds": by_world,
    }
    if out_dir is not None:
        write_evaluation(doc, out_dir)
    print(format_evaluation(doc))
    return doc


def _against_baselines(
    learned: Mapping[str, Any],
    env_options: Mapping[str, Any],
    low_options: Mapping[str, Any],
    world_list: Sequence[str],
    seeds: Sequence[int],
    progress: bool,
) -> dict[str, Any]:
    """Per world: every ``learned`` factory and the baselines on ``seeds``, and each learned
    policy paired with :data:`PAIRED_BASELINE` (the planners run on ``low_options``)."""
    from mrexplore.policies import make_team_policy

    baselines = {b: (lambda agents, b=b: make_team_policy(b, agents)) for b in BASELINES}
    by_world: dict[str, Any] = {}
    for w in world_list:
        results = evaluate_policies(learned, {**env_options, "world": w}, seeds, progress=progress)
        results.update(
            evaluate_policies(baselines, {**low_options, "world": w}, seeds, progress=progress)
        )
        comparison = {
            lname: {
                f"time_to_{level:g}": paired(
                    results[lname]["time_to"][f"{level:g}"]["values"],
                    results[PAIRED_BASELINE]["time_to"][f"{level:g}"]["values"],
                )
                for level in COVERAGE_LEVELS
            }
            for lname in learned
        }
        by_world[w] = {"results": results, "paired": comparison}
    return by_world


def team_env_options(env_options: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """``(options, low-level options)`` an evaluated team policy acts in: ``env_options`` with
    the exploration task and, when it names none, the env's default world; checked.

    Raises:
        ConfigError: an unknown or bad option.
    """
    from mrexplore.environment.config import EnvConfig
    from mrexplore.environment.goal_actions import split_options

    options = {**dict(env_options), "task": "explore"}
    options.setdefault("world", EnvConfig().world)
    _, _, low_options = split_options(options)
    EnvConfig.from_kwargs(**{k: v for k, v in low_options.items() if k != "world"})
    return options, low_options


def evaluate_team(
    policy: Callable[[list[str]], Any],
    env_options: Mapping[str, Any],
    n_seeds: int = 20,
    out: str | Path | None = None,
    name: str = "policy",
    worlds: Sequence[str] | None = None,
    progress: bool = True,
    force: bool = False,
) -> dict[str, Any]:
    """Any team policy against the frontier planners, as ``mrexplore evaluate`` does for a
    policy folder: the same held-out seeds, tables, paired comparison, ``eval.json`` and plot.

    For a policy no folder describes (a TorchRL or hand-written policy, a callable):
    ``policy(agents)`` returns an object with ``reset(rng)`` and either ``act(views)`` (robot
    views, as the planners) or ``uses_observations = True`` and ``act_obs(obs) -> {agent:
    action}`` (the env's observations, as a trained network).

    Args:
        policy: the factory, called once per episode with the agents' names.
        env_options: the env it acts in (``world``, ``n_robots``, ``max_time_s``, the
            observation format it was trained on, ...); the task is exploration.
        n_seeds: held-out seeds (from ``EVAL_SEED_BASE`` up) per world.
        out: a new folder for ``eval.json`` and ``eval.png`` (None: write nothing).
        name: the policy's row in the tables.
        worlds: world specs to evaluate on (default: ``env_options["world"]``).

    Raises:
        ConfigError: ``n_seeds < 1``, a policy that is not callable, or bad env options.
        OutputExistsError: ``out`` is a file or a non-empty folder (without ``force``).
    """
    if isinstance(n_seeds, bool) or not isinstance(n_seeds, (int, np.integer)) or n_seeds < 1:
        raise ConfigError(f"evaluate needs at least 1 seed, got {n_seeds!r}")
    if not callable(policy):
        raise ConfigError(f"evaluate_team: policy must be a factory policy(agents), got {policy!r}")
    options, low_options = team_env_options(env_options)
    out_dir = None if out is None else check_out_dir(out, force=force, what="evaluate_team")
    world_list = [str(w) for w in worlds] if worlds else [str(options.get("world"))]
    seeds = list(range(EVAL_SEED_BASE, EVAL_SEED_BASE + int(n_seeds)))
    by_world = _against_baselines({name: policy}, options, low_options, world_list, seeds, progress)
    head = {"policy": name, "env": options, "seeds": seeds}
    return _report(head, by_world, world_list[0], out_dir)


def import_team_factory(spec: str) -> Callable[[list[str]], Any]:
    """The team-policy factory named ``spec`` = ``package.module:function`` (the function may be
    a dotted attribute path, e.g. ``module:Class.make``), imported with the current directory on
    the import path (as ``python -m`` has it), so a ``my_policy.py`` beside you is found.

    Raises:
        ConfigError: ``spec`` is malformed, the module cannot be imported (or raised while
            importing), it has no such attribute, or the attribute is not callable; the message
            names which.
    """
    import importlib
    import os
    import sys

    module_name, sep, attr = str(spec).partition(":")
    if not sep or not module_name or not attr:
        raise ConfigError(
            f"--team-factory must be package.module:function, got {spec!r} (e.g. "
            "my_policy:make_team, where make_team(agents) returns the team policy)"
        )
    cwd = os.getcwd()
    if cwd not in sys.path and "" not in sys.path:
        sys.path.insert(0, cwd)  # a console script, unlike python -m, lacks it
    try:
        obj: Any = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        raise ConfigError(
            f"--team-factory {spec}: cannot import {module_name!r} ({exc}); run from the folder "
            "that holds it or install its package"
        ) from exc
    except Exception as exc:  # the user's module failed while importing: say so, not crash
        raise ConfigError(
            f"--team-factory {spec}: importing {module_name!r} raised {type(exc).__name__}: {exc}"
        ) from exc
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise ConfigError(f"--team-factory {spec}: {module_name!r} has no attribute {attr!r}")
        obj = getattr(obj, part)
    if not callable(obj):
        raise ConfigError(
            f"--team-factory {spec}: {attr!r} is a {type(obj).__name__}, not a callable "
            "factory(agents) returning a team policy"
        )
    return obj


def check_team_policy(policy: Any, spec: str) -> None:
    """Refuse, before any episode, a factory's product that :func:`evaluate_team` cannot run:
    it needs ``reset(rng)`` and either ``act(views)`` or ``uses_observations = True`` with
    ``act_obs(obs)``.

    Raises:
        ConfigError: naming ``spec`` and the missing method.
    """
    needs = ["reset", "act_obs" if getattr(policy, "uses_observations", False) else "act"]
    missing = [m for m in needs if not callable(getattr(policy, m, None))]
    if missing:
        raise ConfigError(
            f"--team-factory {spec} returned a {type(policy).__name__} without "
            f"{' and '.join(m + '()' for m in missing)}; a team policy has reset(rng) and "
            "act(views), or uses_observations = True and act_obs(obs)"
        )


def parse_env_options(pairs: Sequence[str]) -> dict[str, Any]:
    """``["KEY=VALUE", ...]`` -> env options, each value read as a YAML scalar (``3`` an int,
    ``5.0`` a float, ``true`` a bool, ``float32`` a string).

    Raises:
        ConfigError: an item without ``=`` or with an empty key.
    """
    import yaml

    options: dict[str, Any] = {}
    for item in pairs:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"--env takes KEY=VALUE (e.g. n_robots=3), got {item!r}")
        try:
            options[key.strip()] = yaml.safe_load(value) if value.strip() else value
        except yaml.YAMLError:
            options[key.strip()] = value
    return options


def write_evaluation(doc: Mapping[str, Any], out_dir: Path) -> None:
    """Write ``eval.json`` and ``eval.png`` (when matplotlib is there) to ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    write_text(out_dir / "eval.json", json.dumps(doc, indent=2))
    try:
        with atomic_path(out_dir / "eval.png") as tmp:
            plot_evaluation(doc, tmp)
    except ImportError as exc:
        print(f"(no plot: {exc}; pip install 'mrexplore[plot]')")


def _ci(s: Mapping[str, Any]) -> str:
    """``mean [low, high]``; ``mean [n too small]`` below :data:`MIN_N_FOR_CI` values."""
    if s.get("ci_low") is None or int(s.get("n", MIN_N_FOR_CI)) < MIN_N_FOR_CI:
        return f"{s['mean']:.1f} [n too small]"
    return f"{s['mean']:.1f} [{s['ci_low']:.1f}, {s['ci_high']:.1f}]"


def format_evaluation(doc: Mapping[str, Any]) -> str:
    """The evaluation as text tables: per world, every policy's success rate, times to 90 % and
    95 % coverage (mean [95 % CI], how many reached it), coverage at fixed times; then the
    paired comparison with the baseline."""
    env = doc.get("env", {})
    worlds = doc.get("worlds") or {str(env.get("world")): doc}
    cap, target = env.get("max_time_s"), env.get("target_coverage")
    lines = [
        f"evaluation on {len(doc['seeds'])} held-out seeds per world"
        + (f", episodes capped at {float(cap):g} s" if cap is not None else "")
        + (f", target coverage {float(target):.0%}" if target is not None else "")
    ]
    for w, block in worlds.items():
        results = block["results"]
        times = list(next(iter(results.values()))["coverage_at"])
        levels = list(next(iter(results.values())).get("time_to", {}))
        head = f"{'policy':<32} {'success':>7} " + " ".join(
            f"{'t' + str(round(float(lv) * 100)) + '% (s) [95% CI] reached':>34}" for lv in levels
        )
        head += " " + " ".join(f"{'cov@' + t + 's':>9}" for t in times)
        lines += ["", f"world {w}", head]
        for name, s in results.items():
            n = len(s["task_time_s"]["values"])
            cells = [f"{_ci(s['time_to'][lv])} {s['time_to'][lv]['reached']}/{n}" for lv in levels]
            tt = " ".join(f"{c:>34}" for c in cells)
            covs = " ".join(f"{s['coverage_at'][t]['mean']:>9.1%}" for t in times)
            lines.append(f"{name:<32} {s['success_rate']:>7.0%} {tt} {covs}")
        planners = [results[b] for b in BASELINES if b != "random" and b in results]
        if cap is not None and planners and all(r["success_rate"] == 0 for r in planners):
            # every score is then a censored time: the cap, not the policies, decides the table
            lines.append(
                f"note: no frontier planner reached the target within {float(cap):g} s on {w}: "
                "the cap is short for this world; evaluate with a longer --max-time-s"
            )
        for lname, comp in block.get("paired", {}).items():
            for key, p in comp.items():
                lines.append(
                    f"paired {lname} - {doc.get('paired_baseline', PAIRED_BASELINE)}, {key} (s): "
                    f"mean {_ci(p)}, n {p['n']}; trained lower in {p['a_lower']}, equal in "
                    f"{p['equal']}, higher in {p['a_higher']}"
                )
    return "\n".join(lines)


def plot_evaluation(doc: Mapping[str, Any], path: Path) -> None:
    """Coverage at fixed times per policy (mean +- std)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    for name, s in doc["results"].items():
        ts = [float(t) for t in s["coverage_at"]]
        m = [s["coverage_at"][t]["mean"] for t in s["coverage_at"]]
        sd = [s["coverage_at"][t]["std"] for t in s["coverage_at"]]
        ax.errorbar(ts, m, yerr=sd, marker="o", capsize=3, label=name)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("team coverage")
    ax.set_ylim(0, 1)
    ax.legend()
    ax.set_title("held-out worlds: coverage at fixed times")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: Sequence[str] | None = None) -> int:
    """CLI: ``mrexplore evaluate FOLDER [--seeds N] [--out DIR]`` or ``mrexplore evaluate
    --team-factory MODULE:FUNCTION [--env KEY=VALUE ...] [--seeds N] [--out DIR]``."""
    p = argparse.ArgumentParser(
        prog="mrexplore evaluate",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "folder", nargs="?", default=None, help="a trained policy folder (`mrexplore train`)"
    )
    p.add_argument(
        "--team-factory",
        default=None,
        metavar="MODULE:FUNCTION",
        help="instead of a folder: a Python factory, FUNCTION(agents) -> team policy (reset(rng) "
        "and act(views), or uses_observations = True and act_obs(obs)), imported with the "
        "current directory on the path",
    )
    p.add_argument(
        "--env",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="with --team-factory: an option of the env the policy acts in (repeat: "
        "world=small_office n_robots=2 obs_dtype=float32 ...); default the env's defaults",
    )
    p.add_argument("--name", default=None, help="with --team-factory: its row in the tables")
    p.add_argument("--seeds", type=int, default=20)
    p.add_argument(
        "--out",
        default=None,
        help="new folder for eval.json/eval.png (default: eval/<policy folder name>, or "
        "eval/<FUNCTION> for a factory; never the policy folder itself)",
    )
    p.add_argument("--force", action="store_true", help="replace the files of a non-empty --out")
    p.add_argument(
        "--worlds",
        nargs="+",
        default=None,
        help="world specs to evaluate on, the same seeds on each (e.g. "
        "'random:twin_wings?width_m=12&height_m=12' tb3_office; default: the training world)",
    )
    p.add_argument(
        "--max-time-s",
        type=float,
        default=None,
        help="episode time limit in simulated seconds (default: the policy's config)",
    )
    args = p.parse_args(argv)
    if (args.folder is None) == (args.team_factory is None):
        raise ConfigError(
            "mrexplore evaluate takes a policy folder or --team-factory MODULE:FUNCTION"
            + (", not both" if args.folder is not None else "")
        )
    if args.team_factory is None:
        if args.env or args.name is not None:
            raise ConfigError(
                "--env and --name go with --team-factory (a folder's config.yaml sets its env)"
            )
        out = args.out if args.out is not None else default_eval_dir(args.folder)
        evaluate_folder(
            args.folder,
            args.seeds,
            out,
            force=args.force,
            worlds=args.worlds,
            max_time_s=args.max_time_s,
        )
    else:
        out = _evaluate_factory(args)
    print(f"wrote {Path(out) / 'eval.json'} and eval.png")
    return 0


def _evaluate_factory(args: argparse.Namespace) -> Path:
    """``--team-factory``: import it, check what it makes, run :func:`evaluate_team`; returns
    the output folder."""
    factory = import_team_factory(args.team_factory)
    if args.max_time_s is not None and not args.max_time_s > 0:
        raise ConfigError(f"--max-time-s must be > 0, got {args.max_time_s!r}")
    options = parse_env_options(args.env)
    if args.max_time_s is not None:
        options["max_time_s"] = float(args.max_time_s)
    options, _ = team_env_options(options)  # checked before the factory runs
    agents = [f"robot_{i}" for i in range(int(options.get("n_robots", 2)))]
    check_team_policy(factory(agents), args.team_factory)
    func = args.team_factory.partition(":")[2]
    out = Path(args.out) if args.out is not None else Path("eval") / func
    evaluate_team(
        factory,
        options,
        n_seeds=args.seeds,
        out=out,
        name=args.name or args.team_factory,
        worlds=args.worlds,
        force=args.force,
    )
    return out
