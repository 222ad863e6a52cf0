"""The task-time experiment and the demo run end to end on a small world and write valid files."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from mrexplore.cli import main
from mrexplore.environment.config import EnvConfig
from mrexplore.errors import ConfigError, OutputExistsError
from mrexplore.experiments import task_time
from mrexplore.experiments.episode import run_episode
from mrexplore.experiments.task_time import CoverageClock, TaskTimeEpisode, run_task_time
from mrexplore.world.registry import envs_dir


@pytest.mark.expensive
def test_task_time_end_to_end(tmp_path: Path) -> None:
    doc = run_task_time(
        world="small_office",
        seeds=2,
        policy="nearest-frontier",
        out=tmp_path,
        progress=False,
        env_options={"max_time_s": 120.0},
        nav_warmup_s=20.0,
    )
    data = json.loads((tmp_path / "task_time.json").read_text())
    assert data == json.loads(json.dumps(doc))
    for task in ("explore", "navigate"):
        entry = data["tasks"][task]
        for team in ("single", "multi"):
            times = entry[team]["task_times_s"]
            assert len(times) == 2 and all(0 < t <= 120.0 for t in times)
            assert entry[team]["success_rate"] > 0
            assert abs(entry[team]["mean"] - sum(times) / 2) < 1e-9
        expected = 1 - entry["multi"]["mean"] / entry["single"]["mean"]
        assert abs(entry["reduction"] - expected) < 1e-9
    with (tmp_path / "task_time.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 2 * 2 * 2
    img = cv2.imread(str(tmp_path / "task_time.png"))
    assert img is not None and img.shape[0] > 100


@pytest.mark.expensive
def test_demo_command_writes_pictures(tmp_path: Path) -> None:
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--world", "small_office"]) == 0
    assert (out / "episode.gif").stat().st_size > 1000
    img = cv2.imread(str(out / "final.png"))
    assert img is not None and img.shape[1] > 1000


# --- validate first, resume, never overwrite ------------------------------------------------------


def _no_episodes(*args: object, **kwargs: object) -> None:
    raise AssertionError("an episode ran before the arguments were checked")


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--max-time-s", "10", "--nav-warmup-s", "20"], "nav_warmup_s (20.0) must be shorter"),
        (["--first-seed", "-1"], "first_seed must be an integer >= 0"),
        (["--seeds", "0"], "seeds must be an integer >= 1"),
        (["--policy", "nope"], "unknown policy 'nope'"),
        (["--world", "no_such_world"], "no_such_world"),
        (["--workers", "0"], "workers must be an integer >= 1"),
        (["--sighting-range-m", "-1"], "sighting_range_m must be"),
        (["--address", " "], "address must be a Ray address"),
    ],
)
def test_task_time_checks_every_argument_before_any_episode(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    args: list[str],
    words: str,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.setattr(task_time, "run_episode", _no_episodes)
    rc = main(["task-time", "--world", "small_office", "--out", str(tmp_path / "r"), *args])
    assert rc == 2
    err = capsys.readouterr().err
    assert words in err and len(err.strip().splitlines()) == 1


def test_task_time_resumes_and_keeps_results(tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    calls: list[int] = []
    interrupts = [2]  # interrupt once, at the second episode
    real = task_time.run_episode

    def interrupted(opts, team, seed):  # type: ignore[no-untyped-def]
        calls.append(seed)
        if len(calls) in interrupts:
            interrupts.clear()
            raise KeyboardInterrupt
        return real(opts, team, seed)

    kw = {
        "world": "small_office",
        "seeds": 1,
        "policy": "nearest-frontier",
        "out": tmp_path,
        "tasks": ("explore",),
        "env_options": {"max_time_s": 10.0},
        "progress": False,
    }
    monkeypatch.setattr(task_time, "run_episode", interrupted)
    with pytest.raises(KeyboardInterrupt):
        run_task_time(**kw)  # type: ignore[arg-type]
    assert not (tmp_path / "task_time.json").exists()
    log = (tmp_path / "episodes.jsonl").read_bytes()
    calls.clear()
    doc = run_task_time(**kw)  # type: ignore[arg-type]
    assert len(calls) == 1  # the single-robot episode was saved; only the team one ran again
    assert len(doc["tasks"]["explore"]["single"]["task_times_s"]) == 1
    assert not (tmp_path / "episodes.jsonl").exists()  # complete: the log is gone
    with pytest.raises(OutputExistsError, match="already exists"):
        run_task_time(**kw)  # type: ignore[arg-type]
    other = tmp_path / "other"
    other.mkdir()
    (other / "episodes.jsonl").write_bytes(log)
    with pytest.raises(OutputExistsError, match="other settings"):
        run_task_time(**{**kw, "out": other, "policy": "random"})  # type: ignore[arg-type]
    (tmp_path / "episodes.jsonl").write_bytes(log)
    calls.clear()
    run_task_time(**{**kw, "force": True})  # type: ignore[arg-type]
    assert len(calls) == 2  # --force starts over: no episode of the earlier run is reused


def test_task_time_out_naming_a_file(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    (tmp_path / "f").write_text("x")
    assert main(["task-time", "--out", str(tmp_path / "f"), "--seeds", "1"]) == 2
    assert "existing file" in capsys.readouterr().err


def test_demo_refuses_to_overwrite_and_bad_seed(tmp_path: Path, monkeypatch, capsys) -> None:  # type: ignore[no-untyped-def]
    from mrexplore.experiments import demo

    monkeypatch.setattr(demo, "run_episode", _no_episodes)
    (tmp_path / "final.png").write_bytes(b"earlier")
    assert main(["demo", "--out", str(tmp_path)]) == 2
    assert "already exists" in capsys.readouterr().err
    assert main(["demo", "--out", str(tmp_path / "new"), "--seed", "-1"]) == 2
    assert "seed must be an integer >= 0" in capsys.readouterr().err
    assert (tmp_path / "final.png").read_bytes() == b"earlier"


def test_task_time_json_has_map_accuracy(tmp_path: Path) -> None:
    run_task_time(
        world="small_office",
        seeds=1,
        tasks=["explore"],
        out=tmp_path,
        progress=False,
        env_options={"max_time_s": 5.0},
    )
    data = json.loads((tmp_path / "task_time.json").read_text())
    for team in ("single", "multi"):
        entry = data["tasks"]["explore"][team]
        (c,) = entry["max_fused_contradiction"]
        assert isinstance(c, float) and 0.0 <= c < 0.05
        assert entry["merged_wrongly_s"] == [0.0]


@pytest.mark.expensive
def test_ray_workers_give_the_serial_results(tmp_path: Path) -> None:
    """2 seeds on 2 local Ray workers: the same task_time.json as the serial run."""
    pytest.importorskip("ray")
    kw = {
        "world": "small_office",
        "seeds": 2,
        "first_seed": 3,
        "policy": "nearest-frontier",
        "tasks": ("explore",),
        "env_options": {"max_time_s": 20.0, "aligned_headings": False},
        "progress": False,
    }
    serial = run_task_time(out=tmp_path / "serial", **kw)  # type: ignore[arg-type]
    parallel = run_task_time(out=tmp_path / "ray", workers=2, **kw)  # type: ignore[arg-type]
    assert parallel == serial
    for name in ("task_time.json", "task_time.csv"):
        assert (tmp_path / "ray" / name).read_bytes() == (tmp_path / "serial" / name).read_bytes()
    single = serial["tasks"]["explore"]["single"]
    assert len(single["task_times_s"]) == 2


def test_a_resumed_episode_keeps_every_field() -> None:
    # A log line read back must give the record the run produced (Ray results and resumed runs
    # go through it), map-accuracy and held-coverage fields included.
    r = _episode(12.5, first_merge=2.5, wrong_s=1.25, contradiction=0.004, held=14.0)
    r.merges_lost = 2
    back = task_time._episode_from_json(json.loads(json.dumps(task_time._episode_to_json(r))))
    assert back == r


# --- wrong merges in every output ------------------------------------------------------------


def _episode(
    time_s: float,
    first_merge: float | None = None,
    wrong_s: float = 0.0,
    contradiction: float = 0.01,
    held: float | None = None,
) -> TaskTimeEpisode:
    """A hand-made episode record (simulated s); ``wrong_s > 0``: it held a wrong merge."""
    return TaskTimeEpisode(
        task_time_s=time_s,
        success=True,
        coverage=0.95,
        times_s=[0.0, time_s],
        coverages=[0.2, 0.95],
        first_merge_time_s=first_merge,
        merge_error=None,
        collisions=0,
        max_fused_contradiction=contradiction,
        merged_wrongly_s=wrong_s,
        wrong_merge=wrong_s > 0,
        held_task_time_s=held,
        held_success=None if held is None else True,
        held_times_s=[] if held is None else [0.0, held],
        held_coverages=[] if held is None else [0.1, 0.95],
    )


def _runs(wrong_s: float) -> dict[str, dict[str, list[TaskTimeEpisode]]]:
    """Two seeds of exploration; the second team episode held a wrong merge ``wrong_s`` s."""
    return {
        "explore": {
            "single": [_episode(100.0, held=110.0), _episode(120.0, held=130.0)],
            "multi": [
                _episode(60.0, first_merge=20.0, held=70.0),
                _episode(50.0, first_merge=30.0, wrong_s=wrong_s, contradiction=0.25, held=150.0),
            ],
        }
    }


def test_a_wrong_merge_shows_in_table_csv_json_and_plot(tmp_path: Path) -> None:
    runs = _runs(wrong_s=12.5)
    doc = task_time._document(runs, "their.yaml", "coordinated-frontier", [7, 8], {})
    team = doc["tasks"]["explore"]["multi"]
    assert team["n_robots"] == 2
    assert team["merged_episodes"] == 2 and team["first_merge_median_s"] == 25.0
    assert team["wrong_merge"] == [False, True] and team["wrong_merge_episodes"] == 1
    assert team["merged_wrongly_s"] == [0.0, 12.5]
    assert team["merged_wrongly_sum_s"] == 12.5 and team["merged_wrongly_max_s"] == 12.5
    assert team["max_fused_contradiction_max"] == 0.25
    assert team["held_task_times_s"] == [70.0, 150.0] and team["held_mean"] == 110.0
    assert doc["tasks"]["explore"]["single"]["wrong_merge_episodes"] == 0
    assert doc["tasks"]["explore"]["held_reduction"] == pytest.approx(1 - 110.0 / 120.0)
    json.loads(json.dumps(doc, allow_nan=False))  # valid JSON, no NaN

    table = task_time.format_table(doc).splitlines()
    (row,) = [line for line in table if line.startswith("explore  2 robots")]
    assert " 2/2 " in row and " 25.0 " in row and " 1/2 " in row
    assert "12.5/12.5" in row and row.endswith("25.0%")
    assert "110.0 +- 40.0" in row  # the held time beside the observed one
    warning = table[-1]
    assert warning.startswith("WARNING: 1 of 4 episodes held a wrong merge")
    assert "explore 2 robots: 1 of 2, 12.5 s merged wrongly" in warning
    assert "include them" in warning
    assert "--sighting-range-m 4" in warning  # merged from the maps alone: the way out
    assert doc["wrong_merge_warning"] == warning
    seen = task_time._document(
        runs, "their.yaml", "coordinated-frontier", [7, 8], {"sighting_range_m": 4.0}
    )
    assert "--sighting-range-m" not in str(seen["wrong_merge_warning"])

    csv_path = tmp_path / "t.csv"
    task_time._write_csv(csv_path, runs, [7, 8])
    with csv_path.open() as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == list(task_time.CSV_COLUMNS)
    wrong = [r for r in rows if r["wrong_merge"] == "1"]
    assert [(r["team"], r["seed"], r["merged_wrongly_s"]) for r in wrong] == [
        ("multi", "8", "12.50")
    ]
    assert wrong[0]["max_fused_contradiction"] == "0.2500"
    assert wrong[0]["held_task_time_s"] == "150.00" and wrong[0]["held_success"] == "1"

    assert task_time._tick_label(doc, "explore").endswith("merged 2/2, wrong merge 1/2")
    pytest.importorskip("matplotlib")
    task_time._plot(tmp_path / "t.png", runs, doc)
    assert cv2.imread(str(tmp_path / "t.png")) is not None


def test_no_wrong_merge_no_warning() -> None:
    doc = task_time._document(_runs(wrong_s=0.0), "their.yaml", "p", [7, 8], {})
    assert doc["wrong_merge_warning"] is None
    # the plot says so too: a plot without a marker is not read as unchecked
    assert task_time._tick_label(doc, "explore").endswith("wrong merge 0/2")
    assert doc["tasks"]["explore"]["multi"]["wrong_merge_episodes"] == 0
    assert "WARNING" not in task_time.format_table(doc)


def test_navigation_has_no_held_time() -> None:
    runs = {"navigate": {"single": [_episode(30.0)], "multi": [_episode(20.0, first_merge=5.0)]}}
    doc = task_time._document(runs, "their.yaml", "p", [1], {})
    entry = doc["tasks"]["navigate"]
    assert entry["multi"]["held_task_times_s"] is None and entry["held_reduction"] is None
    (row,) = [r for r in task_time.format_table(doc).splitlines() if "2 robots" in r]
    assert "100%/-" in row


@pytest.mark.parametrize(
    ("world", "shown"),
    [
        ("symmetric_office", True),  # the shipped world built like the paper's
        (str(envs_dir() / "symmetric_office.yaml"), True),  # the same world as a path
        ("small_office", False),
        ("their.yaml", False),  # a user's world
        ("random:symmetric_office", False),
    ],
)
def test_the_paper_figures_only_on_the_paper_like_world(world: str, shown: bool) -> None:
    doc = task_time._document(_runs(0.0), world, "p", [7, 8], {})
    table = task_time.format_table(doc)
    assert ("seed paper" in table) is shown
    assert ("105 -> 65 s" in table) is shown
    assert (doc["tasks"]["explore"]["paper"] is not None) is shown


class _Sim:
    """The two things :class:`CoverageClock` reads of a simulator."""

    def __init__(self) -> None:
        self.time_s = 0.0
        self.observed = 0.3

    def coverage(self) -> float:
        return self.observed


def test_the_coverage_clock_times_both_coverages_and_waits_for_both() -> None:
    clock = CoverageClock().bind(EnvConfig(target_coverage=0.9))
    assert isinstance(clock, CoverageClock)
    sim = _Sim()
    rng = np.random.default_rng(0)
    clock.reset(sim, rng, rng, None)  # type: ignore[arg-type]
    # (time s, observed, held): observed reaches 0.9 at 2 s, held only at 4 s
    steps = [(1.0, 0.5, 0.4), (2.0, 0.9, 0.6), (3.0, 0.95, 0.8), (4.0, 0.97, 0.9)]
    ends = []
    for t, observed, held in steps:
        sim.time_s, sim.observed = t, observed
        ends.append(clock.terminated(sim, held))  # type: ignore[arg-type]
    assert ends == [False, False, False, True]
    assert clock.observed_time_s == 2.0 and clock.held_time_s == 4.0
    assert clock.observed_curve == [(0.0, 0.3), (1.0, 0.5), (2.0, 0.9)]
    clock.reset(sim, rng, rng, None)  # type: ignore[arg-type]
    assert clock.observed_time_s is None and clock.held_time_s is None


def test_an_exploration_episode_gives_the_observed_run_and_the_held_time() -> None:
    # Until the observed target the held-mode episode is the observed env's: same times, same
    # curve, same end; the held time comes on top.
    opts = {"world": "small_office", "n_robots": 2, "task": "explore", "max_time_s": 60.0}
    job: task_time.Job = ("explore", "multi", 1, {**opts, "coverage_mode": "held"})
    both = task_time.run_job("nearest-frontier", job)
    team = task_time.make_team("nearest-frontier", ["robot_0", "robot_1"], "explore")
    observed = run_episode(opts, team, 1)
    assert both.success and observed.success
    assert both.task_time_s == observed.task_time_s
    assert both.times_s == observed.times_s and both.coverages == observed.coverages
    # the merge figures cover the whole episode: a merge after the observed end is the held run's
    merge = both.first_merge_time_s
    if merge is not None and merge <= both.task_time_s:
        assert observed.first_merge_time_s == merge
    else:
        assert observed.first_merge_time_s is None
    assert both.held_task_time_s is not None and both.held_task_time_s >= both.task_time_s
    assert both.held_times_s[-1] == pytest.approx(both.held_task_time_s)
    assert both.held_coverages[-1] >= 0.95 or not both.held_success


def test_task_time_refuses_the_options_it_sets_itself(tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.setattr(task_time, "run_episode", _no_episodes)
    with pytest.raises(ConfigError, match=r"\['coverage_mode'\] are set by the experiment"):
        run_task_time(
            world="small_office",
            out=tmp_path,
            env_options={"coverage_mode": "observed"},
            progress=False,
        )


class _Stop(Exception):
    """Raised by :func:`_capture_env_options` in place of the first episode."""


def _capture_env_options(monkeypatch: pytest.MonkeyPatch) -> list[dict[str, object]]:
    """Make ``task-time``'s first episode record its env options and stop the run."""
    seen: list[dict[str, object]] = []

    def capture(env_options: dict[str, object], *args: object, **kwargs: object) -> None:
        seen.append(env_options)
        raise _Stop

    monkeypatch.setattr(task_time, "run_episode", capture)
    return seen


def test_task_time_sighting_range_reaches_every_episode(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``--sighting-range-m`` turns sightings on in every episode's env (off without it)."""
    seen = _capture_env_options(monkeypatch)
    for extra, want in (["--sighting-range-m", "4"], 4.0), ([], None):
        with pytest.raises(_Stop):
            main(["task-time", "--world", "small_office", "--seeds", "1", "--out",
                  str(tmp_path / str(want)), *extra])  # fmt: skip
        assert seen[-1].get("sighting_range_m") == want


def test_task_time_rendezvous_only_reaches_every_episode(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--rendezvous-only`` sets the tracker's ``rendezvous_only`` in every episode's env, and
    without ``--sighting-range-m`` it is refused at the door naming the flag."""
    seen = _capture_env_options(monkeypatch)
    argv = ["task-time", "--world", "small_office", "--seeds", "1", "--rendezvous-only"]
    with pytest.raises(_Stop):
        main([*argv, "--sighting-range-m", "4", "--out", str(tmp_path / "a")])
    assert [o.get("merge_options") for o in seen] == [{"rendezvous_only": True}]
    assert main([*argv, "--out", str(tmp_path / "b")]) == 2
    assert "give --sighting-range-m" in capsys.readouterr().err
    assert not (tmp_path / "b").exists()


def test_the_table_says_how_the_teams_merged() -> None:
    """The merge mode in words, from the run's options: the maps alone by default, only robots
    that met with sightings (unless ``rendezvous_only`` is off), none without a merger."""
    mode = task_time.merging_mode
    assert mode({}).startswith("from the maps alone")
    assert mode({"sighting_range_m": 4.0}).startswith("only robots that have met")
    off = {"sighting_range_m": 4.0, "merge_options": {"rendezvous_only": False}}
    assert "never met" in mode(off)
    assert mode({"merger": None}).startswith("none")
    doc = task_time._document(_runs(0.0), "w.yaml", "coordinated-frontier", [7, 8], {})
    assert task_time.format_table(doc).splitlines()[1] == f"merging: {mode({})}"
