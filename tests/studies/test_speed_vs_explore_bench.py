"""``studies/speed_vs_explore_bench.py`` without Explore-Bench: clear errors, the import shims on a
fake checkout, and the round alternation over fake step functions (nothing here is timed)."""

from __future__ import annotations

import importlib.util
import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "studies" / "speed_vs_explore_bench.py"


@pytest.fixture(scope="module")
def bench() -> Iterator[ModuleType]:
    name = "speed_vs_explore_bench"
    spec = importlib.util.spec_from_file_location(name, SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up while the script runs
    try:
        spec.loader.exec_module(module)
        yield module
    finally:
        del sys.modules[name]


def fake_checkout(root: Path, grid_env_source: str) -> Path:
    """A folder laid out like an Explore-Bench checkout, with our own GridEnv.py."""
    folder = root / "onpolicy" / "onpolicy" / "envs" / "GridEnv"
    (folder / "datasets").mkdir(parents=True)
    (folder / "datasets" / "room1_modified.pgm").write_bytes(b"P5\n1 1\n255\n\xfe")
    (folder / "Astar.py").write_text("class AStar:\n    pass\n")
    (folder / "GridEnv.py").write_text(grid_env_source)
    return root


# Uses every shimmed name the way theirs does: relative imports of window and Astar, gym.Env and
# gym.spaces, and reset() reading a hard-coded folder through os.listdir / os.path.join.
FAKE_GRID_ENV = """
import os
import gym
from .window import Window
from .Astar import AStar

class GridEnv(gym.Env):
    def __init__(self):
        self.space = gym.spaces.Box(low=0.0, high=1.0, shape=(2,))
        self.window = Window("map")
        self.window.show(block=False)

    def reset(self):
        d = '/home/nics/git_ws/src/onpolicy/onpolicy/envs/GridEnv/datasets'
        name = os.listdir(d)[0]
        with open(os.path.join(d, name), 'rb') as f:
            return f.read()
"""


def test_not_a_folder_is_a_clear_error(bench: ModuleType, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    assert bench.main(["--explore-bench", str(tmp_path / "nope")]) == 2
    err = capsys.readouterr().err
    assert "no such folder" in err and "git clone https://github.com/efc-robot/Explore-Bench" in err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_not_a_checkout_is_a_clear_error(bench: ModuleType, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    assert bench.main(["--explore-bench", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "not an Explore-Bench checkout" in err and "GridEnv.py" in err
    assert bench.EB_COMMIT[:7] in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize(
    ("source", "words"),
    [
        ("import no_such_package_for_this_test\n", "ModuleNotFoundError"),
        ("import sys\nsys.exit(-1)\n", "SystemExit"),  # their window.py exits this way
        ("x = 1\n", "defines no GridEnv class"),
    ],
)
def test_failed_import_is_a_clear_error(  # type: ignore[no-untyped-def]
    bench: ModuleType, tmp_path: Path, capsys, source: str, words: str
) -> None:
    had_gym = "gym" in sys.modules
    assert bench.main(["--explore-bench", str(fake_checkout(tmp_path, source))]) == 2
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert ("gym" in sys.modules) == had_gym  # no gym alias left behind


def test_shims_serve_what_the_grid_env_imports(bench: ModuleType, tmp_path: Path) -> None:
    folder = bench.find_grid_env(fake_checkout(tmp_path, FAKE_GRID_ENV))
    module = bench.load_grid_env(folder)
    env = module.GridEnv()  # gym.Env, gym.spaces and the no-op Window resolve
    assert env.reset() == (folder / "datasets" / "room1_modified.pgm").read_bytes()


def test_existing_json_is_not_overwritten(bench: ModuleType, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "r.json"
    out.write_text("earlier")
    assert bench.main(["--explore-bench", str(tmp_path), "--json", str(out)]) == 2
    assert "already exists" in capsys.readouterr().err
    assert out.read_text() == "earlier"


class FakeClock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_rounds_alternate_and_ratios_are_medians_of_rounds(bench: ModuleType) -> None:
    clock, calls = FakeClock(), []

    def side(name: str, cost: list[float], steps: int):  # type: ignore[no-untyped-def]
        costs = iter(cost)

        def step(action: int) -> None:
            calls.append(name)
            clock.now += next(costs)

        return bench.Side(name, lambda: 0, step, steps)

    # theirs: 2 steps per round; ours: 4; per-round costs make round 2 an outlier for "ours"
    theirs = side("theirs", [0.05] * 2 + [0.05] * 2 + [0.05] * 2, 2)
    ours = side("ours", [0.001] * 4 + [0.01] * 4 + [0.001] * 4, 4)
    rates = bench.alternate([theirs, ours], rounds=3, clock=clock, proc_clock=clock)
    assert (
        calls
        == ["theirs"] * 2
        + ["ours"] * 4
        + ["ours"] * 4
        + ["theirs"] * 2
        + ["theirs"] * 2
        + ["ours"] * 4
    )
    assert rates["theirs"]["thread"] == pytest.approx([20.0, 20.0, 20.0])
    assert rates["ours"]["thread"] == pytest.approx([1000.0, 100.0, 1000.0])
    s = bench.summarize(rates, "theirs")
    assert s["ours"]["steps_per_s"] == pytest.approx(1000.0)
    assert s["ours"]["ratio"] == pytest.approx(50.0)
    assert s["theirs"]["ratio"] == pytest.approx(1.0)
    assert s["ours"]["ms_per_step"] == pytest.approx(1.0)
