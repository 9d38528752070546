"""The ``multiform`` command: one entry point, one sub-command per job.

Exit status: 0 success; 2 bad input: a bad argument, file or model directory, a file that cannot be
written, a folder another command is writing (one line ``multiform: error: <culprit>: <what is
wrong>``, no traceback, nothing written); 1 anything else (an internal error: one line, and the
traceback with ``--debug``).
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
import sys  # noqa: E402
from collections.abc import Sequence  # noqa: E402
from pathlib import Path  # noqa: E402

from threadpoolctl import threadpool_limits  # noqa: E402

from .errors import InvalidInput  # noqa: E402

# The package's own imports load NumPy's BLAS before the variables above are read: limit it here too.
threadpool_limits(1)

EXIT_BAD_INPUT = 2
EXIT_BROKEN_PIPE = 141         # as a shell reports a process ended by SIGPIPE
MAX_SEED = 2**31 - 1


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


_positive = _number(0.0, float("inf"), low_open=True)
_fraction = _number(0.0, 1.0)


def _add_ray(p: argparse.ArgumentParser) -> None:
    """``--ray ADDRESS``: run the independent trials or demonstrations as Ray tasks."""
    p.add_argument("--ray", metavar="ADDRESS", default=None,
                   help="run the trials as Ray tasks (pip install 'multiform[ray]'): 'auto' joins the cluster this "
                        "machine belongs to, 'local' starts one here with --workers CPUs, or HOST:PORT / "
                        "ray://HOST:PORT; --workers then counts nothing else")


def _default_output(name: str, suffix: str) -> Path:
    """A default output file in the current folder, named for ``name`` (a net's name, which comes
    from a file and may hold a path): only its base name, in safe characters."""
    import re
    base = re.sub(r"[^A-Za-z0-9_.-]", "_", Path(name).name).lstrip(".") or "net"
    return Path(base[:100] + suffix)


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
    """The version ``--version`` names, else the history's latest; says which on stderr."""
    from .petri.revision import History
    from .petri.skillfile import resolve_skill
    latest = len(History(resolve_skill(args.skill), args.history).revisions())
    if args.version is None:
        args.version = latest
        if latest:
            print(f"{what} version {latest}, the latest of the history (--version 0 for the original)",
                  file=sys.stderr)
    return args.version if args.version >= 0 else latest + 1 + args.version


def cmd_draw(args: argparse.Namespace) -> int:
    from .petri.diagram import changed_elements, draw
    version = _chosen_version(args, "drawing")
    apn = _net_version(args, version)
    changed: set[str] = set()
    if version:
        changed = changed_elements(_net_version(args, version - 1), apn)
    out = Path(args.out) if args.out else _default_output(apn.name, ".svg")
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
    out = Path(args.out) if args.out else _default_output(apn.name, ".pnml")
    write_pnml(apn, out)
    print(f"wrote {out} (version {version})")
    return 0


def cmd_net_import(args: argparse.Namespace) -> int:
    from .io import write_text
    from .petri.pnml import read_pnml
    from .petri.skillfile import dump_skill
    apn = read_pnml(args.pnml)
    out = Path(args.out) if args.out else _default_output(apn.name, ".yaml")
    write_text(out, dump_skill(apn))
    print(f"wrote {out}")
    return 0


# -- demonstrations, training, practice, the main job ---------------------------------------------

def _bar(total: int, desc: str):
    from tqdm import tqdm
    return tqdm(total=total, desc=desc, dynamic_ncols=True)


def cmd_record(args: argparse.Namespace) -> int:
    from .demos.dataset import write_dataset
    from .demos.record import record_many
    from .lock import check_writable, exclusive
    from .task import load_task
    task = load_task(args.task)
    out = Path(args.out)
    if out.exists() and not args.overwrite:
        raise InvalidInput("exists; add --overwrite to replace it, or choose another file", file=str(out))
    if out.is_dir():
        raise InvalidInput("is a folder; give a file name (.h5)", file=str(out))
    check_writable(out)               # before recording, not after
    seeds = [args.seed * 100_000 + i for i in range(args.demos)]
    with exclusive(out):
        with _bar(len(seeds), f"recording {args.task} demos") as bar:
            eps = record_many(task.spec or task, seeds, task.DEMO_ENV_KWARGS, workers=args.workers,
                              progress=lambda i, n: bar.update(1), ray=args.ray)
        write_dataset(out, eps, task.SKILL, task.ENV_ID, task.DEMO_ENV_KWARGS)
    ok = sum(e.outcome == "success" for e in eps)
    print(f"wrote {out}: {len(eps)} demos, the mentor succeeded in {ok} ({100 * ok / len(eps):.0f} %)")
    return 0


def cmd_demos_export(args: argparse.Namespace) -> int:
    from .demos.dataset import read_dataset
    from .demos.lerobot import write_lerobot
    ds = read_dataset(args.demos)
    out = write_lerobot(args.out, ds.episodes, ds.skill, ds.env_name, ds.env_kwargs, task=args.task or "")
    print(f"wrote {out}: LeRobot v3 dataset, {len(ds)} episodes, "
          f"{sum(ep.num_samples for ep in ds)} frames at {round(1 / ds.episodes[0].dt)} fps")
    return 0


def cmd_demos_import(args: argparse.Namespace) -> int:
    from .demos.dataset import write_dataset
    from .demos.lerobot import read_lerobot
    split = lambda text: [n.strip() for n in text.split(",")] if text else None  # noqa: E731
    eps, meta = read_lerobot(args.dataset, split(args.variables), split(args.commands), args.state_key,
                             args.action_key, args.transition)
    env = meta.get("env_args", {}) if isinstance(meta.get("env_args"), dict) else {}
    skill = args.skill or str(meta.get("skill") or Path(args.dataset).name)
    env_name = args.env or str(env.get("env_name") or "")
    write_dataset(args.out, eps, skill, env_name, env.get("env_kwargs") or {}, mentor="lerobot import")
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
    return 0


# Tests set this to a teleop script (see multiform.demos.teleop) to drive `multiform teleop` headless.
_TELEOP_SCRIPT = None


def cmd_teleop(args: argparse.Namespace) -> int:
    import h5py

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
    if out.exists() and not args.append:
        raise InvalidInput("exists; add --append to add the new demonstration to it, or choose another file",
                           file=str(out))
    if _TELEOP_SCRIPT is None and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise InvalidInput("needs a display (no DISPLAY or WAYLAND_DISPLAY is set); run it on a desktop session",
                           element="teleop")
    episodes, skill, env_kwargs, mentor = [], task.SKILL, dict(task.DEMO_ENV_KWARGS), args.labeller
    if out.exists():
        ds = read_dataset(out)
        if ds.env_name != task.ENV_ID or ds.env_kwargs.get("action_mode", "ee") != "ee" \
                or tuple(ds.meta["observation_names"]) != tuple(ArmPendulumEnv.observation_names):
            raise InvalidInput(f"holds demonstrations of {ds.env_name} {ds.env_kwargs}; teleop records "
                               f"{task.ENV_ID} with end-effector commands", file=str(out), element="data")
        episodes, skill, env_kwargs = list(ds.episodes), ds.skill, ds.env_kwargs
        with h5py.File(out, "r") as f:
            mentor = str(f["data/demo_0"].attrs.get("mentor", "")) if "data/demo_0" in f else mentor
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
    from .demos.teleop import TeleopAborted, teleop_pendulum
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
        write_dataset(out, episodes + [ep], skill, task.ENV_ID, env_kwargs, mentor=mentor)
    labels = " ".join(f"{lab.transition}:{'s' if lab.success else 'f'}" for lab in ep.labels) or "none"
    print(f"wrote {out}: demo_{len(episodes)} ({ep.duration:.1f} s, seed {seed}, {len(ep.segments())} segment(s), "
          f"labels {labels}, outcome {ep.outcome or 'unlabelled'}); the file holds {len(episodes) + 1} demo(s)")
    return 0


def cmd_label(args: argparse.Namespace) -> int:
    from .demos.labelling import label_session
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


def cmd_train(args: argparse.Namespace) -> int:
    from .demos.dataset import read_dataset
    from .job import train_model
    from .model import SkillModel, staged_model_dir
    from .petri.skillfile import load_skill
    from .task import load_task, task_for_env
    task = load_task(args.task) if args.task else None      # first: a user's task registers its env
    load_skill(args.skill)
    ds = read_dataset(args.demos)
    inverse, env_kwargs = None, ds.env_kwargs
    if args.inverse_model:            # decided before anything is written
        if task is None:
            try:
                task = task_for_env(ds.env_name)
            except InvalidInput:
                task = None
        if task is None or getattr(task, "train_inverse_model", None) is None:
            raise InvalidInput(f"no inverse-model trainer for {ds.env_name}; train without --inverse-model",
                               element="--inverse-model")
        inverse, env_kwargs = task.train_inverse_model, task.robot_env_kwargs(True)
    with staged_model_dir(args.out) as partial:
        model = SkillModel.create(partial, args.skill, args.demos, ds.env_name, env_kwargs)
        print(f"training {model.apn.name} from {len(ds)} demos into {args.out}")
        train_model(model, seed=args.seed, inverse_trainer=inverse, beside=True)
    print(f"model ready: {args.out}")
    return 0


def cmd_practice(args: argparse.Namespace) -> int:
    from .adapt.practice import Practice
    from .model import SkillModel
    from .task import load_task, task_for_env
    task = load_task(args.task) if args.task else None      # first: a user's task registers its env
    model = SkillModel(args.model, env_modules=args.env_module)
    task = task or task_for_env(model.manifest["env"])
    args.task = task.TASK
    scen = {s["name"]: s for s in task.scenarios()}
    if args.scenario not in scen:
        raise InvalidInput(f"unknown scenario {args.scenario!r}; {args.task} has: {', '.join(scen)}",
                           element="--scenario")
    sc = scen[args.scenario]
    folder = Path(args.out or Path(args.model) / "practice" / args.scenario)
    practice = Practice.for_scenario(model, folder, sc, args.max_trials, args.seed, observe=_views(args, folder / "view"))

    def show(state, trial):
        mark = "ok  " if trial["success"] else "FAIL"
        print(f"trial {trial['trial']:3d} v{trial['net_version']} {mark} {trial['outcome']:8s} "
              f"judges {trial['judge_score']}  fired {' '.join(trial['fired'][:12])}"
              + (" …" if len(trial["fired"]) > 12 else ""), flush=True)
        if "mentor" in trial:
            m = trial["mentor"]
            print(f"  the mentor graded it: {m['agree']} of {m['stays']} stays as the robot did", flush=True)
        if trial.get("takeover", {}).get("time") is not None:
            print(f"  the mentor took over where the robot knew least, at {trial['takeover']['time']} s", flush=True)
        if state.revisions and state.revisions[-1].get("after_trial") == trial["trial"]:
            r = state.revisions[-1]
            print(f"  revision {r['version']}: {r['operator']} {r['target']} — {r['reason']}", flush=True)

    state = practice.run(progress=show, stop_after=args.stop_after)
    print(f"{len(state.trials)} trials; {state.stop_reason or 'stopped'}")
    return 1 if state.stop_reason.startswith("fault") else 0


def cmd_evaluate(args: argparse.Namespace) -> int:
    from .adapt.evaluation import Variant, evaluate
    from .io import write_json
    from .lock import check_writable
    from .model import SkillModel
    from .task import load_task, task_for_env
    task = load_task(args.task) if args.task else None      # first: a user's task registers its env
    model = SkillModel(args.model, env_modules=args.env_module)
    task = task or task_for_env(model.manifest["env"])
    name = task.TASK
    if args.version is not None:
        model.history.version(args.version)          # refuses a version the model does not have
    model.verify()
    out = Path(args.out) / "evaluation.json" if args.out else None
    if out is not None:
        if Path(args.out).exists() and not Path(args.out).is_dir():
            raise InvalidInput("is a file; give a folder", file=str(args.out))
        check_writable(out if Path(args.out).is_dir() else Path(args.out))   # the folder is made at the end
    specs = task.evaluation_specs(args.trials, args.seed, args.push_fraction)
    variant = Variant(f"{model.apn.name} v{model.version if args.version is None else args.version}",
                      str(Path(args.model).resolve()), net_version=args.version, env_modules=tuple(args.env_module))
    with _bar(len(specs), f"evaluating {name}") as bar:
        res = evaluate(task.spec or task, variant, specs, workers=args.workers, progress=lambda i, n: bar.update(1),
                       ray=args.ray)
    pushed = f"; pushed {res['pushed']['successes']}/{res['pushed']['trials']}" if res.get("pushed") else ""
    print(f"success {100 * res['rate']:.1f} % ({res['successes']}/{res['trials']}; 95 % CI {100 * res['low']:.1f}-"
          f"{100 * res['high']:.1f} %){pushed}; the robot's own verdict agreed on {100 * res['agreement']:.1f} %"
          + (f"; {res['faults']} fault(s)" if res["faults"] else ""))
    if out is not None:
        write_json(out, {"model": str(args.model), "task": name, "seed": args.seed, "push_fraction": args.push_fraction,
                         "net_version": variant.net_version, **res})
        print(f"wrote {out}")
    return 1 if res["faults"] else 0


def _views(args: argparse.Namespace, folder: Path):
    """The live view's trial factory for ``--view`` (None without it): each trial to an .rrd in ``folder``."""
    if args.view is None:
        return None
    from .view.stream import trial_views
    print(f"the view: each trial saved in {folder}" + ("" if args.view == "spawn" else f", streamed to {args.view}"))
    return trial_views(folder, live=args.view)


def _add_view(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument("--view", nargs="?", const="spawn", default=None, metavar="URL",
                   help=f"stream {what} to a rerun viewer (a local one with a display, or the viewer at URL, e.g. "
                        "rerun+http://host:9876/proxy) and save it as .rrd; needs pip install 'multiform[view]'")


def _every(fps: float) -> int:
    if not 0 < fps <= 1000:
        raise InvalidInput(f"must be in (0, 1000] frames per second, got {fps}", element="--fps")
    return max(1, int(round(1000.0 / fps)))          # control ticks of 1 ms per frame


def cmd_replay(args: argparse.Namespace) -> int:
    from .view.replay import replay_demo, replay_trace, to_recording, to_video
    src = Path(args.source)
    if not src.exists():
        raise InvalidInput("does not exist", file=str(src))
    if src.suffix in (".h5", ".hdf5"):
        r = replay_demo(src, args.demo, every=_every(args.fps))
        print(f"replayed demo {args.demo} of {src}: {len(r.states)} samples, states as recorded "
              f"(largest difference {r.max_error:.3g})")
        stem = f"{src.stem}_demo{args.demo}"
    else:
        r = replay_trace(src, args.model, every=_every(args.fps))
        stem = src.stem
    try:
        if args.video:
            print(f"wrote {to_video(r, args.video)}")
        if args.rrd or args.view is not None or not args.video:
            print(f"wrote {to_recording(r, args.rrd or src.with_name(stem + '.rrd'), live=args.view)}")
    finally:
        if r.env is not None:
            r.env.close()
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from .job import Job, JobConfig
    ablations = JobConfig.ablation_trials if args.ablation_trials is None else args.ablation_trials
    cfg = JobConfig(demos=args.demos, eval_trials=args.eval_trials, ablation_trials=ablations,
                    practice_max_trials=args.max_trials, workers=args.workers, seed=args.seed,
                    videos=not args.no_video, inverse_model=not args.reference_controller,
                    learn=args.learn_from_practice, practice_budget=args.practice_budget, ray=args.ray)
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


# -- the parser ------------------------------------------------------------------------------------

def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="multiform",
        description="Teach a robot a dynamic skill by definition (a Petri net), demonstration "
                    "(GP control laws) and evaluation (SVM judges); the robot practises and repairs "
                    "the definition itself.",
        epilog="Start with `multiform demo pendulum --out runs/pendulum`. SKILL is a skill file "
               "or the name of a bundled skill (pendulum, pendulum_strict, nunchaku).")
    parser.add_argument("--version", action="version", version=f"multiform {_version()}")
    parser.add_argument("--debug", action="store_true", help="show the traceback of an internal error")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True, parser_class=_Parser)

    _add_net_commands(sub)
    _add_demonstration_commands(sub)
    _add_teaching_commands(sub)
    _add_model_commands(sub)
    _add_run_commands(sub)
    _add_output_commands(sub)
    return parser


def _add_net_commands(sub: argparse._SubParsersAction) -> None:
    """Check, draw and net: a skill's net, its versions, PNML."""
    p = sub.add_parser("check", help="validate a skill file and analyse its net (exit 0 ok, 2 problems)")
    p.add_argument("skill", help="skill file or bundled skill name")
    p.add_argument("--max-states", type=_count(1, 10_000_000), default=10_000, help="cap on the reachability graph")
    p.add_argument("--max-seconds", type=_number(0.0, 3600.0, low_open=True), default=5.0,
                   help="time budget of the analysis (its memory is bounded too); an unfinished graph fails the check")
    p.set_defaults(func=cmd_check)

    p = sub.add_parser("draw", help="draw a skill's net (SVG/PNG by suffix)")
    p.add_argument("skill")
    p.add_argument("--out", "-o", help="output file (default <skill>.svg)")
    p.add_argument("--history", help="revision history (default <skill>.history.jsonl beside the skill)")
    p.add_argument("--version", "-v", type=_count(-1_000_000, 1_000_000), dest="version", default=None,
                   help="net version to draw (0 = original; default the latest); its changes are highlighted")
    p.set_defaults(func=cmd_draw)

    net = sub.add_parser("net", help="net versions: diff, history, PNML export/import")
    nsub = net.add_subparsers(dest="net_command", metavar="NET_COMMAND", required=True, parser_class=_Parser)
    p = nsub.add_parser("diff", help="show two versions of a net side by side")
    p.add_argument("skill")
    p.add_argument("a", type=_count(-1_000_000, 1_000_000), help="first version (0 = original)")
    p.add_argument("b", type=_count(-1_000_000, 1_000_000), help="second version (-1 = latest)")
    p.add_argument("--history", help="revision history file")
    p.add_argument("--width", type=_count(40, 1000), default=100)
    p.set_defaults(func=cmd_net_diff)
    p = nsub.add_parser("history", help="list the recorded revisions")
    p.add_argument("skill")
    p.add_argument("--history", help="revision history file")
    p.set_defaults(func=cmd_net_history)
    p = nsub.add_parser("export", help="export a net version as PNML")
    p.add_argument("skill")
    p.add_argument("--out", "-o")
    p.add_argument("--history")
    p.add_argument("--version", "-v", type=_count(-1_000_000, 1_000_000), dest="version", default=None,
                   help="net version to export (0 = original; default the latest)")
    p.set_defaults(func=cmd_net_export)
    p = nsub.add_parser("import", help="import a PNML net as a skill file")
    p.add_argument("pnml")
    p.add_argument("--out", "-o")
    p.set_defaults(func=cmd_net_import)


def _add_demonstration_commands(sub: argparse._SubParsersAction) -> None:
    """Record and demos: the scripted mentor's demonstrations and demonstration files."""
    p = sub.add_parser("record", help="record scripted-mentor demonstrations of a task (HDF5)")
    p.add_argument("task", help="a bundled task (pendulum, nunchaku), an installed one, package.module:NAME or path/to/file.py:NAME")
    p.add_argument("--demos", type=_count(1, 1000), default=40, help="number of demonstrations")
    p.add_argument("--out", "-o", required=True, help="output .h5 file")
    p.add_argument("--overwrite", action="store_true", help="replace --out if it exists")
    p.add_argument("--workers", type=_count(1, 256), default=2, help="processes")
    p.add_argument("--seed", type=_count(0, 40_000), default=0, help="demo i starts from seed 100000 * SEED + i")
    _add_ray(p)
    p.set_defaults(func=cmd_record)

    demos = sub.add_parser("demos", help="inspect, export and import demonstration files")
    dsub = demos.add_subparsers(dest="demos_command", metavar="DEMOS_COMMAND", required=True, parser_class=_Parser)
    p = dsub.add_parser("info", help="count, durations, success fraction, samples per transition")
    p.add_argument("demos")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_demos_info)
    p = dsub.add_parser("export", help="write demos in another format (LeRobot v3 dataset folder)")
    p.add_argument("demos")
    p.add_argument("--format", choices=["lerobot"], default="lerobot")
    p.add_argument("--out", "-o", required=True, help="new folder")
    p.add_argument("--task", help="LeRobot task text (default: the skill's name)")
    p.set_defaults(func=cmd_demos_export)
    p = dsub.add_parser("import", help="read a LeRobot v3 dataset folder as multiform demos (HDF5)")
    p.add_argument("dataset", help="LeRobot dataset folder (meta/info.json, data/...)")
    p.add_argument("--out", "-o", required=True, help="output .h5 file")
    p.add_argument("--variables", help="names of the state vector's entries, comma-separated "
                                       "(default: the feature's own names)")
    p.add_argument("--commands", help="names of the action vector's entries, comma-separated")
    p.add_argument("--state-key", default="observation.state")
    p.add_argument("--action-key", default="action")
    p.add_argument("--transition", default="t0", help="tag of every frame when there are no subtasks")
    p.add_argument("--skill", help="skill name to record (default: the dataset's)")
    p.add_argument("--env", help="env id to record (default: the dataset's)")
    p.set_defaults(func=cmd_demos_import)


def _add_teaching_commands(sub: argparse._SubParsersAction) -> None:
    """Teleop and label: a person demonstrates, labels and grades."""
    p = sub.add_parser("teleop", help="demonstrate a task yourself (keyboard or joystick), label it, save it (HDF5)",
                       description="Drive the arm with the arrow keys or a joystick axis, mark the sub-procedure "
                                   "you are executing with the number keys or joystick buttons (0-6: t0-t6), end "
                                   "with Esc, then label every segment s (success) or f (failure). The "
                                   "demonstration is written to --out, or appended with --append.")
    p.add_argument("task", help="the task (its env must be multiform/ArmPendulum-v0: pendulum)")
    p.add_argument("--out", "-o", required=True, help="demonstration file (.h5)")
    p.add_argument("--append", action="store_true", help="add the demonstration to an existing file")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--keyboard", action="store_true", help="ignore joysticks; arrow keys only")
    g.add_argument("--joystick", action="store_true", help="require a joystick (axis 0 drives, buttons mark)")
    p.add_argument("--time-scale", type=float, default=1.0, help="world speed; below 1 slows it down for a beginner")
    p.add_argument("--max-duration", type=float, default=60.0, help="seconds of simulated time at most")
    p.add_argument("--seed", type=_count(0, MAX_SEED), default=None,
                   help="start state (default: the number of demos in the file)")
    p.add_argument("--labeller", default="human", help="your name, stored with your labels")
    p.set_defaults(func=cmd_teleop)

    p = sub.add_parser("label", help="label segments of demos or recorded trials success/failure (s/f keys)",
                       description="Shows each stay of the token in a judged place (a small plot of the place's "
                                   "judged variables) and reads one key from the terminal: s success, f failure, "
                                   "k skip, q quit. Verdicts are appended to MODEL/labels.jsonl with your name; "
                                   "earlier labels are never lost, a later verdict supersedes for training.")
    p.add_argument("source", help="demonstration file (.h5), trial trace (.npz), or practice folder of traces")
    p.add_argument("--model", "-m", required=True, help="skill model directory")
    p.add_argument("--labeller", default=None, help="your name (default: your login name)")
    p.add_argument("--script", default=None, help="the keys to use instead of the terminal, e.g. sfsk (tests)")
    p.add_argument("--no-show", action="store_true", help="open no plot window")
    p.add_argument("--plots", default=None, help="save every segment's plot (PNG) in this folder")
    p.add_argument("--place", action="append", default=None, help="only this judged place (repeatable)")
    p.add_argument("--refit", action="store_true", help="then revise the judges of the places that got new labels")
    p.add_argument("--seed", type=_count(0, MAX_SEED), default=0, help="random state of a newly fitted judge")
    p.set_defaults(func=cmd_label)


def _add_model_commands(sub: argparse._SubParsersAction) -> None:
    """Train and practice: a skill model from demonstrations, then its practice with repair."""
    p = sub.add_parser("train", help="fit laws, judges and regions of a skill from demonstrations")
    p.add_argument("skill", help="skill file or bundled skill name")
    p.add_argument("demos", help="demonstration file (.h5)")
    p.add_argument("--out", "-o", required=True, help="model directory")
    p.add_argument("--inverse-model", action="store_true", help="also learn the auxiliary inverse model")
    p.add_argument("--task", default=None, help="the task (default: the one whose env recorded the demos); "
                                                "package.module:NAME or path/to/file.py:NAME for your own")
    p.add_argument("--seed", type=_count(0, MAX_SEED), default=0)
    p.set_defaults(func=cmd_train)

    p = sub.add_parser("practice", help="practise a trained skill; repair the net on constant failure")
    p.add_argument("model", help="model directory")
    p.add_argument("--task", default=None,
                   help="the task (default: the bundled or installed one whose env the model runs); "
                        "package.module:NAME or path/to/file.py:NAME for your own")
    p.add_argument("--scenario", default="a_strict", help="the task's practice scenario")
    p.add_argument("--out", help="practice folder (default MODEL/practice/SCENARIO)")
    p.add_argument("--max-trials", type=_count(1, 100_000), default=30)
    p.add_argument("--stop-after", type=_count(1, 100_000), default=None,
                   help="stop after this many trials (resume later)")
    p.add_argument("--seed", type=_count(0, MAX_SEED - 1_000_000), default=0)
    p.add_argument("--env-module", action="append", default=[], metavar="MODULE",
                   help="allow the model's env id to import MODULE (Gymnasium's module:Env-v0 form); a model "
                        "directory never imports code on its own")
    _add_view(p, "each trial (saved in the practice folder's view/)")
    p.set_defaults(func=cmd_practice)


def _add_run_commands(sub: argparse._SubParsersAction) -> None:
    """Evaluate and demo: a model's evaluation, and the main job from nothing to a report."""
    p = sub.add_parser("evaluate", help="run a trained model on the task's evaluation trials; success with its "
                                        "95 %% interval, the pushed split, the robot's own verdict")
    p.add_argument("model", help="model directory")
    p.add_argument("--task", default=None,
                   help="the task (default: the bundled or installed one whose env the model runs); "
                        "package.module:NAME or path/to/file.py:NAME for your own")
    p.add_argument("--trials", type=_count(1, 1_000_000), default=200)
    p.add_argument("--seed", type=_count(0, 40_000), default=0, help="which trials (the main job's evaluation: 0)")
    p.add_argument("--push-fraction", type=_fraction, default=0.5,
                   help="share of the trials pushed while balancing (pendulum)")
    p.add_argument("--version", "-v", type=_count(-1_000_000, 1_000_000), dest="version", default=None,
                   help="net version to run (default: the latest)")
    p.add_argument("--workers", type=_count(1, 256), default=2)
    p.add_argument("--out", "-o", default=None,
                   help="folder for evaluation.json: the rate, its interval, and one record per trial")
    p.add_argument("--env-module", action="append", default=[], metavar="MODULE",
                   help="allow the model's env id to import MODULE")
    _add_ray(p)
    p.set_defaults(func=cmd_evaluate)

    p = sub.add_parser("demo", help="the main job: record, train, practise with repair, evaluate, report")
    p.add_argument("task", help="a bundled task (pendulum, nunchaku), an installed one, package.module:NAME or path/to/file.py:NAME")
    p.add_argument("--out", "-o", required=True, help="run folder")
    p.add_argument("--demos", type=_count(1, 1000), default=None,
                   help="demonstrations (default: the task's DEMOS: pendulum 10, nunchaku 10)")
    p.add_argument("--eval-trials", type=_count(1, 1_000_000), default=200)
    p.add_argument("--ablation-trials", type=_count(0, 1_000_000), default=None,
                   help="the first evaluation trials also run by each ablation (default: 50)")
    p.add_argument("--max-trials", type=_count(1, 100_000), default=30, help="practice trials per scenario at most")
    p.add_argument("--workers", type=_count(1, 256), default=2)
    p.add_argument("--seed", type=_count(0, 40_000), default=0)
    p.add_argument("--no-video", action="store_true")
    p.add_argument("--learn-from-practice", action=argparse.BooleanOptionalAction, default=None,
                   help="after the repair scenarios, keep practising as evaluated and learn from it: refit the laws "
                        "from the robot's own graded successes and the mentor's takeovers, revise the judges with "
                        "the mentor's grades of some trials (default: the task's LEARN: on for both bundled tasks)")
    p.add_argument("--practice-budget", type=_count(0, 100_000), default=100,
                   help="practice trials of all scenarios together at most")
    p.add_argument("--reference-controller", action="store_true",
                   help="drive the arm with the env's model-based controller instead of the learned inverse model")
    _add_view(p, "the report's picked trials (saved in RUN/view/)")
    _add_ray(p)
    p.set_defaults(func=cmd_demo)


def _add_output_commands(sub: argparse._SubParsersAction) -> None:
    """Replay and report: what a run leaves to look at."""
    p = sub.add_parser("replay", help="replay a demonstration or a saved trial into the view (.rrd) or to an MP4",
                       description="A demonstration (a .h5 file, --demo picks one) is replayed on its env from its "
                                   "seed and commands and checked to reproduce the recorded states; a trial trace "
                                   "(.npz) is shown as recorded (its scene needs --model, the model that ran it). "
                                   "Without --video or --rrd, writes SOURCE's name with .rrd.")
    p.add_argument("source", help="demonstration file (.h5) or trial trace (.npz)")
    p.add_argument("--demo", type=_count(0, 1_000_000), default=0, help="which demonstration of the file (from 0)")
    p.add_argument("--model", "-m", default=None, help="skill model directory (for a trial's scene)")
    p.add_argument("--video", default=None, help="write an MP4 with time, place, transition and push on every frame")
    p.add_argument("--rrd", default=None, help="write the rerun recording here")
    p.add_argument("--fps", type=_positive, default=30.0, help="frames per second of the video and the scene")
    _add_view(p, "the replay")
    p.set_defaults(func=cmd_replay)

    p = sub.add_parser("report", help="rebuild a run folder's report.html from its metrics.json")
    p.add_argument("run")
    p.add_argument("--redraw", action="store_true",
                   help="also redraw the plots, nets and videos (reruns the two picked trials from their seeds)")
    p.add_argument("--view", action="store_true",
                   help="also save the picked trials as rerun recordings (RUN/view/*.rrd); implies --redraw")
    p.add_argument("--task", default=None,
                   help="the task that reruns the picked trials (default: the run's, if it is a bundled or installed "
                        "task; a run folder never makes multiform import code)")
    p.set_defaults(func=cmd_report)


def _version() -> str:
    from . import __version__
    return __version__


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error (the argument and what is wrong), exit status 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {_line(message)} (see {self.prog} --help)\n")


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        code = int(args.func(args) or 0)
        sys.stdout.flush()               # a closed pipe shows here, not as a traceback at exit
        return code
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
        return EXIT_BAD_INPUT
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
