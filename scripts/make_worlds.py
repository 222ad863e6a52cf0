#!/usr/bin/env python
"""Regenerate the ready worlds in ``envs/`` (seeded: rerunning writes the same bytes).

Usage: ``python scripts/make_worlds.py [--out envs] [--preview DIR] [--bench N]``

Generated worlds (``symmetric_office``, ``twin_wings``, ``small_office``,
``symmetric_office_coarse``) are drawn from fixed seeds; the real maps (``tb3_office``, ``depot``)
are copied from ``/work/shared/maps`` (or ``--maps``) with their licences. ``--preview`` also writes
a PNG per world with the twin rooms outlined (red = first, blue = second), for a visual check.
``--bench N`` only times N generations (seeds 0..N-1) of each generated world and prints figures.
"""

from __future__ import annotations

import argparse
import shutil
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from mrexplore.world import World, symmetric_office, twin_wings, world_from_file, world_to_file

ROOT = Path(__file__).resolve().parents[1]

#: name -> (generator, seed, options). Seeds are fixed so the files are reproducible.
GENERATED: dict[str, tuple[Callable[..., World], int, dict[str, Any]]] = {
    "symmetric_office": (symmetric_office, 20260101, {"width_m": 20.0, "height_m": 16.0}),
    "twin_wings": (twin_wings, 20260102, {"width_m": 20.0, "height_m": 20.0}),
    "small_office": (symmetric_office, 20260103, {"width_m": 10.0, "height_m": 8.0}),
    # Explore-Bench's grid env settings: 250 x 250 cells at 0.1 m/cell.
    "symmetric_office_coarse": (
        symmetric_office,
        20260104,
        {"width_m": 25.0, "height_m": 25.0, "resolution_m": 0.1},
    ),
}

#: name -> (source YAML relative to the maps folder, licence file name in envs/).
COPIED: dict[str, tuple[str, str]] = {
    "tb3_office": ("turtlebot3/office_raw.yaml", "LICENSE.turtlebot3"),
    "depot": ("nav2/depot.yaml", "LICENSE.nav2"),
}


def copy_map(src_yaml: Path, out_dir: Path, name: str) -> Path:
    """Copy a map_server pair as ``name.yaml`` + ``name.<ext>``: image bytes unchanged, YAML
    unchanged except its ``image:`` line, which names the renamed image."""
    lines = src_yaml.read_text(encoding="utf-8").splitlines(keepends=True)
    image_line = next(i for i, line in enumerate(lines) if line.startswith("image:"))
    src_image = src_yaml.parent / lines[image_line].split(":", 1)[1].strip()
    dst_image = out_dir / f"{name}{src_image.suffix}"
    shutil.copyfile(src_image, dst_image)
    lines[image_line] = f"image: {dst_image.name}\n"
    dst_yaml = out_dir / f"{name}.yaml"
    dst_yaml.write_text("".join(lines), encoding="utf-8")
    return dst_yaml


def preview(world: World, path: Path, scale: int = 2) -> None:
    """PNG of the world (walls black), twin rooms outlined, row 0 at the bottom as on a map."""
    img = cv2.cvtColor(np.where(world.walls, 0, 255).astype(np.uint8), cv2.COLOR_GRAY2BGR)
    for k, (c, r, w, h) in enumerate(world.meta.get("twin_rooms", [])):
        cv2.rectangle(
            img, (c, r), (c + w - 1, r + h - 1), (0, 0, 255) if k == 0 else (255, 0, 0), 1
        )
    img = cv2.resize(img[::-1], None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST)
    cv2.imwrite(str(path), img)


def bench(n: int) -> None:
    """Print generation time (ms) and redraw attempts over seeds 0..n-1 of each generated world."""
    print(
        f"{'world':24s} {'cells':>11s} {'mean ms':>8s} {'median':>7s} {'max':>7s} {'attempts':>9s}"
    )
    for name, (gen, _, opts) in GENERATED.items():
        times, attempts = [], []
        for seed in range(n):
            t0 = time.perf_counter()
            world = gen(np.random.default_rng(seed), **opts)
            times.append((time.perf_counter() - t0) * 1e3)
            attempts.append(world.meta["seed_info"]["attempts"])
        cells = f"{world.shape[1]}x{world.shape[0]}"
        print(
            f"{name:24s} {cells:>11s} {np.mean(times):8.1f} {np.median(times):7.1f} "
            f"{np.max(times):7.1f} {np.mean(attempts):9.2f}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "envs")
    parser.add_argument(
        "--maps", type=Path, default=Path(__file__).resolve().parents[2] / "shared" / "maps"
    )
    parser.add_argument("--preview", type=Path, default=None)
    parser.add_argument("--bench", type=int, default=0, metavar="N")
    args = parser.parse_args()
    if args.bench:
        bench(args.bench)
        return
    args.out.mkdir(parents=True, exist_ok=True)
    if args.preview:
        args.preview.mkdir(parents=True, exist_ok=True)

    for name, (gen, seed, opts) in GENERATED.items():
        t0 = time.perf_counter()
        world = gen(np.random.default_rng(seed), **opts)
        dt_ms = (time.perf_counter() - t0) * 1e3
        meta = dict(world.meta, seed=seed)
        world = World(world.walls, world.resolution_m, world.origin_m, name, meta)
        path = world_to_file(world, args.out / f"{name}.yaml")
        w_m, h_m = world.size_m
        print(
            f"{name:24s} {world.shape[1]:4d} x {world.shape[0]:4d} cells  "
            f"{w_m:5.1f} x {h_m:5.1f} m  "
            f"{world.resolution_m} m/cell  generated in {dt_ms:6.1f} ms -> {path.name}"
        )
        if args.preview:
            preview(world, args.preview / f"{name}.png", 2 if world.shape[1] < 500 else 1)

    for name, (src, licence) in COPIED.items():
        src_yaml = args.maps / src
        path = copy_map(src_yaml, args.out, name)
        shutil.copyfile(src_yaml.parent / "LICENSE", args.out / licence)
        world = world_from_file(path, name=name)
        w_m, h_m = world.size_m
        print(
            f"{name:24s} {world.shape[1]:4d} x {world.shape[0]:4d} cells  "
            f"{w_m:5.1f} x {h_m:5.1f} m  "
            f"{world.resolution_m} m/cell  copied from {src}"
        )
        if args.preview:
            preview(world, args.preview / f"{name}.png", 1)


if __name__ == "__main__":
    main()
