"""A labelling session: a person grades the segments of demonstrations or of the robot's recorded
trials, one at a time, and the verdicts go to the skill model's label store (``multiform label``).

The segments are the judges' segments: the *stays* of the token in a judged place
(:func:`multiform.learn.views.stays`; a place is judged when the skill file gives it ``judge:``
variables). For each one a small plot of the place's judged variables over time is shown (and/or
saved as a PNG) and one key is read: ``s`` success, ``f`` failure, ``k`` skip, ``q`` quit. Every
verdict is appended to ``MODEL_DIR/labels.jsonl`` at once (an atomic rewrite through
:class:`~multiform.learn.labels.LabelStore`: earlier records are never edited or lost, a new
verdict on a segment supersedes the older ones for training).

Segment ids in the label store (``source``):

* the model's own demonstration file: ``demo_<i>``, the ids its training gave the mentor's labels,
  so a new verdict supersedes the mentor's for the same segment;
* any other demonstration file: ``<file name>:demo_<i>``;
* a trial trace ``<folder>/traces/trial_0007.npz`` written by practice: ``<folder>_7``, the id
  practice grades that trial under (the folder is named for the scenario by default);
  any other trace file: its stem.

With ``refit``, each place that got new verdicts has its judge revised
(:meth:`multiform.learn.judge.Judge.revise`) with every effective mentor label of that place whose
segment can be cut now (the model's demonstrations and the labelled source): a re-labelled segment
takes the new verdict, the judge's other training rows stay, and the kernel search reruns.
Everything the session reads is validated before anything is written.
"""

from __future__ import annotations

import getpass
import os
import re
import sys
from collections.abc import Callable, Iterable, Mapping, Sequence
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

import h5py
import numpy as np

from ..adapt.learners import refit_judges
from ..errors import InvalidInput, MissingInput
from ..learn.features import Segment
from ..learn.judge import Judge
from ..learn.labels import ROBOT, LabelRecord, LabelStore, is_mentor, now
from ..learn.training import demo_source, judged_places
from ..learn.views import stays, value_matrix
from ..model import SkillModel
from ..petri.net import APN
from ..runtime.trace import Trace
from ..demos.dataset import read_dataset
from ..demos.episode import Episode

KEYS = {"s": "success", "f": "failure", "k": "skip", "q": "quit"}
KEY_HELP = "s success, f failure, k skip, q quit"
CONTEXT = 0.5                      # s of the episode shown on each side of a segment
KeyReader = Callable[[str], str]   # prompt → one key ("" when the input has ended)


@dataclass(frozen=True)
class LabelSource:
    """One episode to label: its label-store id, the episode, and the file it came from."""

    source: str
    episode: Episode
    file: str


@dataclass(frozen=True)
class SegmentToLabel:
    """One stay of the token in a judged place, with what the person is shown about it."""

    source: str
    file: str
    place: str
    place_label: str
    start: int
    end: int
    dt: float
    variables: tuple[str, ...]
    values: np.ndarray                     # (T, k): the judged variables over the whole episode
    earlier: LabelRecord | None = None     # the effective mentor label so far
    score: float | None = None             # the current judge's P(success)

    @property
    def segment(self) -> Segment:
        return Segment(self.values[self.start:self.end], self.variables, self.dt, self.source, self.start,
                       self.end, self.place)

    def describe(self) -> str:
        t0, t1 = self.start * self.dt, self.end * self.dt
        text = f"{self.source} {self.place}" + (f" ({self.place_label})" if self.place_label else "")
        text += f", {t0:.2f}-{t1:.2f} s"
        if self.earlier is not None:
            text += f"; earlier: {'success' if self.earlier.success else 'failure'} by {self.earlier.labeller}"
        if self.score is not None:
            text += f"; judge {self.score:.2f}"
        return text


@dataclass
class SessionResult:
    """What a session did: the records written, keys used, plots saved, judges refitted."""

    segments: int
    records: list[LabelRecord] = field(default_factory=list)
    skipped: int = 0
    quit: bool = False
    unlabelled: int = 0                     # segments never reached (quit or end of input)
    unused_keys: str = ""
    plots: list[Path] = field(default_factory=list)
    refit: dict[str, dict[str, Any]] = field(default_factory=dict)


# -- checking the inputs ----------------------------------------------------------------------------

def check_script(keys: str) -> str:
    """The key script without whitespace; any key other than s, f, k, q is refused."""
    out = []
    for i, c in enumerate(keys):
        if c.isspace():
            continue
        if c not in KEYS:
            raise InvalidInput(f"invalid key {c!r} at position {i + 1}; keys: {KEY_HELP}", element="--script")
        out.append(c)
    return "".join(out)


def check_labeller(name: str) -> str:
    """A person's name for the records: not empty, not the robot's (its grades never train judges)."""
    name = name.strip()
    if not name:
        raise InvalidInput("must not be empty", element="--labeller")
    if not is_mentor(name):
        raise InvalidInput(f"names starting with {ROBOT!r} are the robot's own grades and never train a judge; "
                           "give the person's name", element="--labeller")
    return name


def default_labeller() -> str:
    """The login name, or ``human``."""
    try:
        return getpass.getuser() or "human"
    except (KeyError, OSError):
        return "human"


def read_sources(path: str | os.PathLike, model_demos: str | os.PathLike | None = None) -> list[LabelSource]:
    """The episodes of a demonstration file (HDF5), a trial trace (.npz), or a folder of traces
    (a practice folder or its ``traces/``), with their label-store ids (see the module docstring)."""
    path = Path(path)
    if not path.exists():
        raise MissingInput("file not found", file=str(path))
    if path.is_dir():
        files = sorted((path / "traces").glob("trial_*.npz")) or sorted(path.glob("*.npz"))
        if not files:
            raise InvalidInput("folder holds no trial traces (traces/trial_*.npz or *.npz)", file=str(path))
        return [_trace_source(f) for f in files]
    if h5py.is_hdf5(path):
        ds = read_dataset(path)
        own = model_demos is not None and Path(model_demos).resolve() == path.resolve()
        return [LabelSource(demo_source(i) if own else f"{path.name}:{demo_source(i)}", ep, str(path))
                for i, ep in enumerate(ds.episodes)]
    with open(path, "rb") as f:
        magic = f.read(4)
    if magic.startswith(b"PK"):
        return [_trace_source(path)]
    raise InvalidInput("neither a demonstration file (HDF5) nor a trial trace (.npz)", file=str(path))


def _trace_source(path: Path) -> LabelSource:
    trace = Trace.load(path)
    m = re.fullmatch(r"trial_(\d+)", path.stem)
    if m and path.parent.name == "traces":
        source = f"{path.parent.parent.resolve().name}_{int(m.group(1))}"
    else:
        source = path.stem
    return LabelSource(source, trace.to_episode(), str(path))


def segments_to_label(apn: APN, sources: Sequence[LabelSource], store: LabelStore | None = None,
                      judges: Mapping[str, Judge] | None = None, places: Iterable[str] | None = None
                      ) -> list[SegmentToLabel]:
    """Every stay in a judged place (of ``places`` if given), in source and time order.

    Raises :class:`InvalidInput` when an episode's tags are not transitions of ``apn`` or it lacks
    a judged variable, naming the file and the episode.
    """
    judged = judged_places(apn)
    wanted = list(judged) if places is None else list(places)
    bad = [p for p in wanted if p not in judged]
    if bad:
        raise InvalidInput(f"{', '.join(bad)}: not a judged place of {apn.name} (judged: {', '.join(judged) or 'none'})",
                           element="--place")
    known = set(apn.transition_ids)
    earlier: dict[tuple[str, int, int], LabelRecord] = {}
    if store is not None:
        earlier = {r.key: r for r in store.effective(sources=[s.source for s in sources])}
    names = tuple(dict.fromkeys(v for p in wanted for v in judged[p]))
    out: list[SegmentToLabel] = []
    for src in sources:
        ep = src.episode
        unknown = sorted({str(t) for t in np.unique(ep.transitions)} - known - {""})
        if unknown:
            raise InvalidInput(f"transition(s) {', '.join(unknown)} are not in skill {apn.name}'s net "
                               f"({', '.join(apn.transition_ids)})", file=src.file, element=src.source)
        runs = [(s, e, p) for s, e, p in stays(apn, ep.transitions) if p in wanted]
        if not runs:
            continue
        try:
            values = value_matrix(apn, ep, names)
        except KeyError as exc:
            raise InvalidInput(f"{exc.args[0]} (a judged variable of {apn.name})", file=src.file,
                               element=src.source) from None
        for s, e, p in runs:
            cols = [names.index(v) for v in judged[p]]
            seg = SegmentToLabel(src.source, src.file, p, apn.place(p).label, s, e, ep.dt, judged[p],
                                 np.ascontiguousarray(values[:, cols]), earlier.get((src.source, s, e)))
            if judges and p in judges:
                seg = _with_score(seg, judges[p])
            out.append(seg)
    return out


def _with_score(seg: SegmentToLabel, judge: Judge) -> SegmentToLabel:
    from dataclasses import replace
    return replace(seg, score=judge.grade(seg.segment))


# -- keys -------------------------------------------------------------------------------------------

def script_reader(script: str) -> tuple[KeyReader, Callable[[], str]]:
    """A key reader that plays ``script`` (checked with :func:`check_script`), and a function
    returning the keys not used yet."""
    keys = iter(check_script(script))
    rest: list[str] = []

    def read(prompt: str) -> str:
        key = next(keys, "")
        print(f"{prompt}{key or '(end of script)'}")
        return key

    def unused() -> str:
        rest.extend(keys)
        return "".join(rest)

    return read, unused


class TerminalKeys:
    """Keys from the terminal: one key press without Enter on a TTY (cbreak mode for the whole
    session, so keys typed ahead are kept), else the characters of the input; "" at its end.
    Use as a context manager; the terminal's mode is restored on exit."""

    def __init__(self, stream: TextIO | None = None):
        self.stream = stream or sys.stdin
        self._saved: Any = None

    def __enter__(self) -> TerminalKeys:
        if self.stream.isatty():
            try:
                import termios
                import tty
            except ImportError:                     # no termios: line input
                return self
            fd = self.stream.fileno()
            self._saved = termios.tcgetattr(fd)
            tty.setcbreak(fd)
        return self

    def __exit__(self, *exc: Any) -> None:
        if self._saved is not None:
            import termios
            termios.tcsetattr(self.stream.fileno(), termios.TCSADRAIN, self._saved)
            self._saved = None

    def _key(self) -> str:
        while True:
            c = self.stream.read(1)
            if c in ("", "\x04"):                  # end of input / Ctrl-D
                return ""
            if not c.isspace():
                return c

    def __call__(self, prompt: str) -> str:
        print(prompt, end="", flush=True)
        key = self._key()
        print(key if key else "(end of input)")
        return key


# -- plots ------------------------------------------------------------------------------------------

def plot_segment(seg: SegmentToLabel, fig: Any = None) -> Any:
    """Draw the segment's judged variables over time (``CONTEXT`` s either side in grey, the segment
    shaded) on ``fig`` (a new :class:`matplotlib.figure.Figure` if None); returns the figure."""
    from matplotlib.figure import Figure

    k = len(seg.variables)
    if fig is None:
        fig = Figure(figsize=(6.4, 1.0 + 1.3 * k), dpi=90)
    fig.clear()
    pad = int(round(CONTEXT / seg.dt))
    lo, hi = max(0, seg.start - pad), min(len(seg.values), seg.end + pad)
    t = np.arange(lo, hi) * seg.dt
    inside = (np.arange(lo, hi) >= seg.start) & (np.arange(lo, hi) < seg.end)
    axes = fig.subplots(k, 1, sharex=True, squeeze=False)[:, 0]
    for ax, name, col in zip(axes, seg.variables, seg.values[lo:hi].T):
        ax.plot(t, np.where(inside, np.nan, col), color="0.65", lw=1.0)
        ax.plot(t, np.where(inside, col, np.nan), color="C0", lw=1.3)
        ax.axvspan(seg.start * seg.dt, seg.end * seg.dt, color="C0", alpha=0.08, lw=0)
        ax.set_ylabel(name)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time [s]")
    title = f"{seg.source}: {seg.place}" + (f" ({seg.place_label})" if seg.place_label else "")
    sub = []
    if seg.earlier is not None:
        sub.append(f"earlier: {'success' if seg.earlier.success else 'failure'} by {seg.earlier.labeller}")
    if seg.score is not None:
        sub.append(f"judge: {seg.score:.2f}")
    fig.suptitle(title + ("\n" + "; ".join(sub) if sub else ""), fontsize=10)
    fig.tight_layout()
    return fig


def plot_name(i: int, seg: SegmentToLabel) -> str:
    """A file name for segment ``i``'s plot."""
    src = re.sub(r"[^A-Za-z0-9_.-]+", "-", seg.source)
    return f"{i + 1:03d}_{src}_{seg.place}_{seg.start}-{seg.end}.png"


class _Window:
    """A matplotlib window that shows one segment at a time without blocking the terminal."""

    def __init__(self) -> None:
        import matplotlib.pyplot as plt
        self.plt = plt
        self.fig = None

    def show(self, seg: SegmentToLabel) -> None:
        if self.fig is None or not self.plt.fignum_exists(self.fig.number):
            self.fig = self.plt.figure(figsize=(6.4, 1.0 + 1.3 * len(seg.variables)), dpi=90)
        plot_segment(seg, self.fig)
        self.fig.canvas.manager.set_window_title(f"multiform label: {seg.source} {seg.place}")
        self.plt.show(block=False)
        self.plt.pause(0.05)

    def close(self) -> None:
        if self.fig is not None:
            self.plt.close(self.fig)


def can_show() -> bool:
    """Whether a plot window can be opened (a display and an interactive matplotlib backend)."""
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        return False
    import matplotlib
    import matplotlib.pyplot  # noqa: F401  (resolves the backend)
    return matplotlib.get_backend().lower() not in {"agg", "pdf", "ps", "svg", "cairo", "template"}


# -- the session ------------------------------------------------------------------------------------

def label_session(model_dir: str | os.PathLike, source: str | os.PathLike, labeller: str | None = None,
                  script: str | None = None, show: bool = True, plots: str | os.PathLike | None = None,
                  refit: bool = False, places: Sequence[str] | None = None, seed: int = 0,
                  read_key: KeyReader | None = None, log: Callable[[str], None] = print) -> SessionResult:
    """Let a person label the judged segments of ``source`` into ``model_dir``'s label store.

    Keys come from ``script`` if given, else from ``read_key``, else from the terminal. ``show``
    opens a plot window when a display is available; ``plots`` saves every shown segment's plot
    there. Every input is checked (model, labels, judges, source, script, labeller, places, plots
    folder) before anything is written.
    """
    labeller = check_labeller(default_labeller() if labeller is None else labeller)
    unused: Callable[[], str] = lambda: ""  # noqa: E731
    if script is not None:
        read_key, unused = script_reader(script)
    model = SkillModel(model_dir)
    manifest = model.manifest
    apn = model.apn
    store = model.labels
    judges = model.judges()
    sources = read_sources(source, manifest.get("demos"))
    segments = segments_to_label(apn, sources, store, judges, places)
    if not segments:
        raise InvalidInput(f"no stays in a judged place ({', '.join(places or judged_places(apn))}) to label",
                           file=str(source))
    plot_dir = None if plots is None else Path(plots)
    if plot_dir is not None and plot_dir.exists() and not plot_dir.is_dir():
        raise InvalidInput("exists and is not a folder", file=str(plot_dir), element="--plots")
    window = _Window() if show and can_show() else None
    result = SessionResult(segments=len(segments))
    log(f"{len(segments)} segment(s) to label from {source} as {labeller!r}; keys: {KEY_HELP}")
    with ExitStack() as stack:
        if read_key is None:
            read_key = stack.enter_context(TerminalKeys())
        if window is not None:
            stack.callback(window.close)
        for i, seg in enumerate(segments):
            if plot_dir is not None:
                result.plots.append(_save_plot(plot_dir, i, seg))
            if window is not None:
                window.show(seg)
            key = _ask(read_key, f"[{i + 1}/{len(segments)}] {seg.describe()} — s/f/k/q? ", log)
            if key in ("", "q"):
                result.quit = key == "q"
                result.unlabelled = len(segments) - i
                break
            if key == "k":
                result.skipped += 1
                continue
            record = LabelRecord(source=seg.source, start=seg.start, end=seg.end, transition=seg.place,
                                 place=seg.place, success=key == "s", labeller=labeller, time=now())
            store.add(record)
            result.records.append(record)
    result.unused_keys = unused()
    if refit and result.records:
        labelled = list(dict.fromkeys(r.place for r in result.records))
        result.refit = refit_judges(model, labelled, {s.source: s.episode for s in sources}, labeller, seed=seed)
    return result


def _save_plot(plot_dir: Path, i: int, seg: SegmentToLabel) -> Path:
    """Segment ``i``'s plot, saved in ``plot_dir``."""
    plot_dir.mkdir(parents=True, exist_ok=True)
    out = plot_dir / plot_name(i, seg)
    plot_segment(seg).savefig(out)
    return out


def _ask(read_key: KeyReader, prompt: str, log: Callable[[str], None]) -> str:
    """The person's key for one segment: asked again, with the keys' help, until it is one of them
    (or nothing: the input ended)."""
    key = read_key(prompt)
    while key and key not in KEYS:
        log(f"  keys: {KEY_HELP}")
        key = read_key(prompt)
    return key
