"""The ``multiform`` command: one entry point, one sub-command per job, a thin shell over
:mod:`multiform.api` (the options are the API's parameters, with its defaults).

Conventions, the same for every sub-command:

* **Exit status**: 0 success; 2 the input is wrong (a bad argument, a malformed file or model
  directory, an output that exists without ``--overwrite``, a file that cannot be written, a folder
  another command is writing); 66 an input file or folder does not exist (``EX_NOINPUT`` of BSD's
  sysexits); 1 anything else (an internal error: one line, the traceback with ``--debug``); 130
  interrupted; 141 the reader of the output went away. An error is one line
  ``multiform: error: <culprit>: <what is wrong>``, and nothing is written.
* **Outputs**: a command never replaces an existing output file or folder unless ``--overwrite``
  is given, and then only once the new one is complete; a folder only if it is empty or holds what
  the command writes there (a model's ``model.json``, a dataset's ``meta/info.json``). Folders that a
  command resumes (a run folder of ``demo``, a practice folder, a model directory that ``label`` adds
  to) are not outputs to replace.
* **Names**: ``TASK`` and ``--task`` always name a task (bundled, installed, ``package.module:NAME``
  or ``path/to/file.py:NAME``; ``module:NAME`` also finds modules in the current folder);
  ``--net-version`` a version of a net; ``--version`` is the program's version.
* **Completion**: ``multiform --print-completion bash`` (or zsh, tcsh) prints a completion script
  (by shtab), e.g. ``multiform --print-completion bash > ~/.local/share/bash-completion/completions/multiform``.
"""

from __future__ import annotations

import os

# One BLAS/OpenMP thread per process: the 1 kHz loop is single-threaded, the jobs run their own worker
# processes, and on a shared 2-core machine a second BLAS thread made small solves 30x slower.
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
# Videos need MuJoCo's offscreen renderer without a display: EGL (installed by `make setup`).
os.environ.setdefault("MUJOCO_GL", "egl")

import argparse  # noqa: E402
import contextlib  # noqa: E402
import sys  # noqa: E402
from collections.abc import Callable, Iterator, Sequence  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

from threadpoolctl import threadpool_limits  # noqa: E402

from . import api, cli_options  # noqa: E402
from .cli_options import JOB_DEFAULTS  # noqa: E402,F401  (the main job's sizes, as JobConfig has them)
from .errors import InvalidInput, MissingInput  # noqa: E402

# The package's own imports load NumPy's BLAS before the variables above are read: limit it here too.
threadpool_limits(1)

EXIT_BAD_INPUT = cli_options.EXIT_BAD_INPUT
EXIT_MISSING = 66              # EX_NOINPUT: an input file or folder does not exist
EXIT_BROKEN_PIPE = 141         # as a shell reports a process ended by SIGPIPE


def _line(text: object) -> str:
    """``text`` on one line: control characters (a newline or an escape sequence in a file name)
    shown escaped, so nothing in the input can forge another line or recolour the terminal."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in str(text))


def _print_problems(exc: InvalidInput) -> None:
    """The first problem on the error line; a file with several problems lists the rest below."""
    first, *rest = exc.problems or [str(exc)]
    more = f" (and {len(rest)} more problem(s), below)" if rest else ""
    print(f"multiform: error: {_line(first)}{more}", file=sys.stderr)
    for p in rest:
        print(f"  {_line(p)}", file=sys.stderr)


def _default_output(name: str, suffix: str) -> Path:
    """A default output file in the current folder, named for ``name`` (a net's name, which comes
    from a file and may hold a path): only its base name, in safe characters."""
    import re
    base = re.sub(r"[^A-Za-z0-9_.-]", "_", Path(name).name).lstrip(".") or "net"
    return Path(base[:100] + suffix)


def _output(args: argparse.Namespace, path: Path, kind: str = "file") -> Path:
    """``path`` as a new output of this command (the one overwrite policy of :mod:`multiform.api`)."""
    from .api import _new_output
    return _new_output(path, args.overwrite, kind)


@contextlib.contextmanager
def _progress(desc: str) -> Iterator[Callable[[int, int], None]]:
    """A progress callback ``(done, total)`` whose bar appears with the first finished item, so a
    command refused before any work prints no bar."""
    bar: list[Any] = []

    def update(done: int, total: int) -> None:
        if not bar:
            from tqdm import tqdm
            bar.append(tqdm(total=total, desc=desc, dynamic_ncols=True))
        bar[0].update(done - bar[0].n)
    try:
        yield update
    finally:
        if bar:
            bar[0].close()


# -- net commands ----------------------------------------------------------------------------------

def cmd_check(args: argparse.Namespace) -> int:
    from .petri.analysis import analyse, report
    from .petri.skillfile import load_skill
    apn = load_skill(args.skill)
    result = analyse(apn, max_states=args.max_states, max_seconds=args.max_seconds)
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


def _chosen_version(args: argparse.Namespace, what: str) -> int:
    """The version ``--net-version`` names, else the history's latest; says which on stderr."""
    from .petri.revision import History
    from .petri.skillfile import resolve_skill
    latest = len(History(resolve_skill(args.skill), args.history).revisions())
    if args.net_version is None:
        args.net_version = latest
        if latest:
            print(f"{what} version {latest}, the latest of the history (--net-version 0 for the original)",
                  file=sys.stderr)
    return args.net_version if args.net_version >= 0 else latest + 1 + args.net_version


def cmd_draw(args: argparse.Namespace) -> int:
    from .petri.diagram import changed_elements, draw
    version = _chosen_version(args, "drawing")
    apn = _net_version(args, version)
    changed: set[str] = set()
    if version:
        changed = changed_elements(_net_version(args, version - 1), apn)
    out = _output(args, Path(args.out) if args.out else _default_output(apn.name, ".svg"))
    draw(apn, out, changed=changed, title=f"{apn.name}" + (f" (version {version})" if version else ""))
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
    version = _chosen_version(args, "exporting")
    apn = _net_version(args, version)
    out = _output(args, Path(args.out) if args.out else _default_output(apn.name, ".pnml"))
    write_pnml(apn, out)
    print(f"wrote {out} (version {version})")
    return 0


def cmd_net_import(args: argparse.Namespace) -> int:
    from .io import write_text
    from .petri.pnml import read_pnml
    from .petri.skillfile import dump_skill
    apn = read_pnml(args.pnml)
    out = _output(args, Path(args.out) if args.out else _default_output(apn.name, ".yaml"))
    write_text(out, dump_skill(apn))
    print(f"wrote {out}")
    return 0


# -- demonstrations --------------------------------------------------------------------------------

def cmd_record(args: argparse.Namespace) -> int:
    from .lock import check_writable
    from .task import load_task
    task = load_task(args.task)
    check_writable(Path(args.out))        # the command makes no folder: a mistyped path is refused
    n = task.DEMOS if args.demos is None else args.demos
    with _progress(f"recording {task.TASK} demos") as progress:
        out = api.record(task, args.out, demos=n, seed=args.seed, workers=args.workers, overwrite=args.overwrite,
                         progress=progress, ray=args.ray, mentor=args.mentor, kinesthetic=args.kinesthetic)
    from .demos.dataset import read_dataset
    ds = read_dataset(out)
    eps = ds.episodes
    ok = sum(e.outcome == "success" for e in eps)
    how = " (guiding the arm by hand)" if ds.meta.get("teaching") else ""
    print(f"wrote {out}: {len(eps)} demos by {eps[0].mentor or 'an unnamed mentor'}{how}, who succeeded in {ok} "
          f"({100 * ok / len(eps):.0f} %)")
    return 0


def cmd_demos_merge(args: argparse.Namespace) -> int:
    names = {}
    for item in args.mentor:
        file, sep, name = item.rpartition("=")
        if not sep or not file:
            raise InvalidInput(f"must be FILE=NAME, got {item!r}", element="--mentor")
        names[file] = name
    ds = api.merge_demos(args.demos, args.out, names, overwrite=args.overwrite)
    per = ds.summary()["mentors"]
    print(f"wrote {args.out}: {len(ds)} demos of {ds.skill} by " +
          ", ".join(f"{m} ({v['demos']})" for m, v in per.items()))
    return 0


def cmd_demos_export(args: argparse.Namespace) -> int:
    from .demos.dataset import read_dataset
    out = api.export_demos(args.demos, args.out, fps=args.fps, task_text=args.task_text or "", overwrite=args.overwrite)
    ds = read_dataset(args.demos)
    import json
    info = json.loads((out / "meta" / "info.json").read_text())
    print(f"wrote {out}: LeRobot v3 dataset, {len(ds)} episodes, {info['total_frames']} frames at {info['fps']} fps")
    return 0


def cmd_demos_import(args: argparse.Namespace) -> int:
    split = lambda text: [n.strip() for n in text.split(",")] if text else None  # noqa: E731
    ds = api.import_demos(args.dataset, args.out, split(args.variables), split(args.commands), args.state_key,
                          args.action_key, args.transition, skill=args.skill, env=args.env, overwrite=args.overwrite,
                          mentor=args.mentor)
    eps = ds.episodes
    ok = sum(ep.outcome == "success" for ep in eps)
    print(f"wrote {args.out}: {len(eps)} demos ({ok} successful), variables "
          f"{', '.join(eps[0].observation_names)}; commands {', '.join(eps[0].command_names)}")
    return 0


def cmd_demos_info(args: argparse.Namespace) -> int:
    import json

    from .demos.dataset import read_dataset
    s = read_dataset(args.demos).summary()
    if args.json:
        print(json.dumps(s, indent=2))
        return 0
    d = s["duration_s"]
    print(f"{s['file']}: skill {s['skill']}, env {s['env']}")
    print(f"demos: {s['demos']} ({s['success']} successful, {100 * s['success_fraction']:.0f} %)")
    print(f"duration: {d['total']:.1f} s in all, mean {d['mean']:.1f} s, min {d['min']:.1f} s, max {d['max']:.1f} s")
    print(f"samples: {s['samples']}; labelled segments: {s['segments']} ({s['segments_success']} success)")
    print("samples per transition: " + ", ".join(f"{k} {v}" for k, v in s["samples_per_transition"].items()))
    print("mentors: " + ", ".join(f"{m} ({v['demos']} demos, {v['success']} successful)"
                                  for m, v in s["mentors"].items()))
    return 0


# Tests set this to a teleop script (see multiform.teach.teleop) to drive `multiform teleop` headless.
_TELEOP_SCRIPT = None


def cmd_teleop(args: argparse.Namespace) -> int:
    from .demos.dataset import read_dataset, write_dataset
    from .envs.arm_pendulum import ArmPendulumEnv
    from .task import load_task
    task = load_task(args.task)
    if task.ENV_ID != "multiform/ArmPendulum-v0":
        raise InvalidInput(f"teleop drives the arm of multiform/ArmPendulum-v0; {args.task} runs {task.ENV_ID}",
                           element=args.task)
    out = Path(args.out)
    for flag, value in (("--time-scale", args.time_scale), ("--max-duration", args.max_duration)):
        if not value > 0:
            raise InvalidInput(f"must be positive, got {value}", element=flag)
    if out.exists() and not (args.append or args.overwrite):
        raise InvalidInput("exists; add --append to add the new demonstration to it, --overwrite to replace it, "
                           "or choose another file", file=str(out))
    if _TELEOP_SCRIPT is None and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise InvalidInput("needs a display (no DISPLAY or WAYLAND_DISPLAY is set); run it on a desktop session",
                           element="teleop")
    from .demos.episode import check_mentor_name
    check_mentor_name(args.labeller, element="--mentor")
    episodes, skill, env_kwargs = [], task.SKILL, dict(task.DEMO_ENV_KWARGS)
    if out.exists() and args.append:
        ds = read_dataset(out)
        if ds.env_name != task.ENV_ID or ds.env_kwargs.get("action_mode", "ee") != "ee" \
                or tuple(ds.meta["observation_names"]) != tuple(ArmPendulumEnv.observation_names):
            raise InvalidInput(f"holds demonstrations of {ds.env_name} {ds.env_kwargs}; teleop records "
                               f"{task.ENV_ID} with end-effector commands", file=str(out), element="data")
        episodes, skill, env_kwargs = list(ds.episodes), ds.skill, ds.env_kwargs
    try:
        import pygame
    except ImportError:
        print("teleop needs pygame: pip install 'multiform[teleop]'", file=sys.stderr)
        return 1
    if args.joystick:
        pygame.joystick.init()
        count = pygame.joystick.get_count()
        pygame.joystick.quit()
        if not count:
            raise InvalidInput("no joystick found; use --keyboard", element="--joystick")
    from .teach.teleop import TeleopAborted, teleop_pendulum
    seed = len(episodes) if args.seed is None else args.seed
    print("arrows / stick: move the hand   0-6 / buttons: mark the sub-procedure (t0-t6)   Esc: end; "
          "then s / f per segment", flush=True)
    try:
        ep = teleop_pendulum(seed=seed, options=task.demo_options(seed), joystick=not args.keyboard,
                             time_scale=args.time_scale, max_duration=args.max_duration, labeller=args.labeller,
                             script=_TELEOP_SCRIPT)
    except TeleopAborted as exc:
        print(f"teleop: {exc}; nothing written", file=sys.stderr)
        return 1
    from .lock import exclusive
    with exclusive(out):
        ep.mentor = args.labeller
        write_dataset(out, episodes + [ep], skill, task.ENV_ID, env_kwargs)
    labels = " ".join(f"{lab.transition}:{'s' if lab.success else 'f'}" for lab in ep.labels) or "none"
    print(f"wrote {out}: demo_{len(episodes)} ({ep.duration:.1f} s, seed {seed}, {len(ep.segments())} segment(s), "
          f"labels {labels}, outcome {ep.outcome or 'unlabelled'}); the file holds {len(episodes) + 1} demo(s)")
    return 0


def cmd_label(args: argparse.Namespace) -> int:
    from .teach.labelling import label_session
    from .lock import exclusive
    from .model import SkillModel
    SkillModel(args.model).verify(to_run=False)
    with exclusive(args.model):
        res = label_session(args.model, args.source, labeller=args.labeller, script=args.script, show=not args.no_show,
                            plots=args.plots, refit=args.refit, places=args.place, seed=args.seed)
    ok = sum(r.success for r in res.records)
    print(f"labelled {len(res.records)} of {res.segments} segment(s) ({ok} success, {len(res.records) - ok} failure), "
          f"skipped {res.skipped}" + (f", {res.unlabelled} left" if res.unlabelled else "")
          + f"; appended to {Path(args.model) / 'labels.jsonl'}")
    if res.unused_keys:
        print(f"note: {len(res.unused_keys)} key(s) of the script were not used: {res.unused_keys}")
    if res.plots:
        print(f"plots: {len(res.plots)} in {args.plots}")
    for place, info in res.refit.items():
        print(f"judge {place} refitted on {info['segments']} labelled segments ({info['success_labels']} success): "
              f"kernel {info['kernel']}")
    return 0


# -- training, practice, evaluation ----------------------------------------------------------------

def cmd_train(args: argparse.Namespace) -> int:
    api.train(args.skill, args.demos, args.out, task=args.task, seed=args.seed, inverse_model=args.inverse_model,
              overwrite=args.overwrite, fusion=args.fusion, workers=args.workers)
    print(f"model ready: {args.out}")
    return 0


def _show_trial(state: Any, trial: Any) -> None:
    """One line per practice trial, and what the mentor and the repairs did after it."""
    mark = "ok  " if trial.success else "FAIL"
    print(f"trial {trial.trial:3d} v{trial.net_version} {mark} {trial.outcome:8s} "
          f"judges {trial.judge_score}  fired {' '.join(trial.fired[:12])}"
          + (" …" if len(trial.fired) > 12 else ""), flush=True)
    if trial.mentor is not None:
        print(f"  the mentor graded it: {trial.mentor.agree} of {trial.mentor.stays} stays as the robot did",
              flush=True)
    if trial.takeover is not None and trial.takeover.time is not None:
        print(f"  the mentor took over where the robot knew least, at {trial.takeover.time} s", flush=True)
    if state.revisions and state.revisions[-1].after_trial == trial.trial:
        r = state.revisions[-1]
        print(f"  revision {r.version}: {r.operator} {r.target} — {r.reason}", flush=True)


def cmd_practice(args: argparse.Namespace) -> int:
    model = api.open_model(args.model, env_modules=tuple(args.env_module))
    observe = (lambda folder: _views(args, folder / "view")) if args.view is not None else None
    state = api.practise(model, args.task, scenario=args.scenario, out=args.out, max_trials=args.max_trials,
                         seed=args.seed, stop_after=args.stop_after, progress=_show_trial, observe=observe,
                         options=args.options, workers=args.workers)
    print(f"{len(state.trials)} trials; {state.stop_reason or 'stopped'}")
    return 1 if state.stop_reason.startswith("fault") else 0


def cmd_evaluate(args: argparse.Namespace) -> int:
    model = api.open_model(args.model, env_modules=tuple(args.env_module))
    with _progress("evaluating") as progress:
        res = api.evaluate(model, args.task, trials=args.trials, seed=args.seed, push_fraction=args.push_fraction,
                           workers=args.workers, version=args.net_version, out=args.out, overwrite=args.overwrite,
                           progress=progress, ray=args.ray, options=args.options)
    pushed = f"; pushed {res['pushed']['successes']}/{res['pushed']['trials']}" if res.get("pushed") else ""
    print(f"success {100 * res['rate']:.1f} % ({res['successes']}/{res['trials']}; 95 % CI {100 * res['low']:.1f}-"
          f"{100 * res['high']:.1f} %){pushed}; the robot's own verdict agreed on {100 * res['agreement']:.1f} %"
          + (f"; {res['faults']} fault(s)" if res["faults"] else ""))
    if args.out:
        print(f"wrote {Path(args.out) / 'evaluation.json'}")
    return 1 if res["faults"] else 0


def cmd_mentor(args: argparse.Namespace) -> int:
    with _progress("the mentor") as progress:
        r = api.mentor_rate(args.task, trials=args.trials, seed=args.seed, workers=args.workers, progress=progress)
    print(f"the mentor succeeded in {r['successes']}/{r['trials']} of the evaluation starts: {100 * r['rate']:.1f} % "
          f"(95 % CI {100 * r['low']:.1f}-{100 * r['high']:.1f} %)")
    return 0


def _views(args: argparse.Namespace, folder: Path):
    """The live view's trial factory for ``--view`` (None without it): each trial to an .rrd in ``folder``."""
    if args.view is None:
        return None
    from .view.stream import trial_views
    print(f"the view: each trial saved in {folder}" + ("" if args.view == "spawn" else f", streamed to {args.view}"))
    return trial_views(folder, live=args.view)


def _every(fps: float) -> int:
    if not 0 < fps <= 1000:
        raise InvalidInput(f"must be in (0, 1000] frames per second, got {fps}", element="--fps")
    return max(1, int(round(1000.0 / fps)))          # control ticks of 1 ms per frame


def cmd_replay(args: argparse.Namespace) -> int:
    from .view.replay import replay_demo, replay_trace, to_recording, to_video
    src = Path(args.source)
    if not src.exists():
        raise MissingInput("does not exist", file=str(src))
    stem = f"{src.stem}_demo{args.demo}" if src.suffix in (".h5", ".hdf5") else src.stem
    video = _output(args, Path(args.video)) if args.video else None
    rrd = None
    if args.rrd or args.view is not None or not args.video:
        rrd = _output(args, Path(args.rrd) if args.rrd else src.with_name(stem + ".rrd"))
    if src.suffix in (".h5", ".hdf5"):
        r = replay_demo(src, args.demo, every=_every(args.fps))
        print(f"replayed demo {args.demo} of {src}: {len(r.states)} samples, states as recorded "
              f"(largest difference {r.max_error:.3g})")
    else:
        r = replay_trace(src, args.model, every=_every(args.fps))
    try:
        if video is not None:
            print(f"wrote {to_video(r, video)}")
        if rrd is not None:
            print(f"wrote {to_recording(r, rrd, live=args.view)}")
    finally:
        if r.env is not None:
            r.env.close()
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from .job import Job, JobConfig
    mentors = args.mentors
    if mentors and not any(n for _, n in mentors):          # names only: --demos shared evenly, in order
        from .task import load_task
        total = args.demos or load_task(args.task).DEMOS
        mentors = tuple((name, total // len(mentors) + (i < total % len(mentors))) for i, (name, _) in enumerate(mentors))
    cfg = JobConfig(demos=args.demos, eval_trials=args.eval_trials, ablation_trials=args.ablation_trials,
                    practice_max_trials=args.max_trials, workers=args.workers, seed=args.seed,
                    videos=not args.no_video, inverse_model=not args.reference_controller,
                    learn=args.learn_from_practice, practice_budget=args.practice_budget, ray=args.ray,
                    mentors=mentors, fusion=args.fusion, practice=args.practice,
                    kinesthetic=args.kinesthetic, practice_seed=args.practice_seed)
    m = Job(args.task, args.out, cfg, view=args.view).run()
    sr = m["success_rate"]
    print(f"success rate {100 * sr['rate']:.1f} % ({sr['successes']}/{sr['trials']}; 95 % CI "
          f"{100 * sr['low']:.1f}-{100 * sr['high']:.1f} %); report: {Path(args.out) / 'report.html'}")
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    from .io import read_json
    from .lock import exclusive
    from .report.page import build_report
    path = Path(args.run) / "metrics.json"
    metrics = read_json(path, "run metrics (is this a run folder?)")
    if not isinstance(metrics, dict):
        raise InvalidInput("must be a JSON object", file=str(path))
    with exclusive(args.run):
        try:
            if args.redraw or args.view:
                from .report.artifacts import rebuild
                from .task import installed_task, load_task
                task = load_task(args.task) if args.task else installed_task(metrics.get("task"), str(path))
                out = rebuild(args.run, task, view=args.view)
            else:
                out = build_report(args.run, metrics)
        except InvalidInput:
            raise
        except (KeyError, TypeError, ValueError, AttributeError, IndexError) as exc:
            raise InvalidInput(f"malformed ({type(exc).__name__}: {exc})", file=str(path)) from None
    print(f"wrote {out}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The command line, each sub-command run by this module's ``cmd_*`` function of its name."""
    handlers = {name[4:]: fn for name, fn in globals().items() if name.startswith("cmd_")}
    return cli_options.build_parser(handlers)


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if os.getcwd() not in sys.path:     # module:NAME task specs find modules in the current folder,
        sys.path.append(os.getcwd())    # as under `python -m multiform` (last: nothing installed is shadowed)
    try:
        code = int(args.func(args) or 0)
        sys.stdout.flush()               # a closed pipe shows here, not as a traceback at exit
        return code
    except MissingInput as exc:
        _print_problems(exc)
        return EXIT_MISSING
    except InvalidInput as exc:
        _print_problems(exc)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:              # `multiform ... | head`: the reader left, nothing is wrong
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_BROKEN_PIPE
    except OSError as exc:               # a file that cannot be read or written: the file and why
        if args.debug:
            raise
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"multiform: error: {_line(where)}{_line(exc.strerror or exc)}", file=sys.stderr)
        return EXIT_MISSING if isinstance(exc, FileNotFoundError) else EXIT_BAD_INPUT
    except RecursionError:
        if args.debug:
            raise
        print("multiform: error: the input is nested too deeply to read", file=sys.stderr)
        return EXIT_BAD_INPUT
    except Exception as exc:             # a bug of ours: one line, the traceback on request
        if args.debug:
            raise
        print(f"multiform: internal error: {type(exc).__name__}: {_line(exc)} (run again with --debug for the "
              "traceback)", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
