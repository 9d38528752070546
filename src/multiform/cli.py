"""The ``multiform`` command: one entry point, one sub-command per job.

Exit status: 0 success, 2 bad input (the message names file, element and problem), 1 other errors.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from .errors import InvalidInput

EXIT_BAD_INPUT = 2


def _print_problems(exc: InvalidInput) -> None:
    print(f"error: {len(exc.problems)} problem(s) found", file=sys.stderr)
    for p in exc.problems:
        print(f"  {p}", file=sys.stderr)


# -- net commands ----------------------------------------------------------------------------------

def cmd_check(args: argparse.Namespace) -> int:
    from .petri.analysis import analyse, report
    from .petri.skillfile import load_skill
    apn = load_skill(args.skill)
    result = analyse(apn, max_states=args.max_states)
    for line in report(apn, result):
        print(line)
    if not result.ok:
        print("check: FAILED", file=sys.stderr)
        return EXIT_BAD_INPUT
    print("check: ok")
    return 0


def _net_version(args: argparse.Namespace, version: int | None):
    from .petri.revision import History
    from .petri.skillfile import load_skill, resolve_skill
    if version is None or version == 0 and not getattr(args, "history", None):
        return load_skill(args.skill)
    hist = History(resolve_skill(args.skill), args.history)
    return hist.version(version)


def cmd_draw(args: argparse.Namespace) -> int:
    from .petri.diagram import changed_elements, draw
    apn = _net_version(args, args.version)
    changed: set[str] = set()
    if args.version:
        changed = changed_elements(_net_version(args, args.version - 1), apn)
    out = Path(args.out or f"{apn.name}.svg")
    draw(apn, out, changed=changed, title=f"{apn.name}" + (f" (version {args.version})" if args.version else ""))
    print(f"wrote {out}")
    return 0


def cmd_net_diff(args: argparse.Namespace) -> int:
    from .petri.netdiff import side_by_side
    a, b = _net_version(args, args.a), _net_version(args, args.b)
    print(side_by_side(a, b, f"version {args.a}", f"version {args.b}", width=args.width))
    return 0


def cmd_net_history(args: argparse.Namespace) -> int:
    from .petri.revision import History
    from .petri.skillfile import resolve_skill
    hist = History(resolve_skill(args.skill), args.history)
    revs = hist.revisions()
    print(f"{hist.original}: version 0 (original)")
    for r in revs:
        print(f"version {r.version}: {r.operator} {r.target} — {r.reason}  [{r.time}]")
    return 0


def cmd_net_export(args: argparse.Namespace) -> int:
    from .petri.pnml import write_pnml
    apn = _net_version(args, args.version)
    out = Path(args.out or f"{apn.name}.pnml")
    write_pnml(apn, out)
    print(f"wrote {out}")
    return 0


def cmd_net_import(args: argparse.Namespace) -> int:
    from .io import write_text
    from .petri.pnml import read_pnml
    from .petri.skillfile import dump_skill
    apn = read_pnml(args.pnml)
    out = Path(args.out or f"{apn.name}.yaml")
    write_text(out, dump_skill(apn))
    print(f"wrote {out}")
    return 0


# -- the parser ------------------------------------------------------------------------------------

def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="multiform",
        description="Teach a robot a dynamic skill by definition (a Petri net), demonstration "
                    "(GP control laws) and evaluation (SVM judges); the robot practises and repairs "
                    "the definition itself.",
        epilog="Start with `multiform demo pendulum --out runs/pendulum`. SKILL is a skill file "
               "or the name of a bundled skill (pendulum, pendulum_strict, nunchaku).")
    parser.add_argument("--version", action="version", version=f"multiform {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    p = sub.add_parser("check", help="validate a skill file and analyse its net (exit 0 ok, 2 problems)")
    p.add_argument("skill", help="skill file or bundled skill name")
    p.add_argument("--max-states", type=int, default=10_000, help="cap on the reachability graph")
    p.set_defaults(func=cmd_check)

    p = sub.add_parser("draw", help="draw a skill's net (SVG/PNG by suffix)")
    p.add_argument("skill")
    p.add_argument("--out", "-o", help="output file (default <skill>.svg)")
    p.add_argument("--history", help="revision history (default <skill>.history.jsonl beside the skill)")
    p.add_argument("--version", "-v", type=int, dest="version", default=None,
                   help="net version to draw (0 = original); changes of that version are highlighted")
    p.set_defaults(func=cmd_draw)

    net = sub.add_parser("net", help="net versions: diff, history, PNML export/import")
    nsub = net.add_subparsers(dest="net_command", metavar="NET_COMMAND", required=True)
    p = nsub.add_parser("diff", help="show two versions of a net side by side")
    p.add_argument("skill")
    p.add_argument("a", type=int, help="first version (0 = original)")
    p.add_argument("b", type=int, help="second version (-1 = latest)")
    p.add_argument("--history", help="revision history file")
    p.add_argument("--width", type=int, default=100)
    p.set_defaults(func=cmd_net_diff)
    p = nsub.add_parser("history", help="list the recorded revisions")
    p.add_argument("skill")
    p.add_argument("--history", help="revision history file")
    p.set_defaults(func=cmd_net_history)
    p = nsub.add_parser("export", help="export a net version as PNML")
    p.add_argument("skill")
    p.add_argument("--out", "-o")
    p.add_argument("--history")
    p.add_argument("--version", "-v", type=int, dest="version", default=None)
    p.set_defaults(func=cmd_net_export)
    p = nsub.add_parser("import", help="import a PNML net as a skill file")
    p.add_argument("pnml")
    p.add_argument("--out", "-o")
    p.set_defaults(func=cmd_net_import)
    return parser


def _version() -> str:
    from . import __version__
    return __version__


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except InvalidInput as exc:
        _print_problems(exc)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
