"""Safe outputs for every command: never overwrite an input or an earlier result by accident.

Two rules, one place (every command that writes files uses these helpers, not a copy):

1. **Refuse before any work.** :func:`check_outputs` refuses an output path that is one of the
   command's inputs (a map YAML, the image it names), or that already exists, unless the user
   said ``force=True`` (``--force``). :func:`check_out_dir` does the same for an output folder:
   a folder that exists and is not empty is refused without ``force``; a path naming a file is
   always refused.
2. **No half-written files.** :func:`atomic_path` yields a temporary name beside the target (same
   folder, same suffix, so encoders that choose the format by extension still work); the target
   is replaced only when the writer finished without an exception (``os.replace`` is atomic on
   one file system). An interrupted run leaves the old file or nothing, never a truncated one.
"""

from __future__ import annotations

import contextlib
import os
import uuid
from collections.abc import Iterable, Iterator
from pathlib import Path

from mrexplore.errors import OutputExistsError


def _same(a: Path, b: Path) -> bool:
    """Whether two paths name the same file (resolving links, ``..`` and case-insensitive FS)."""
    try:
        if a.exists() and b.exists():
            return a.samefile(b)
    except OSError:  # pragma: no cover - unreadable paths: compare names
        pass
    return a.expanduser().resolve() == b.expanduser().resolve()


def check_outputs(
    outputs: Iterable[str | Path],
    inputs: Iterable[str | Path] = (),
    force: bool = False,
    what: str = "output",
) -> None:
    """Refuse outputs that would destroy an input or an existing file (unless ``force``).

    Args:
        outputs: every file the command will write.
        inputs: every file the command reads (never overwritten without ``force``).
        force: the user's ``--force``: allow replacing existing files, inputs included (the
            inputs are read completely before anything is written).
        what: the command's name for messages.

    Raises:
        OutputExistsError: an output is an input, an existing file (without ``force``), or an
            existing folder (always: a folder is never replaced by a file).
    """
    ins = [Path(p) for p in inputs]
    for out in (Path(p) for p in outputs):
        if out.is_dir():
            raise OutputExistsError(f"{what}: {out} is a folder; give a file name")
        if force:
            continue
        for inp in ins:
            if _same(out, inp):
                raise OutputExistsError(
                    f"{what}: would overwrite the input {inp}; choose another output name "
                    "(or pass --force)"
                )
        if out.exists():
            raise OutputExistsError(
                f"{what}: {out} already exists; choose another output name or pass --force"
            )


def check_out_dir(
    folder: str | Path,
    force: bool = False,
    what: str = "output",
    protect: Iterable[str | Path] = (),
) -> Path:
    """Refuse an output folder that is a file, one of ``protect`` or a non-empty folder.

    ``protect`` lists folders that must never receive results (e.g. a policy folder being
    evaluated); they are refused even with ``force``. Creates nothing; returns ``Path(folder)``.

    Raises:
        OutputExistsError: ``folder`` names a file, a protected folder, or a non-empty folder
            (without ``force``).
    """
    path = Path(folder)
    if path.exists() and not path.is_dir():
        raise OutputExistsError(f"{what}: --out {path} is an existing file, not a folder")
    for p in protect:
        if path.exists() and Path(p).exists() and _same(path, Path(p)):
            raise OutputExistsError(
                f"{what}: will not write into {path} (it is an input); choose another --out"
            )
    if not force and path.is_dir() and any(path.iterdir()):
        raise OutputExistsError(
            f"{what}: {path} exists and is not empty; choose another --out or pass --force "
            "to replace its files"
        )
    return path


@contextlib.contextmanager
def atomic_path(target: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``target``; rename it to ``target`` on success.

    The temporary name keeps ``target``'s suffix (``.png``, ``.zip``, ...), so writers that pick
    the format from it behave the same. On an exception the temporary file is removed and
    ``target`` is left as it was.
    """
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = target.with_name(f".{target.stem}.tmp-{uuid.uuid4().hex[:8]}{target.suffix}")
    try:
        yield tmp
        os.replace(tmp, target)
    finally:
        if tmp.exists():
            tmp.unlink()


def write_text(target: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``target`` through a temporary file; returns ``target``."""
    with atomic_path(target) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(target)


def write_bytes(target: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``target`` through a temporary file; returns ``target``."""
    with atomic_path(target) as tmp:
        tmp.write_bytes(data)
    return Path(target)
