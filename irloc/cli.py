"""The `irloc` command: one entry point, one subcommand per job.

Each subcommand lives with the package it belongs to and is imported only when called, so
`irloc replay` does not start a web server's imports.
"""

from __future__ import annotations

import importlib
import sys

# subcommand -> (module, function, one-line help)
SUBCOMMANDS: dict[str, tuple[str, str, str]] = {
    "serve": (
        "irloc.serve",
        "main",
        "run the server (API + viewer) on the simulated site or hardware",
    ),
    "agent": ("agent.cli", "main", "the on-robot localizer talking MQTT to the site"),
    "simulate": ("irloc.simulate_cli", "main", "write a recording of a simulated scenario"),
    "replay": ("recording.replay_cli", "main", "localize a recording and write poses.csv"),
    "calibrate": ("irloc.calibrate_cli", "main", "calibrate the lens from chessboard photos"),
    "export": ("export.cli", "main", "write a recording as MCAP (Foxglove or ROS 2)"),
    "report": ("export.report_cli", "main", "write the validation report (HTML) of a recording"),
    "survey": ("survey.cli", "main", "locate every landmark from a survey drive's recording"),
    "keys": ("server.keys_cli", "main", "manage API keys"),
}


def usage() -> str:
    lines = ["usage: irloc COMMAND [ARGS...]", "", "commands:"]
    lines += [f"  {name:<10} {text}" for name, (_, _, text) in SUBCOMMANDS.items()]
    lines += ["", "Run 'irloc COMMAND --help' for a command's options."]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if not args or args[0] in ("-h", "--help", "help"):
        print(usage())
        return 0
    name, rest = args[0], args[1:]
    if name not in SUBCOMMANDS:
        print(f"irloc: unknown command {name!r}\n\n{usage()}", file=sys.stderr)
        return 2
    module_name, func_name, _ = SUBCOMMANDS[name]
    func = getattr(importlib.import_module(module_name), func_name)
    return int(func(rest) or 0)


if __name__ == "__main__":
    raise SystemExit(main())
