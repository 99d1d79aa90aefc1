"""`irloc calibrate`: the lens from chessboard photos (`calibration.cli`), or `irloc calibrate
mounting RECORDING` (`irloc.calibrate_mounting`, which reads a recording: `calibration` does
not import `recording`)."""

from __future__ import annotations


def main(argv: list[str]) -> int:
    """Entry point of `irloc calibrate`; returns the exit status."""
    if argv[:1] == ["mounting"]:
        from irloc.calibrate_mounting import main as mounting_main

        return mounting_main(argv[1:])
    from calibration.cli import main as lens_main

    return lens_main(argv)
