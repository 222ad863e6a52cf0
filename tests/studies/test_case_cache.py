"""The merge bench's case cache: the same cases whether made or read back; a change of code,
family, seed or options misses; a bad directory is refused at the door."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mrexplore.cli import main
from mrexplore.errors import ConfigError
from mrexplore.studies import case_cache, merge_bench
from mrexplore.studies.case_cache import cached_cases, check_cache_dir
from mrexplore.studies.merge_bench import make_cases, run_bench


def _same(a: list, b: list) -> bool:  # type: ignore[type-arg]
    return len(a) == len(b) and all(
        x.name == y.name
        and np.array_equal(x.a, y.a)
        and np.array_equal(x.b, y.b)
        and np.array_equal(x.T_ab, y.T_ab)
        and x.overlap == y.overlap
        and x.meta == y.meta
        for x, y in zip(a, b, strict=True)
    )


def _never() -> list:  # type: ignore[type-arg]
    raise AssertionError("the cache should have answered")


def test_a_hit_gives_the_cases_made_and_a_changed_key_misses(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    made = make_cases("real", 2, 3)
    first = cached_cases(tmp_path, "real", 2, 3, None, lambda: made)
    assert first is made and len(list(tmp_path.glob("*.pkl"))) == 1
    assert _same(cached_cases(tmp_path, "real", 2, 3, None, _never), made)
    calls: list[int] = []

    def counted() -> list:  # type: ignore[type-arg]
        calls.append(1)
        return made

    cached_cases(tmp_path, "real", 2, 4, None, counted)  # another seed
    cached_cases(tmp_path, "real", 2, 3, {"map_l_occ": 1.4}, counted)  # other options
    monkeypatch.setattr(case_cache, "source_digest", lambda: "other code")
    cached_cases(tmp_path, "real", 2, 3, None, counted)  # the same key under other code
    assert len(calls) == 3  # and no temporary file is left behind
    assert all(f.suffix == ".pkl" and not f.name.startswith(".") for f in tmp_path.iterdir())


def test_rows_are_the_same_with_the_cache_and_read_back(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    kw = {"methods": ["semantic"], "families": ["real"], "seeds": [1, 2]}
    plain = run_bench(2, **kw)  # type: ignore[arg-type]
    cached = run_bench(2, case_cache=tmp_path, **kw)  # type: ignore[arg-type]
    monkeypatch.setattr(merge_bench, "real_cases", lambda n, seed: _never())
    again = run_bench(2, case_cache=tmp_path, **kw)  # type: ignore[arg-type]
    for rows in (cached, again):
        for r, p in zip(rows, plain, strict=True):
            assert {k: v for k, v in r.items() if "ms" not in k and k != "cases"} == {
                k: v for k, v in p.items() if "ms" not in k and k != "cases"
            }
            assert [{k: v for k, v in c.items() if k != "ms"} for c in r["cases"]] == [
                {k: v for k, v in c.items() if k != "ms"} for c in p["cases"]
            ]


def test_a_bad_cache_directory_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    f = tmp_path / "file"
    f.write_text("mine")
    with pytest.raises(ConfigError, match="is a file, not a directory"):
        check_cache_dir(f)
    assert main(["bench", "merge", "--n", "1", "--families", "real", "--case-cache", str(f)]) == 2
    assert "--case-cache" in capsys.readouterr().err and f.read_text() == "mine"
    made = check_cache_dir(tmp_path / "new" / "dir")
    assert made.is_dir() and made.stat().st_mode & 0o777 == 0o700
    shared = tmp_path / "shared"
    shared.mkdir(mode=0o777)
    shared.chmod(0o777)
    with pytest.raises(ConfigError, match="no one else may write"):
        check_cache_dir(shared)


def test_a_damaged_entry_is_a_miss_and_is_written_again(tmp_path: Path) -> None:
    made = make_cases("real", 1, 0)
    cached_cases(tmp_path, "real", 1, 0, None, lambda: made)
    (entry,) = tmp_path.glob("*.pkl")
    entry.write_bytes(entry.read_bytes()[:20])  # cut short
    assert cached_cases(tmp_path, "real", 1, 0, None, lambda: made) is made
    assert _same(cached_cases(tmp_path, "real", 1, 0, None, _never), made)


def test_lidar_options_key_only_the_lidar_family(tmp_path: Path) -> None:
    """``--lidar-options`` change the lidar family's maps only: the other families' cases are
    the same entry with them or without."""
    plain = make_cases("real", 1, 0, None, tmp_path)
    with_options = make_cases("real", 1, 0, {"map_l_occ": 1.4}, tmp_path)
    assert _same(plain, with_options) and len(list(tmp_path.glob("*.pkl"))) == 1
