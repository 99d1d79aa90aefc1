"""`irloc survey REC --anchor ID --anchor ID --out MAP.json`: locate every landmark of a
survey drive (`docs/survey.md`).

REC is a recording (`docs/recording.md`) of a robot driving under the ceiling: while the
landmarks blink one at a time (`survey.blinks`; `irloc serve`'s live survey does this), or
with every LED lit after the anchors were named (the paper's one-at-a-time start): then each
landmark is named by where its spots sit against its rough position (`survey.association`).
Its map.json holds the anchors' surveyed positions and every other landmark with a rough
position or none. The output map has the same landmarks with refined x, y, z and `sigma_m`. Errors
name what is wrong and write nothing.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tqdm import tqdm

from survey.bundle import BundleConfig, solve_survey
from survey.drive import read_survey_drive, survey_problem
from survey.result import SurveyResult
from survey.survey_map import surveyed_map, write_map_atomic

PROG = "irloc survey"


def parse_args(argv: list[str]) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog=PROG, description=__doc__.split("\n\n")[0])
    p.add_argument("recording", type=Path, help="the survey drive's recording folder")
    p.add_argument(
        "--anchor",
        type=int,
        action="append",
        default=[],
        metavar="ID",
        help="a landmark held at its map.json position (two or more)",
    )
    p.add_argument("--out", type=Path, required=True, help="where to write the surveyed map")
    p.add_argument(
        "--anchor-sigma-mm",
        type=float,
        default=1000 * BundleConfig.anchor_sigma_m,
        metavar="MM",
        help="how well the anchors were surveyed, 1 sigma per axis, mm (default %(default)s: "
        "a total station); it is part of every landmark's sigma_m",
    )
    p.add_argument(
        "--rough-sigma-cm",
        type=float,
        default=100 * BundleConfig.rough_sigma_m,
        metavar="CM",
        help="how far map.json's rough positions may be off, 1 sigma per axis, cm (default "
        "%(default)s: up to ~30 cm); landmarks no blink names are named by where their spots "
        "sit where this tells them from their neighbours",
    )
    p.add_argument(
        "--allow-unseen",
        action="store_true",
        help="write the map even if some landmarks could not be surveyed (they keep what "
        "map.json gave them)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar and no table")
    args = p.parse_args(argv)
    if not args.anchor_sigma_mm > 0:
        p.error(f"--anchor-sigma-mm must be > 0, got {args.anchor_sigma_mm}")
    if not args.rough_sigma_cm > 0:
        p.error(f"--rough-sigma-cm must be > 0, got {args.rough_sigma_cm}")
    return args


def table(result: SurveyResult) -> str:
    """The per-landmark table printed on a terminal."""
    lines = [
        f"{'id':>6} {'x m':>8} {'y m':>8} {'z m':>7} {'sigma mm':>9} {'moved m':>8} "
        f"{'views':>5} {'rms px':>6}  notes"
    ]
    for lid, e in sorted(result.landmarks.items()):
        moved = (
            ""
            if e.given is None or e.anchor
            else f"{float(((e.position - e.given) ** 2).sum()) ** 0.5:.3f}"
        )
        sigma = "anchor" if e.anchor else f"{1000 * e.sigma_m:.1f}"
        x, y, z = e.position.tolist()
        lines.append(
            f"{lid:>6} {x:>8.3f} {y:>8.3f} {z:>7.3f} {sigma:>9} {moved:>8} {e.views:>5} "
            f"{e.rms_px:>6.2f}  {'; '.join(e.flags)}"
        )
    wl, wr, wb = result.wheel_calibration
    dfu, dfv, du, dv, yaw, dk1, roll, pitch, dz, dk2 = result.camera_correction
    lines.append(
        f"reprojection {result.rms_px:.2f} px RMS; wheels x{wl:.4f} / x{wr:.4f}, base "
        f"x{wb:.4f}; camera focal {100 * dfu:+.2f} / {100 * dfv:+.2f} %, "
        f"centre {du:+.2f} / {dv:+.2f} px, "
        f"yaw {yaw * 57.29578:+.3f} deg, k1 / k2 {dk1:+.5f} / {dk2:+.5f}, roll / pitch "
        f"{1000 * roll:+.2f} / {1000 * pitch:+.2f} mrad, height {1000 * dz:+.1f} mm"
    )
    return "\n".join(lines)


def unnamed_lines(result: SurveyResult, ids: list[int]) -> str:
    """One line per landmark not surveyed, with the reason."""
    return "\n".join(f"  {lid}: {result.unnamed.get(lid, 'never identified')}" for lid in ids)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(sys.argv[1:] if argv is None else argv)
    show = not args.quiet and sys.stderr.isatty()
    try:
        bar = tqdm(total=1, desc="frames", unit="frame", disable=not show, leave=False)

        def frames_done(i: int, n: int) -> None:
            bar.total = n
            bar.n = i
            bar.refresh()

        drive = read_survey_drive(args.recording, progress=frames_done)
        bar.close()
        problem = survey_problem(drive, args.anchor)
        windows = tqdm(total=1, desc="solving", unit="window", disable=not show, leave=False)

        def solved(i: int, n: int) -> None:
            windows.total = n
            windows.n = i
            windows.refresh()

        config = BundleConfig(
            anchor_sigma_m=args.anchor_sigma_mm / 1000.0,
            rough_sigma_m=args.rough_sigma_cm / 100.0,
        )
        result = solve_survey(problem, config, progress=solved)
        windows.close()
    except ValueError as exc:
        print(f"{PROG}: {str(exc).removeprefix('survey: ')}", file=sys.stderr)
        return 1
    never = sorted(set(lm.id for lm in drive.landmarks) - set(result.landmarks))
    if never and not args.allow_unseen:
        print(
            f"{PROG}: landmark(s) {', '.join(map(str, never))} not surveyed:\n"
            + unnamed_lines(result, never)
            + "\ndrive under them, blink them, or pass --allow-unseen to keep their map.json "
            "positions; nothing written",
            file=sys.stderr,
        )
        return 1
    write_map_atomic(args.out, surveyed_map(drive.landmarks, result))
    if not args.quiet:
        print(table(result))
        if never:
            print(f"not surveyed (kept as map.json gave them):\n{unnamed_lines(result, never)}")
        flagged = result.flagged()
        print(
            f"{len(result.landmarks)} landmarks surveyed, {len(flagged)} flagged, "
            f"{len(never)} never seen; wrote {args.out}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
