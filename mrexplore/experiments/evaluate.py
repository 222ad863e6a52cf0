"""``mrexplore evaluate <policy folder>``: a trained policy side by side with the baselines.

Runs the trained policy and ``random``, ``nearest-frontier`` and ``coordinated-frontier`` on the
same held-out seeds (never used in training: training env copies are seeded from the training
seed, evaluation from ``EVAL_SEED_BASE`` up), and reports task time (mean, spread, success rate)
and team coverage at fixed times, as a table, JSON and a plot.
"""

from __future__ import annotations

import argparse
import json
import statistics
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from mrexplore.errors import ConfigError
from mrexplore.experiments.episode import EpisodeResult, run_episode
from mrexplore.experiments.trained import RLLIB_MODULE, load_team_policy, read_config
from mrexplore.io_safety import atomic_path, check_out_dir, write_text

EVAL_SEED_BASE = 1_000_000
BASELINES = ("random", "nearest-frontier", "coordinated-frontier")
COVERAGE_TIMES_S = (15.0, 30.0, 60.0, 90.0, 120.0)


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
    }
    for t in times_s:
        cov = [coverage_at(r, t) for r in results]
        out["coverage_at"][f"{t:g}"] = {
            "mean": statistics.fmean(cov),
            "std": statistics.pstdev(cov),
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
) -> dict[str, Any]:
    """Evaluate ``folder`` (model.zip + config.yaml) against the baselines.

    Writes ``eval.json`` and ``eval.png`` to ``out`` when given (refused when ``out`` is the
    policy folder, a file, or a non-empty folder without ``force``); with ``out=None`` it only
    returns the document. Everything is checked and the model loaded before any episode runs.

    Raises:
        ConfigError: not a policy folder, ``n_seeds < 1``, broken config.yaml or model.zip.
        OutputExistsError: ``out`` is refused (see above).
    """
    from mrexplore.policies import make_team_policy

    folder = Path(folder)
    if isinstance(n_seeds, bool) or not isinstance(n_seeds, (int, np.integer)) or n_seeds < 1:
        raise ConfigError(f"evaluate needs at least 1 seed, got {n_seeds!r}")
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
    seeds = list(range(EVAL_SEED_BASE, EVAL_SEED_BASE + int(n_seeds)))
    trained = load_team_policy(
        folder, [f"robot_{i}" for i in range(int(env_options.get("n_robots", 2)))]
    )
    rllib = " rllib" if config.get("backend") == "rllib" else ""
    name = f"trained ({config.get('algo', 'ppo')}{rllib})"
    policies: dict[str, Any] = {name: lambda agents: trained}
    for b in BASELINES:
        policies[b] = lambda agents, b=b: make_team_policy(b, agents)
    if progress:
        print(
            f"evaluating {folder} and {len(BASELINES)} baselines on {len(seeds)} held-out "
            f"seed(s): {len(policies) * len(seeds)} episodes"
        )
    summaries = evaluate_policies(policies, env_options, seeds, progress=progress)
    doc: dict[str, Any] = {
        "policy_folder": str(folder),
        "env": env_options,
        "seeds": seeds,
        "trained_actions": "deterministic" if trained.deterministic else "sampled",
        "results": summaries,
    }
    if out_dir is not None:
        write_evaluation(doc, out_dir)
    print(format_evaluation(doc))
    return doc


def write_evaluation(doc: Mapping[str, Any], out_dir: Path) -> None:
    """Write ``eval.json`` and ``eval.png`` (when matplotlib is there) to ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    write_text(out_dir / "eval.json", json.dumps(doc, indent=2))
    try:
        with atomic_path(out_dir / "eval.png") as tmp:
            plot_evaluation(doc, tmp)
    except ImportError as exc:
        print(f"(no plot: {exc}; pip install 'mrexplore[plot]')")


def format_evaluation(doc: Mapping[str, Any]) -> str:
    """The evaluation as a text table."""
    results = doc["results"]
    times = list(next(iter(results.values()))["coverage_at"])
    head = f"{'policy':<26} {'task time (s)':>16} {'success':>8} " + " ".join(
        f"{'cov@' + t + 's':>9}" for t in times
    )
    lines = [f"evaluation on {len(doc['seeds'])} held-out seeds", head]
    for name, s in results.items():
        tt = s["task_time_s"]
        covs = " ".join(f"{s['coverage_at'][t]['mean']:>9.1%}" for t in times)
        lines.append(
            f"{name:<26} {tt['mean']:>8.1f} +- {tt['std']:<5.1f} {s['success_rate']:>8.0%} {covs}"
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
    """CLI: ``mrexplore evaluate FOLDER [--seeds N] [--out DIR]``."""
    p = argparse.ArgumentParser(prog="mrexplore evaluate", description=__doc__)
    p.add_argument("folder")
    p.add_argument("--seeds", type=int, default=20)
    p.add_argument(
        "--out",
        default=None,
        help="new folder for eval.json/eval.png (default: eval/<policy folder name>; never the "
        "policy folder itself)",
    )
    p.add_argument("--force", action="store_true", help="replace the files of a non-empty --out")
    args = p.parse_args(argv)
    out = args.out if args.out is not None else default_eval_dir(args.folder)
    evaluate_folder(args.folder, args.seeds, out, force=args.force)
    print(f"wrote {Path(out) / 'eval.json'} and eval.png")
    return 0
