"""``mrexplore merge a.yaml b.yaml -o merged.yaml``: merge two ROS map_server maps from files.

Writes the merged map (YAML + PGM, in a's frame, canvas grown as needed, origin shifted so the
world coordinates of a's cells are unchanged) and a PNG beside it (``merged.png``) with the two
inputs side by side, each captioned with its file name, the matched points joined by lines
(like the seed paper's Figure 6), the outcome in words (transform and score, or the refusal and
its reason), the fused map when merged, and a legend of the colours. Prints the transform and
the score, or says plainly that no reliable match was found; when the refusal is an ambiguity
(look-alike places), it also prints the best pose and its rivals with their agreement, so a
user who knows where the maps overlap can tell which is right.

Exit codes: **0** merged, **1** refused (no reliable match: a clean, expected outcome, but one a
script must be able to tell apart), **2** bad input (missing or malformed file, different
resolutions, bad option).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from mrexplore.errors import ConfigError, MapFileError, MrexploreError
from mrexplore.grid import Int8Grid, affine_inverse, chain, make_transform, transform_angle
from mrexplore.io_safety import check_outputs, write_bytes
from mrexplore.merge import MergeResult, PosePrior, merge_maps
from mrexplore.merge.common import to_gray, translation
from mrexplore.world.map_io import OccupancyFile


def merge_files(
    a_yaml: str | Path,
    b_yaml: str | Path,
    out_yaml: str | Path,
    method: str = "semantic",
    detector: str | None = None,
    force: bool = False,
    prior_m: Sequence[float] | None = None,
    prior_radius_m: float = 2.0,
    prior_turn_deg: float = 10.0,
    **options: Any,
) -> MergeResult:
    """Merge map file b into map file a; write ``out_yaml`` (+ image) and a PNG figure when matched.

    The outputs (``out_yaml``, its ``.pgm`` image and the ``.png`` figure) are checked before any
    work: none may be an input (a YAML or the image it names) or an existing file unless
    ``force``. ``min_common_m2`` and ``min_wall_area_m2`` are measured at the maps' own
    resolution (from the YAML).

    ``prior_m``: a rough guess ``(x_m, y_m, yaw_deg)`` of b's map frame in a's (a point at
    ``p`` in b's frame lies at ``R(yaw) p + (x, y)`` in a's; ``(0, 0, 0)`` when both maps were
    built in one frame), believed within ``prior_radius_m`` and ``prior_turn_deg``: only poses
    near it are considered (:class:`~mrexplore.merge.PosePrior`, semantic method only).

    Raises:
        MapFileNotFoundError / MapFileError: a file is missing or malformed, or the two maps'
            resolutions differ (the merger works in cells: it cannot rescale).
        OutputExistsError: an output would overwrite an input or an existing file.
        ConfigError: bad method, detector or option.
    """
    from mrexplore.world.map_io import read_map_yaml, write_map_yaml

    out_yaml = Path(out_yaml)
    png = out_yaml.with_suffix(".png")
    fa, fb = read_map_yaml(a_yaml), read_map_yaml(b_yaml)
    check_outputs(
        [out_yaml, out_yaml.with_suffix(".pgm"), png],
        inputs=[p for p in (fa.path, fb.path, fa.image_path, fb.image_path) if p is not None],
        force=force,
        what="mrexplore merge",
    )
    if not np.isclose(fa.resolution_m, fb.resolution_m, rtol=1e-6, atol=0.0):
        raise MapFileError(
            f"maps have different resolutions: {fa.path.name} {fa.resolution_m} m/cell, "
            f"{fb.path.name} {fb.resolution_m} m/cell; resample one first"
        )
    if detector is not None:
        options["detector"] = detector
    if prior_m is not None:
        if method.lower() != "semantic":
            raise ConfigError(f"--prior works with the semantic method only, not {method!r}")
        options["prior"] = file_prior(fa, fb, prior_m, prior_radius_m, prior_turn_deg)
    res = merge_maps(fa.grid, fb.grid, method=method, resolution_m=fa.resolution_m, **options)
    if res.matched and res.merged is not None:
        dc, dr = res.offset
        ox, oy, yaw = fa.origin_m
        origin = (ox - dc * fa.resolution_m, oy - dr * fa.resolution_m, yaw)
        write_map_yaml(out_yaml, res.merged, fa.resolution_m, origin)
    img = figure(fa.grid, fb.grid, res, a_name=Path(a_yaml).name, b_name=Path(b_yaml).name)
    ok, encoded = cv2.imencode(".png", img)
    if ok:
        write_bytes(png, encoded.tobytes())
    return res


def _cells_to_frame(f: OccupancyFile) -> NDArray[np.float64]:
    """3x3: a map file's cell (col, row) centre -> its map frame (metres), from its origin
    (lower-left corner of cell (0, 0), yaw about it) and resolution."""
    ox, oy, yaw = f.origin_m
    res = float(f.resolution_m)
    scale = np.diag([res, res, 1.0])
    return chain(make_transform(float(yaw), float(ox), float(oy)), scale, translation(0.5, 0.5))


def file_prior(
    fa: OccupancyFile,
    fb: OccupancyFile,
    prior_m: Sequence[float],
    radius_m: float,
    turn_deg: float,
) -> PosePrior:
    """The :class:`~mrexplore.merge.PosePrior` in cells for a guess ``(x_m, y_m, yaw_deg)`` of
    b's map frame in a's (see :func:`merge_files`)."""
    vals = [float(v) for v in prior_m]
    if len(vals) != 3 or not all(np.isfinite(vals)):
        raise ConfigError(f"--prior must be three finite numbers x_m,y_m,yaw_deg, got {prior_m!r}")
    if not (np.isfinite(radius_m) and radius_m > 0 and np.isfinite(turn_deg) and turn_deg > 0):
        raise ConfigError(
            f"--prior-radius-m and --prior-turn-deg must be > 0, got {radius_m!r}, {turn_deg!r}"
        )
    frame = make_transform(np.radians(vals[2]), vals[0], vals[1])
    T = chain(affine_inverse(_cells_to_frame(fa)), frame, _cells_to_frame(fb))
    return PosePrior(T, radius_m / float(fa.resolution_m), turn_deg)


def _panel(grid: Int8Grid) -> NDArray[np.uint8]:
    """BGR image of a map with row 0 at the bottom (flipped for display)."""
    return cv2.cvtColor(to_gray(grid)[::-1].copy(), cv2.COLOR_GRAY2BGR)


_FONT = cv2.FONT_HERSHEY_SIMPLEX
_TEXT_SCALE = 0.45
_LINE_PX = 18  # one text line's height at _TEXT_SCALE
_MIN_WIDTH_PX = 480  # small maps: the captions still get a readable line length
_REFUSED = (0, 0, 200)  # BGR red: the refusal's words


def figure_labels(
    res: MergeResult,
    a_name: str = "a",
    b_name: str = "b",
    resolution_m: float | None = None,
    max_lines: int = 40,
) -> dict[str, str]:
    """The words of :func:`figure`: what each panel is, what the lines are and the outcome.

    Keys: ``"a"`` and ``"b"`` (the two input panels), ``"matches"`` (the lines between them),
    ``"result"`` (the panel below: the fused map with the transform and score, or the refusal
    and its reason). ``resolution_m`` (m/cell) adds the translation in metres; by default it is
    read from ``res.info`` (set by :func:`~mrexplore.merge.merge_maps`).
    """
    if resolution_m is None and "resolution_m" in (res.info or {}):
        resolution_m = float(res.info["resolution_m"])
    n = len(res.matches)
    shown = min(n, max_lines)
    if n == 0:
        matches = "no matched points to draw"
    else:
        whose = "supporting the merge" if res.matched else "of the best pose weighed (refused)"
        matches = f"lines: {shown} of {n} matched point pairs a <-> b {whose} (one colour per pair)"
    method = res.method or "?"
    if res.matched and res.transform is not None:
        T = res.transform
        deg = round(float(np.degrees(transform_angle(T))), 2) + 0.0  # + 0.0: no "-0.00"
        tx, ty = round(float(T[0, 2]), 1) + 0.0, round(float(T[1, 2]), 1) + 0.0
        move = f"translation ({tx:.1f}, {ty:.1f}) cells"
        if resolution_m is not None:
            move += f" = ({tx * resolution_m:.2f}, {ty * resolution_m:.2f}) m"
        result = (
            f"below: the fused result (a + b in a's frame): MERGED by the {method} method, "
            f"score {res.score:.3f}; b -> a: rotation {deg:.2f} deg, {move}"
        )
    else:
        result = (
            f"below: no fused result: REFUSED by the {method} method (best score "
            f"{res.score:.3f}): {res.reason or 'no reliable match'}"
        )
    return {
        "a": f"a: {a_name} (reference; the result is in its frame)",
        "b": f"b: {b_name} (the map to merge into a)",
        "matches": matches,
        "result": result,
    }


def _wrap(text: str, width_px: int) -> list[str]:
    """``text`` in lines no wider than ``width_px`` at the figure's font (a longer word alone)."""
    lines: list[str] = []
    for word in text.split():
        line = f"{lines[-1]} {word}" if lines else word
        if lines and cv2.getTextSize(line, _FONT, _TEXT_SCALE, 1)[0][0] <= width_px:
            lines[-1] = line
        else:
            lines.append(word)
    return lines or [""]


def _text_bar(text: str, width: int, colour: tuple[int, int, int] = (0, 0, 0)) -> NDArray[np.uint8]:
    """A white bar ``width`` px wide holding ``text``, wrapped to fit."""
    lines = _wrap(text, width - 12)
    bar = np.full((len(lines) * _LINE_PX + 6, width, 3), 255, dtype=np.uint8)
    for i, line in enumerate(lines):
        y = 4 + (i + 1) * _LINE_PX - 5
        cv2.putText(bar, line, (6, y), _FONT, _TEXT_SCALE, colour, 1, cv2.LINE_AA)
    return bar


def _legend(width: int) -> NDArray[np.uint8]:
    """The colours: the maps' three values (map_server gray) and a matched pair's mark."""
    items = [(254, "free"), (0, "occupied"), (205, "unknown")]
    bar = np.full((_LINE_PX + 10, width, 3), 255, dtype=np.uint8)
    y0, x = 5, 6
    cv2.putText(bar, "legend:", (x, y0 + 12), _FONT, _TEXT_SCALE, (0, 0, 0), 1, cv2.LINE_AA)
    x += 70
    for gray, label in items:
        cv2.rectangle(bar, (x, y0), (x + 13, y0 + 13), (gray, gray, gray), -1)
        cv2.rectangle(bar, (x, y0), (x + 13, y0 + 13), (90, 90, 90), 1)
        cv2.putText(bar, label, (x + 18, y0 + 12), _FONT, _TEXT_SCALE, (0, 0, 0), 1, cv2.LINE_AA)
        x += 18 + cv2.getTextSize(label, _FONT, _TEXT_SCALE, 1)[0][0] + 14
    col = (40, 120, 200)
    cv2.circle(bar, (x + 4, y0 + 7), 3, col, 1)
    cv2.line(bar, (x + 4, y0 + 7), (x + 24, y0 + 7), col, 1, cv2.LINE_AA)
    cv2.circle(bar, (x + 24, y0 + 7), 3, col, 1)
    cv2.putText(
        bar, "a matched pair", (x + 32, y0 + 12), _FONT, _TEXT_SCALE, (0, 0, 0), 1, cv2.LINE_AA
    )
    return bar


def _stack(rows: Sequence[NDArray[np.uint8]], width: int) -> NDArray[np.uint8]:
    """``rows`` one above the other, left-aligned on a white canvas ``width`` px wide."""
    out = np.full((sum(r.shape[0] for r in rows), width, 3), 255, dtype=np.uint8)
    y = 0
    for r in rows:
        out[y : y + r.shape[0], : r.shape[1]] = r
        y += r.shape[0]
    return out


def figure(
    a: Int8Grid,
    b: Int8Grid,
    res: MergeResult,
    max_lines: int = 40,
    a_name: str = "a",
    b_name: str = "b",
    resolution_m: float | None = None,
) -> NDArray[np.uint8]:
    """BGR image (H, W, 3 uint8): a caption per input, [a | b] with matched points joined by
    lines, the outcome in words (transform and score, or the refusal's reason), the fused map
    when merged, and a legend of the colours. The words are :func:`figure_labels`'."""
    labels = figure_labels(res, a_name, b_name, resolution_m, max_lines)
    pa, pb = _panel(a), _panel(b)
    h = max(pa.shape[0], pb.shape[0])
    gap = 10
    top = np.full((h, pa.shape[1] + gap + pb.shape[1], 3), 255, dtype=np.uint8)
    top[h - pa.shape[0] :, : pa.shape[1]] = pa
    top[h - pb.shape[0] :, pa.shape[1] + gap :] = pb
    m = res.matches[:max_lines] if res.matches.size else np.zeros((0, 4))
    rng = np.random.default_rng(0)  # fixed colours, figure only
    for ca, ra, cb, rb in m:
        col = tuple(int(x) for x in rng.integers(0, 200, 3))
        p1 = (round(ca), round(h - 1 - ra))
        p2 = (round(cb) + pa.shape[1] + gap, round(h - 1 - rb))
        cv2.circle(top, p1, 3, col, 1)
        cv2.circle(top, p2, 3, col, 1)
        cv2.line(top, p1, p2, col, 1, cv2.LINE_AA)
    merged = res.matched and res.merged is not None
    bottom = _panel(res.merged) if merged and res.merged is not None else None
    width = max(top.shape[1], 0 if bottom is None else bottom.shape[1], _MIN_WIDTH_PX)
    # the input captions: "left"/"right" name the panel even when a name is wider than it
    rows = [
        _text_bar(f"left, {labels['a']}", width),
        _text_bar(f"right, {labels['b']}", width),
        top,
        _text_bar(labels["matches"], width),
        np.full((gap, width, 3), 255, dtype=np.uint8),
        _text_bar(labels["result"], width, (0, 0, 0) if merged else _REFUSED),
    ]
    if bottom is not None:
        rows.append(bottom)
    rows.append(_legend(width))
    return _stack(rows, width)


def _pose_line(label: str, T: NDArray[np.float64], ag: Any, resolution_m: float) -> str:
    # rounded, then + 0.0: a -1e-12 would print as "-0.00"
    tx, ty = round(float(T[0, 2]), 1) + 0.0, round(float(T[1, 2]), 1) + 0.0
    deg = round(float(np.degrees(transform_angle(T))), 2) + 0.0
    text = (
        f"  {label}: rotation {deg:.2f} deg, translation "
        f"({tx:.1f}, {ty:.1f}) cells = ({tx * resolution_m:.2f}, {ty * resolution_m:.2f}) m"
    )
    if ag is not None:
        text += f", index {ag.score:.3f} ({ag.agree} agreeing, {ag.disagree} contradicting walls)"
    return text


def candidate_lines(res: MergeResult, resolution_m: float, max_rivals: int = 3) -> list[str]:
    """When the semantic merger refused because far-apart poses explain the maps about as well
    (look-alike places), the poses it weighed (b's cells -> a's, as ``transform`` would be),
    best first: a user who knows where the maps overlap can tell which one is right. Empty for
    other refusals and other methods. Wall counts are of the verifier's sampled wall cells."""
    info = res.info or {}
    best, rivals = info.get("best_transform"), info.get("rivals") or []
    if best is None or not rivals or not res.reason.startswith("ambiguous"):
        return []
    ags = info.get("rival_agreements") or [None] * len(rivals)
    lines = ["the best pose and its rivals, far poses that explain half as much or more (b -> a):"]
    lines.append(_pose_line("best ", np.asarray(best), info.get("best_agreement"), resolution_m))
    shown: list[NDArray[np.float64]] = [np.asarray(best)]
    # strongest first (the merger lists a rival moved by a map's repeat, its last check, last)
    pairs = sorted(zip(rivals, ags, strict=True), key=lambda p: -(p[1].score if p[1] else 0.0))
    for T, ag in pairs:
        T = np.asarray(T)
        if any(_near(T, S) for S in shown):
            continue  # the same place as one listed, a cell or a degree apart
        if len(shown) > max_rivals:
            lines.append("  ... and more")
            break
        lines.append(_pose_line("rival", T, ag, resolution_m))
        shown.append(T)
    return lines


def _near(T: NDArray[np.float64], S: NDArray[np.float64]) -> bool:
    """Within 3 cells and 2 degrees of each other."""
    turn = abs((transform_angle(T) - transform_angle(S) + np.pi) % (2 * np.pi) - np.pi)
    return bool(np.hypot(*(T[:2, 2] - S[:2, 2])) < 3.0 and np.degrees(turn) < 2.0)


def main(argv: Sequence[str] | None = None) -> int:
    """CLI entry point; returns the exit code (0 merged, 1 refused, 2 bad input)."""
    p = argparse.ArgumentParser(prog="mrexplore merge", description=__doc__.split("\n\n")[0])
    p.add_argument("a", help="map_server YAML of the reference map (the result is in its frame)")
    p.add_argument("b", help="map_server YAML of the map to merge into a")
    p.add_argument("-o", "--out", required=True, help="output YAML (image and .png beside it)")
    p.add_argument("--method", default="semantic", help="semantic (default), paper or orb")
    p.add_argument("--detector", default=None, help="harris, shi-tomasi, fast, sift, orb")
    p.add_argument(
        "--force", action="store_true", help="replace existing outputs (even an input map)"
    )
    p.add_argument(
        "--prior",
        default=None,
        metavar="X_M,Y_M,YAW_DEG",
        help="a rough guess of b's map frame in a's (0,0,0: both built in one frame); only "
        "poses near it are considered (for maps of look-alike places)",
    )
    p.add_argument("--prior-radius-m", type=float, default=2.0, help="how far off the guess may be")
    p.add_argument("--prior-turn-deg", type=float, default=10.0, help="how much it may be turned")
    args = p.parse_args(list(argv) if argv is not None else None)
    try:
        prior = None
        if args.prior is not None:
            try:
                prior = tuple(float(v) for v in args.prior.split(","))
            except ValueError:
                raise ConfigError(f"--prior must be x_m,y_m,yaw_deg, got {args.prior!r}") from None
        res = merge_files(
            args.a,
            args.b,
            args.out,
            method=args.method,
            detector=args.detector,
            force=args.force,
            prior_m=prior,
            prior_radius_m=args.prior_radius_m,
            prior_turn_deg=args.prior_turn_deg,
        )
    except (MrexploreError, ConfigError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    png = Path(args.out).with_suffix(".png")
    if not res.matched or res.transform is None:
        print(f"no reliable match found: {res.reason}")
        print(f"(best score {res.score:.3f}; figure: {png})")
        lines = candidate_lines(res, float(res.info["resolution_m"]))  # merge_maps sets it
        for line in lines:
            print(line)
        if lines and args.prior is None:
            print("if you know roughly where b lies in a, give it: --prior X_M,Y_M,YAW_DEG")
        return 1
    T = res.transform
    print(f"merged with method={res.method} in {res.time_s * 1e3:.0f} ms, score {res.score:.3f}")
    print(
        f"transform b -> a (cells): rotation {np.degrees(transform_angle(T)):.2f} deg, "
        f"translation ({T[0, 2]:.2f}, {T[1, 2]:.2f})"
    )
    print(np.array2string(T, precision=4, suppress_small=True))
    print(f"wrote {args.out} and {png}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
