"""The ``multiform`` command's options: every sub-command with its arguments, their help and their
defaults (the API's own, read from :mod:`multiform.api`'s signatures), and argparse's error and
help format. :mod:`multiform.cli` runs what they parse."""

from __future__ import annotations

import argparse
import inspect
from collections.abc import Callable, Mapping
from typing import Any

from . import api

EXIT_BAD_INPUT = 2
MAX_SEED = 2**31 - 1
Handlers = Mapping[str, Callable[[argparse.Namespace], int]]

TASK_HELP = ("a task: bundled (pendulum, nunchaku, ball_in_cup), installed (entry point group multiform.tasks), "
             "package.module:NAME or path/to/file.py:NAME")

def _count(low: int, high: int):
    """An argparse type: a whole number in ``low..high`` (numbers that size work or memory are bounded)."""
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
        if not low <= v <= high:
            raise argparse.ArgumentTypeError(f"must be in {low}..{high}, got {v}")
        return v
    return parse


def _number(low: float, high: float, low_open: bool = False):
    """An argparse type: a finite number in ``low..high`` (above ``low`` with ``low_open``)."""
    def parse(text: str) -> float:
        import math
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
        if not (math.isfinite(v) and (v > low if low_open else v >= low) and v <= high):
            want = f"above {low:g}" if low_open else f"in {low:g}..{high:g}"
            if low_open and high != float("inf"):
                want += f" and at most {high:g}"
            raise argparse.ArgumentTypeError(f"must be a finite number {want}, got {text}")
        return v
    return parse


def _json_object(text: str) -> dict[str, Any]:
    """An argparse type: a JSON object (reset options), bounded as any data read from a file."""
    import json

    from .io import plain_data_problems
    try:
        value = json.loads(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"not JSON ({exc})") from None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError(f"must be a JSON object, got {type(value).__name__}")
    problems = plain_data_problems(value, "options")
    if problems:
        raise argparse.ArgumentTypeError(f"{problems[0][0]}: {problems[0][1]}")
    return value


_positive = _number(0.0, float("inf"), low_open=True)
_fraction = _number(0.0, 1.0)
_version_number = _count(-1_000_000, 1_000_000)


def _default(fn: Callable[..., Any], name: str) -> Any:
    """The default of parameter ``name`` of the API function ``fn``: the command's default too."""
    return inspect.signature(fn).parameters[name].default


def _add_ray(p: argparse.ArgumentParser) -> None:
    """``--ray ADDRESS``: run the independent trials or demonstrations as Ray tasks."""
    p.add_argument("--ray", metavar="ADDRESS", default=None,
                   help="run the trials as Ray tasks (pip install 'multiform[ray]'): 'auto' joins the cluster this "
                        "machine belongs to, 'local' starts one here with --workers CPUs, or HOST:PORT / "
                        "ray://HOST:PORT; --workers then counts nothing else (default: no Ray, local processes)")


def _add_overwrite(p: argparse.ArgumentParser, what: str = "the output") -> None:
    p.add_argument("--overwrite", action="store_true", help=f"replace {what} if it exists")


def _add_workers(p: argparse.ArgumentParser, default: int) -> None:
    p.add_argument("--workers", type=_count(1, 256), default=default,
                   help="worker processes for the independent demonstrations, trials or law fits (results do not "
                        "depend on it)")


def _add_net_version(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument("--net-version", type=_version_number, dest="net_version", default=None, metavar="N",
                   help=f"net version to {what} (0 = the original, -1 = the latest; default: the latest)")



def _add_view(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument("--view", nargs="?", const="spawn", default=None, metavar="URL",
                   help=f"stream {what} to a rerun viewer (a local one with a display, or the viewer at URL, e.g. "
                        "rerun+http://host:9876/proxy) and save it as .rrd; needs pip install 'multiform[view]' (default: no view)")



# -- the parser ------------------------------------------------------------------------------------

# The main job's sizes, as JobConfig has them (a test checks that the two agree; importing the job
# here would make every --help load the learners).
JOB_DEFAULTS = {"eval_trials": 200, "ablation_trials": 50, "practice_max_trials": 30, "practice_budget": 100,
                "workers": 2, "seed": 0, "learn": True}


class _HelpFormatter(argparse.HelpFormatter):
    """Every option's help ends with its default: ``(default: X)``, ``(default: off)`` for a flag,
    unless the help already says what the default is."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if "default" in text or action.default is argparse.SUPPRESS or action.required or not action.option_strings:
            return text
        if isinstance(action, (argparse._StoreTrueAction, argparse._StoreFalseAction)):
            return f"{text} (default: off)" if action.default is False else f"{text} (default: on)"
        if isinstance(action, argparse.BooleanOptionalAction) and isinstance(action.default, bool):
            return f"{text} (default: {'on' if action.default else 'off'})"
        if action.default is None or isinstance(action, argparse.BooleanOptionalAction):
            return text
        return f"{text} (default: %(default)s)"


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error (the argument and what is wrong), exit status 2, and the
    defaults shown in every help."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", _HelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> None:  # type: ignore[override]
        line = "".join(c if c.isprintable() else repr(c)[1:-1] for c in message)   # nothing forges a line
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {line} (see {self.prog} --help)\n")


def _version() -> str:
    from . import __version__
    return __version__


def build_parser(handlers: Handlers) -> argparse.ArgumentParser:
    """The whole command line; ``handlers`` maps each sub-command's name (``net_export``, ...) to the
    function that runs it."""
    parser = _Parser(
        prog="multiform",
        description="Teach a robot a dynamic skill by definition (a Petri net), demonstration "
                    "(GP control laws) and evaluation (SVM judges); the robot practises and repairs "
                    "the definition itself.",
        epilog="Start with `multiform demo pendulum --out runs/pendulum`. SKILL is a skill file "
               "or the name of a bundled skill (pendulum, pendulum_strict, nunchaku, ball_in_cup). Exit status: 0 ok, "
               "2 the input is wrong, 66 an input file is missing, 1 an internal error.")
    parser.add_argument("--version", action="version", version=f"multiform {_version()}")
    parser.add_argument("--debug", action="store_true", help="show the traceback of an internal error")
    import shtab
    shtab.add_argument_to(parser, ["--print-completion"],
                          help="print a shell completion script for SHELL (bash, zsh, tcsh) and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True, parser_class=_Parser)

    _add_net_commands(sub, handlers)
    _add_demonstration_commands(sub, handlers)
    _add_teaching_commands(sub, handlers)
    _add_model_commands(sub, handlers)
    _add_run_commands(sub, handlers)
    _add_output_commands(sub, handlers)
    return parser


def _add_net_commands(sub: argparse._SubParsersAction, h: Handlers) -> None:
    """Check, draw and net: a skill's net, its versions, PNML."""
    p = sub.add_parser("check", help="validate a skill file and analyse its net (exit 0 ok, 2 problems, 66 missing)")
    p.add_argument("skill", help="skill file or bundled skill name")
    p.add_argument("--max-states", type=_count(1, 10_000_000), default=10_000, help="cap on the reachability graph")
    p.add_argument("--max-seconds", type=_number(0.0, 3600.0, low_open=True), default=5.0,
                   help="time budget of the analysis (its memory is bounded too); an unfinished graph fails the check")
    p.set_defaults(func=h["check"])

    p = sub.add_parser("draw", help="draw a skill's net (SVG, PNG, PDF or DOT by suffix)")
    p.add_argument("skill", help="skill file, bundled skill name or model directory")
    p.add_argument("--out", "-o", help="output file (default: NET_NAME.svg in the current folder)")
    p.add_argument("--history", help="revision history (default: SKILL.history.jsonl beside the skill)")
    _add_net_version(p, "draw; its changes are highlighted")
    _add_overwrite(p, "--out")
    p.set_defaults(func=h["draw"])

    net = sub.add_parser("net", help="net versions: diff, history, PNML export/import")
    nsub = net.add_subparsers(dest="net_command", metavar="NET_COMMAND", required=True, parser_class=_Parser)
    p = nsub.add_parser("diff", help="show two versions of a net side by side")
    p.add_argument("skill", help="skill file, bundled skill name or model directory")
    p.add_argument("a", type=_version_number, help="first version (0 = original)")
    p.add_argument("b", type=_version_number, help="second version (-1 = latest)")
    p.add_argument("--history", help="revision history file (default: SKILL.history.jsonl beside the skill)")
    p.add_argument("--width", type=_count(40, 1000), default=100, help="columns of the side-by-side view")
    p.set_defaults(func=h["net_diff"])
    p = nsub.add_parser("history", help="list the recorded revisions")
    p.add_argument("skill", help="skill file, bundled skill name or model directory")
    p.add_argument("--history", help="revision history file (default: SKILL.history.jsonl beside the skill)")
    p.set_defaults(func=h["net_history"])
    p = nsub.add_parser("export", help="export a net version as PNML")
    p.add_argument("skill", help="skill file, bundled skill name or model directory")
    p.add_argument("--out", "-o", help="output file (default: NET_NAME.pnml in the current folder)")
    p.add_argument("--history", help="revision history file (default: SKILL.history.jsonl beside the skill)")
    _add_net_version(p, "export")
    _add_overwrite(p, "--out")
    p.set_defaults(func=h["net_export"])
    p = nsub.add_parser("import", help="import a PNML net as a skill file")
    p.add_argument("pnml", help="PNML file (multiform's own export, or any place/transition net)")
    p.add_argument("--out", "-o", help="skill file to write (default: NET_NAME.yaml in the current folder)")
    _add_overwrite(p, "--out")
    p.set_defaults(func=h["net_import"])


def _add_demonstration_commands(sub: argparse._SubParsersAction, h: Handlers) -> None:
    """Record and demos: the scripted mentor's demonstrations and demonstration files."""
    p = sub.add_parser("record", help="record scripted-mentor demonstrations of a task (HDF5)")
    p.add_argument("task", metavar="TASK", help=TASK_HELP)
    p.add_argument("--demos", type=_count(1, 1000), default=_default(api.record, "demos"),
                   help="number of demonstrations (default: the task's DEMOS, 10 for each bundled task)")
    p.add_argument("--out", "-o", required=True, help="output .h5 file")
    _add_overwrite(p, "--out")
    _add_workers(p, _default(api.record, "workers"))
    p.add_argument("--seed", type=_count(0, 40_000), default=_default(api.record, "seed"),
                   help="demo i starts from seed 100000 * SEED + i")
    p.add_argument("--mentor", default=None, metavar="NAME",
                   help="which of the task's scripted mentors demonstrates (pendulum and nunchaku: expert, average, "
                        "poor); its name is stored with every demo and label (default: the task's default mentor)")
    _add_kinesthetic(p)
    _add_ray(p)
    p.set_defaults(func=h["record"])

    demos = sub.add_parser("demos", help="inspect, export and import demonstration files")
    dsub = demos.add_subparsers(dest="demos_command", metavar="DEMOS_COMMAND", required=True, parser_class=_Parser)
    p = dsub.add_parser("info", help="count, durations, success fraction, samples per transition")
    p.add_argument("demos", help="demonstration file (.h5)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=h["demos_info"])
    p = dsub.add_parser("export", help="write demos in another format (LeRobot v3 dataset folder)")
    p.add_argument("demos", help="demonstration file (.h5)")
    p.add_argument("--format", choices=["lerobot"], default="lerobot", help="the format to write")
    p.add_argument("--out", "-o", required=True, help="new folder")
    p.add_argument("--fps", type=_positive, default=None,
                   help="frames per second, a whole divisor of the control rate: each frame holds the state at its "
                        "start and the mean command over its ticks (default: the control rate)")
    p.add_argument("--task-text", default=None,
                   help="LeRobot's task description of every episode (default: the skill's name)")
    _add_overwrite(p, "--out")
    p.set_defaults(func=h["demos_export"])
    p = dsub.add_parser("import", help="read a LeRobot v3 dataset folder as multiform demos (HDF5)")
    p.add_argument("dataset", help="LeRobot dataset folder (meta/info.json, data/...)")
    p.add_argument("--out", "-o", required=True, help="output .h5 file")
    p.add_argument("--variables", help="names of the state vector's entries, comma-separated "
                                       "(default: the feature's own names)")
    p.add_argument("--commands", help="names of the action vector's entries, comma-separated "
                                      "(default: the feature's own names)")
    p.add_argument("--state-key", default="observation.state", help="the feature holding the state vector")
    p.add_argument("--action-key", default="action", help="the feature holding the action vector")
    p.add_argument("--transition", default="t0", help="tag of every frame when there are no subtasks")
    p.add_argument("--skill", help="skill name to record (default: the dataset's)")
    p.add_argument("--env", help="env id to record (default: the dataset's)")
    p.add_argument("--mentor", default="", metavar="NAME",
                   help="who demonstrated the episodes that do not say (default: nobody named)")
    _add_overwrite(p, "--out")
    p.set_defaults(func=h["demos_import"])
    p = dsub.add_parser("merge", help="merge several people's demonstration files into one (HDF5)",
                        description="Every demo keeps its mentor and labels; the merged file has one robomimic "
                                    "filter key per mentor (mask/mentor_NAME). Files of different skills, envs, "
                                    "variables, commands or control periods are refused.")
    p.add_argument("demos", nargs="+", help="demonstration files (.h5), in the order their demos are to appear")
    p.add_argument("--out", "-o", required=True, help="output .h5 file")
    p.add_argument("--mentor", action="append", default=[], metavar="FILE=NAME",
                   help="the mentor of FILE's demos where the file records none, repeatable (default: none; such "
                        "a file is refused)")
    _add_overwrite(p, "--out")
    p.set_defaults(func=h["demos_merge"])


def _add_teaching_commands(sub: argparse._SubParsersAction, h: Handlers) -> None:
    """Teleop and label: a person demonstrates, labels and grades."""
    p = sub.add_parser("teleop", help="demonstrate a task yourself (keyboard or joystick), label it, save it (HDF5)",
                       description="Drive the arm with the arrow keys or a joystick axis, mark the sub-procedure "
                                   "you are executing with the number keys or joystick buttons (0-6: t0-t6), end "
                                   "with Esc, then label every segment s (success) or f (failure). The "
                                   "demonstration is written to --out, or appended with --append.")
    p.add_argument("task", metavar="TASK", help="the task (its env must be multiform/ArmPendulum-v0: pendulum)")
    p.add_argument("--out", "-o", required=True, help="demonstration file (.h5)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--append", action="store_true", help="add the demonstration to an existing file")
    _add_overwrite(g, "--out")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--keyboard", action="store_true", help="ignore joysticks; arrow keys only")
    g.add_argument("--joystick", action="store_true", help="require a joystick (axis 0 drives, buttons mark)")
    p.add_argument("--time-scale", type=float, default=1.0, help="world speed; below 1 slows it down for a beginner")
    p.add_argument("--max-duration", type=float, default=60.0, help="seconds of simulated time at most")
    p.add_argument("--seed", type=_count(0, MAX_SEED), default=None,
                   help="start state (default: the number of demos in the file)")
    p.add_argument("--mentor", "--labeller", dest="labeller", default="human", metavar="NAME",
                   help="your name, stored with your demonstration and your labels")
    p.set_defaults(func=h["teleop"])

    p = sub.add_parser("label", help="label segments of demos or recorded trials success/failure (s/f keys)",
                       description="Shows each stay of the token in a judged place (a small plot of the place's "
                                   "judged variables) and reads one key from the terminal: s success, f failure, "
                                   "k skip, q quit. Verdicts are appended to MODEL/labels.jsonl with your name; "
                                   "earlier labels are never lost, a later verdict supersedes for training.")
    p.add_argument("source", help="demonstration file (.h5), trial trace (.npz), or practice folder of traces")
    p.add_argument("--model", "-m", required=True, help="skill model directory")
    p.add_argument("--mentor", "--labeller", dest="labeller", default=None, metavar="NAME",
                   help="your name, stored with every label (default: your login name)")
    p.add_argument("--script", default=None,
                   help="the keys to use instead of the terminal, e.g. sfsk (default: read keys from the terminal)")
    p.add_argument("--no-show", action="store_true", help="open no plot window")
    p.add_argument("--plots", default=None, help="save every segment's plot (PNG) in this folder (default: none saved)")
    p.add_argument("--place", action="append", default=None,
                   help="only this judged place, repeatable (default: every judged place)")
    p.add_argument("--refit", action="store_true", help="then revise the judges of the places that got new labels")
    p.add_argument("--seed", type=_count(0, MAX_SEED), default=0, help="random state of a newly fitted judge")
    p.set_defaults(func=h["label"])


def _add_model_commands(sub: argparse._SubParsersAction, h: Handlers) -> None:
    """Train and practice: a skill model from demonstrations, then its practice with repair."""
    p = sub.add_parser("train", help="fit laws, judges and regions of a skill from demonstrations")
    p.add_argument("skill", help="skill file or bundled skill name")
    p.add_argument("demos", help="demonstration file (.h5)")
    p.add_argument("--out", "-o", required=True, help="model directory")
    _add_overwrite(p, "the model directory")
    p.add_argument("--inverse-model", action="store_true", help="also learn the auxiliary inverse model")
    p.add_argument("--task", default=None, help=TASK_HELP + " (default: the one whose env recorded the demos)")
    p.add_argument("--seed", type=_count(0, MAX_SEED), default=_default(api.train, "seed"),
                   help="random state of every fit")
    _add_fusion(p)
    _add_workers(p, _default(api.train, "workers"))
    p.set_defaults(func=h["train"])

    p = sub.add_parser("practice", help="practise a trained skill; repair the net on constant failure")
    p.add_argument("model", help="model directory")
    p.add_argument("--task", default=None, help=TASK_HELP + " (default: the one whose env the model runs)")
    p.add_argument("--scenario", default=None, help="the task's practice scenario (default: the task's first)")
    p.add_argument("--options", type=_json_object, default=None, metavar="JSON",
                   help='env reset options that override the task\'s in every trial, e.g. \'{"length": 0.24}\': '
                        "practise on a changed object (default: the task's)")
    p.add_argument("--out", help="practice folder, resumed if it exists (default: MODEL/practice/SCENARIO)")
    p.add_argument("--max-trials", type=_count(1, 100_000), default=_default(api.practise, "max_trials"),
                   help="trials at most")
    p.add_argument("--stop-after", type=_count(1, 100_000), default=None,
                   help="stop after this many trials and resume later (default: run to the end)")
    p.add_argument("--seed", type=_count(0, MAX_SEED - 1_000_000), default=_default(api.practise, "seed"),
                   help="the trials' seeds and the repairs' random state")
    _add_env_module(p)
    _add_view(p, "each trial (saved in the practice folder's view/)")
    _add_workers(p, _default(api.practise, "workers"))
    p.set_defaults(func=h["practice"])


def _add_fusion(p: argparse.ArgumentParser) -> None:
    p.add_argument("--fusion", action=argparse.BooleanOptionalAction, default=True,
                   help="with demonstrations of several mentors, weigh each by how far it proves reliable, per "
                        "maneuver and per place (MODEL/mentors.json); --no-fusion pools them as one mentor's")


def _mentor_plan(text: str) -> tuple[tuple[str, int], ...]:
    """``expert:5,poor:10`` (or ``expert,average,poor``: counts 0, spread by the job over --demos)."""
    out = []
    for part in text.split(","):
        name, sep, count = part.strip().partition(":")
        if not name:
            raise argparse.ArgumentTypeError(f"a mentor needs a name, got {text!r}")
        try:
            n = int(count) if sep else 0
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a whole number of demos: {count!r}") from None
        if sep and not 1 <= n <= 1000:
            raise argparse.ArgumentTypeError(f"demos per mentor must be in 1..1000, got {n}")
        out.append((name, n))
    if any(n for _, n in out) and not all(n for _, n in out):
        raise argparse.ArgumentTypeError(f"give every mentor a count or none, got {text!r}")
    return tuple(out)


def _add_env_module(p: argparse.ArgumentParser) -> None:
    p.add_argument("--env-module", action="append", default=[], metavar="MODULE",
                   help="allow the model's env id to import MODULE (Gymnasium's module:Env-v0 form), repeatable; "
                        "a model directory never imports code on its own (default: none)")


def _add_run_commands(sub: argparse._SubParsersAction, h: Handlers) -> None:
    """Evaluate, mentor and demo: a model's evaluation, the mentor's, and the main job."""
    p = sub.add_parser("evaluate", help="run a trained model on the task's evaluation trials; success with its "
                                        "95 %% interval, the pushed split, the robot's own verdict")
    p.add_argument("model", help="model directory")
    p.add_argument("--task", default=None, help=TASK_HELP + " (default: the one whose env the model runs)")
    p.add_argument("--trials", type=_count(1, 1_000_000), default=_default(api.evaluate, "trials"),
                   help="evaluation trials")
    p.add_argument("--seed", type=_count(0, 40_000), default=_default(api.evaluate, "seed"),
                   help="trial i starts from seed 50000000 + 100000 * SEED + i (the main job's evaluation: 0)")
    p.add_argument("--options", type=_json_object, default=None, metavar="JSON",
                   help="env reset options that override the task's in every trial (default: the task's)")
    p.add_argument("--push-fraction", type=_fraction, default=_default(api.evaluate, "push_fraction"),
                   help="share of the trials the experimenter pushes (where the task pushes)")
    _add_net_version(p, "run")
    _add_workers(p, _default(api.evaluate, "workers"))
    p.add_argument("--out", "-o", default=None,
                   help="folder for evaluation.json: the rate, its interval, and one record per trial "
                        "(default: print only)")
    _add_overwrite(p, "OUT/evaluation.json")
    _add_env_module(p)
    _add_ray(p)
    p.set_defaults(func=h["evaluate"])

    p = sub.add_parser("mentor", help="the scripted mentor's own success rate from the evaluation trials' starts")
    p.add_argument("task", metavar="TASK", help=TASK_HELP)
    p.add_argument("--trials", type=_count(1, 1_000_000), default=_default(api.mentor_rate, "trials"),
                   help="evaluation starts (those of `evaluate --trials`)")
    p.add_argument("--seed", type=_count(0, 40_000), default=_default(api.mentor_rate, "seed"),
                   help="which starts (those of `evaluate --seed`)")
    _add_workers(p, _default(api.mentor_rate, "workers"))
    p.set_defaults(func=h["mentor"])

    p = sub.add_parser("demo", help="the main job: record, train, practise with repair, evaluate, report",
                       description="The main job in a run folder; a folder from an earlier run is resumed: stages "
                                   "whose results are there (the same demonstrations, the trained model, finished "
                                   "practice) are reused.")
    p.add_argument("task", metavar="TASK", help=TASK_HELP)
    p.add_argument("--out", "-o", required=True, help="run folder (resumed if it exists)")
    p.add_argument("--demos", type=_count(1, 1000), default=None,
                   help="demonstrations (default: the task's DEMOS, 10 for each bundled task)")
    p.add_argument("--eval-trials", type=_count(1, 1_000_000), default=JOB_DEFAULTS["eval_trials"],
                   help="evaluation trials of the final skill")
    p.add_argument("--ablation-trials", type=_count(0, 1_000_000), default=JOB_DEFAULTS["ablation_trials"],
                   help="the first evaluation trials also run by each ablation (0: no ablations)")
    p.add_argument("--max-trials", type=_count(1, 100_000), default=JOB_DEFAULTS["practice_max_trials"],
                   help="practice trials per scenario at most")
    _add_workers(p, JOB_DEFAULTS["workers"])
    p.add_argument("--seed", type=_count(0, 40_000), default=JOB_DEFAULTS["seed"],
                   help="the job's seed: its demonstrations, practice and evaluation trials")
    p.add_argument("--practice-seed", type=_count(0, 40_000), default=None,
                   help="the seed of practice's trial draws alone: with all else the same, another value shows how "
                        "much the result owes to the trials practice happened to draw (default: --seed)")
    p.add_argument("--no-video", action="store_true", help="write no videos")
    p.add_argument("--learn-from-practice", action=argparse.BooleanOptionalAction, default=JOB_DEFAULTS["learn"],
                   help="run the task's scenarios that learn from practice: refit the laws from the robot's own "
                        "graded successes and the mentor's takeovers, revise the judges with the mentor's grades "
                        "of some trials; off: practice only repairs the net")
    p.add_argument("--practice-budget", type=_count(0, 100_000), default=JOB_DEFAULTS["practice_budget"],
                   help="practice trials of all scenarios together at most")
    p.add_argument("--reference-controller", action="store_true",
                   help="drive the arm with the env's model-based controller instead of the learned inverse model")
    p.add_argument("--mentors", type=_mentor_plan, default=(), metavar="NAME[:N],...",
                   help="demonstrations by several of the task's scripted mentors, in order: expert:5,poor:10, or "
                        "expert,average,poor to share --demos evenly; they also take turns grading practice trials "
                        "(default: the task's default mentor alone)")
    p.add_argument("--practice", type=_json_object, default={}, metavar="JSON",
                   help="practice settings over every scenario's own (PracticeConfig fields, see "
                        'multiform.adapt.practice), e.g. \'{"deliberate": true, "max_robot_seconds": 900}\' '
                        "(default: the task's)")
    _add_fusion(p)
    _add_kinesthetic(p)
    _add_view(p, "the report's picked trials (saved in RUN/view/)")
    _add_ray(p)
    p.set_defaults(func=h["demo"])


def _add_kinesthetic(p: argparse.ArgumentParser) -> None:
    p.add_argument("--kinesthetic", action=argparse.BooleanOptionalAction, default=None,
                   help="the mentor teaches by guiding the compliant arm by hand: the commands are recovered from the "
                        "arm's motion and the person's forces are never kept (default: the task's KINESTHETIC: on for "
                        "ball_in_cup, off for pendulum; nunchaku has no hand-guiding mode)")


def _add_output_commands(sub: argparse._SubParsersAction, h: Handlers) -> None:
    """Replay and report: what a run leaves to look at."""
    p = sub.add_parser("replay", help="replay a demonstration or a saved trial into the view (.rrd) or to an MP4",
                       description="A demonstration (a .h5 file, --demo picks one) is replayed on its env from its "
                                   "seed and commands and checked to reproduce the recorded states; a trial trace "
                                   "(.npz) is shown as recorded (its scene needs --model, the model that ran it). "
                                   "Without --video or --rrd, writes SOURCE's name with .rrd.")
    p.add_argument("source", help="demonstration file (.h5) or trial trace (.npz)")
    p.add_argument("--demo", type=_count(0, 1_000_000), default=0, help="which demonstration of the file (from 0)")
    p.add_argument("--model", "-m", default=None,
                   help="skill model directory, for a trial's scene (default: none, the trace as recorded)")
    p.add_argument("--video", default=None,
                   help="write an MP4 with time, place, transition and push on every frame (default: no video)")
    p.add_argument("--rrd", default=None, help="write the rerun recording here (default: SOURCE's name with .rrd)")
    p.add_argument("--fps", type=_positive, default=30.0, help="frames per second of the video and the scene")
    _add_overwrite(p, "--video and --rrd")
    _add_view(p, "the replay")
    p.set_defaults(func=h["replay"])

    p = sub.add_parser("report", help="rebuild a run folder's report.html from its metrics.json")
    p.add_argument("run", help="run folder of `multiform demo`")
    p.add_argument("--redraw", action="store_true",
                   help="also redraw the plots, nets and videos (reruns the two picked trials from their seeds)")
    p.add_argument("--view", action="store_true",
                   help="also save the picked trials as rerun recordings (RUN/view/*.rrd); implies --redraw")
    p.add_argument("--task", default=None,
                   help="the task that reruns the picked trials (default: the run's, if it is a bundled or installed "
                        "task; a run folder never makes multiform import code)")
    p.set_defaults(func=h["report"])
