"""A trial as a rerun recording: written live while the executor runs it (:class:`TrialStream`, an
executor observer) or afterwards from a saved trace or a demonstration (:func:`log_trace`).

Entities, on the timelines ``tick`` (control ticks) and ``sim_time``:

* ``state/<variable>``, ``command/<command>`` — scalars, every tick;
* ``net/marking/<place>`` — the tokens of each place, at the start and at every firing;
* ``net/fired`` — a text log line per firing (the transition); ``net/graph`` — the net's places and
  transitions as a graph, marked places and the transition that just fired coloured;
* ``scene/<body>`` — the MuJoCo bodies (their geoms once, their poses every ``scene_every`` ticks);
* ``events`` — pushes, safety clips and the outcome; ``judges/<place>`` — the judges' grades at the end.

The recording is saved to an ``.rrd`` file (written beside its final name and renamed when complete),
and optionally sent live to a rerun viewer at the same time. The live copy is best effort and never
holds up a trial: it goes out from a thread of its own through a bounded queue (what a slow viewer
cannot take is dropped), and closing waits for it a few seconds at most; a viewer that is
unreachable or never answers costs the file nothing and the command at most those seconds.
"""

from __future__ import annotations

import os
import queue
import sys
import tempfile
import threading
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr

from ..petri.net import APN
from . import scene

APP = "multiform"
MARKED, FIRED, IDLE = (27, 158, 119, 255), (192, 57, 43, 255), (200, 200, 200, 255)


def viewer_url(live: str | None) -> str | None:
    """Where to send a live stream: ``None`` (file only), a rerun gRPC URL, or ``"spawn"`` to start
    a local viewer (only with a display; otherwise the file alone is written)."""
    if live is None or live == "":
        return None
    if live == "spawn":
        if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            return None
        rr.spawn(connect=False)
        return "rerun+http://127.0.0.1:9876/proxy"
    return live


class LiveView:
    """A best-effort copy of a recording sent to the viewer at ``url`` from a thread of its own:
    the calls (:meth:`call`) go through a queue of ``capacity`` entries and are dropped when it is
    full, so neither a slow nor an unreachable viewer ever blocks the caller."""

    FLUSH_SECONDS = 2.0

    def __init__(self, url: str, recording_id: str, capacity: int = 100_000):
        self.url = url
        self.dropped = 0
        self.error = ""
        self._rec: rr.RecordingStream | None = None
        self._queue: queue.Queue = queue.Queue(maxsize=capacity)
        self._closing = threading.Event()
        self._thread = threading.Thread(target=self._send, args=(recording_id,), name="multiform-view", daemon=True)
        self._thread.start()

    def call(self, method: str, *args: Any, **kwargs: Any) -> None:
        """``RecordingStream.<method>(*args, **kwargs)`` on the live stream, when the thread gets to it."""
        try:
            self._queue.put_nowait((method, args, kwargs))
        except queue.Full:
            self.dropped += 1

    def _send(self, recording_id: str) -> None:
        try:
            self._rec = rec = rr.RecordingStream(APP, recording_id=recording_id)
            rec.set_sinks(rr.GrpcSink(self.url))
            while True:
                try:
                    method, args, kwargs = self._queue.get(timeout=0.05)
                except queue.Empty:
                    if self._closing.is_set():
                        break
                    continue
                getattr(rec, method)(*args, **kwargs)
            rec.flush(timeout_sec=self.FLUSH_SECONDS)
        except Exception as exc:          # the viewer is best effort: its failure is reported, not raised
            self.error = f"{type(exc).__name__}: {exc}"
            if self._rec is not None:
                _keep_for_ever(self._rec)
            return
        rec.disconnect()

    def close(self, timeout: float = 5.0) -> str:
        """Let the thread send what is queued, waiting ``timeout`` seconds at most; returns "" if the
        viewer took it all, else what went wrong. A viewer still not answering is left behind (see
        :func:`_keep_for_ever`)."""
        self._closing.set()
        self._thread.join(timeout)
        if self._thread.is_alive():
            if self._rec is not None:
                _keep_for_ever(self._rec)
            return f"the viewer at {self.url} did not answer within {timeout:g} s"
        if self.error:
            return f"the viewer at {self.url} could not be reached ({self.error.splitlines()[0][:200]})"
        if self.dropped:
            return f"the viewer at {self.url} was too slow: {self.dropped} of the recording's messages were not sent"
        return ""


def _keep_for_ever(rec: rr.RecordingStream) -> None:
    """Never release ``rec``, whose viewer does not answer: rerun disconnects a released stream (at the
    next release of any stream, or at exit) by waiting for its viewer, for ever if it never answers.
    The stream is leaked instead (a reference that is never dropped) and rerun's exit-time flush of
    every stream is switched off."""
    import ctypes
    ctypes.pythonapi.Py_IncRef(ctypes.py_object(rec))
    rr.unregister_shutdown()


class _Tee:
    """The file's recording stream, each call also queued for the live view."""

    def __init__(self, rec: rr.RecordingStream, live: LiveView):
        self._rec, self._live = rec, live

    def __getattr__(self, name: str) -> Any:
        method = getattr(self._rec, name)

        def both(*args: Any, **kwargs: Any) -> Any:
            self._live.call(name, *args, **kwargs)
            return method(*args, **kwargs)
        return both


_unreachable: set[str] = set()        # viewers that failed once: later recordings of this process skip them


class Recording:
    """A rerun recording saved to ``path`` (atomically, on :meth:`close`) and sent to ``live``
    (best effort: see :class:`LiveView`)."""

    def __init__(self, path: str | os.PathLike, title: str = "", live: str | None = None):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{self.path.name}.", suffix=".rrd", dir=self.path.parent)
        os.close(fd)
        self._tmp = Path(tmp)
        recording_id = f"{self.path.stem}-{os.getpid()}-{id(self)}"
        self._file = rr.RecordingStream(APP, recording_id=recording_id)
        self._file.set_sinks(rr.FileSink(str(self._tmp)))
        url = viewer_url(live)
        self.live = LiveView(url, recording_id) if url and url not in _unreachable else None
        self.rec: Any = _Tee(self._file, self.live) if self.live is not None else self._file
        if title:
            self.rec.log("description", rr.TextDocument(title), static=True)

    def close(self) -> Path:
        """Complete the file (always) and the live copy (best effort; a failure is said once on stderr)."""
        self._file.flush()
        self._file.disconnect()
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(self._tmp, 0o666 & ~umask)        # mkstemp made it private; a saved file gets the usual mode
        os.replace(self._tmp, self.path)
        if self.live is not None:
            problem = self.live.close()
            if problem and self.live.url not in _unreachable:
                _unreachable.add(self.live.url)
                print(f"multiform: the view: {problem}; the recordings are saved, the viewer is not tried again "
                      f"({self.path})", file=sys.stderr)
        return self.path

    def abandon(self) -> None:
        self._file.disconnect()
        if self.live is not None:
            self.live.close(timeout=1.0)
        self._tmp.unlink(missing_ok=True)


def _times(ticks: np.ndarray, dt: float) -> list[rr.TimeColumn]:
    ticks = np.asarray(ticks, dtype=np.int64)
    return [rr.TimeColumn("tick", sequence=ticks), rr.TimeColumn("sim_time", duration=ticks * dt)]


def _set_time(rec: rr.RecordingStream, tick: int, dt: float) -> None:
    rec.set_time("tick", sequence=int(tick))
    rec.set_time("sim_time", duration=tick * dt)


def log_net(rec: rr.RecordingStream, apn: APN) -> None:
    """The net's arcs, once."""
    edges = [(p, t.id) for t in apn.transitions for p in t.inputs] + [(t.id, p) for t in apn.transitions for p in t.outputs]
    rec.log("net/graph", rr.GraphEdges(edges, graph_type="directed"), static=True)


def log_marking(rec: rr.RecordingStream, apn: APN | None, tick: int, dt: float, marking: Sequence[int],
                fired: str | None, place_ids: Sequence[str] = ()) -> None:
    """The marking at ``tick`` (scalars per place) and the graph with it (and ``fired``) coloured;
    without the net (``apn`` None) the marking of ``place_ids`` and the firing only."""
    _set_time(rec, tick, dt)
    places = apn.place_ids if apn is not None else tuple(place_ids)
    for p, n in zip(places, marking):
        rec.log(f"net/marking/{p}", rr.Scalars([float(n)]))
    if apn is not None:
        ids = list(apn.place_ids) + list(apn.transition_ids)
        colours = [MARKED if n > 0 else IDLE for n in marking] + [FIRED if t == fired else IDLE
                                                                  for t in apn.transition_ids]
        labels = [f"{p} ({n})" if n else p for p, n in zip(apn.place_ids, marking)] + list(apn.transition_ids)
        rec.log("net/graph", rr.GraphNodes(ids, labels=labels, colors=colours))
    if fired is not None:
        rec.log("net/fired", rr.TextLog(fired, level="INFO"))


def log_series(rec: rr.RecordingStream, prefix: str, names: Sequence[str], ticks: np.ndarray, dt: float,
               rows: np.ndarray) -> None:
    """Columns of ``rows`` (T, len(names)) as scalar series ``prefix/<name>``."""
    if not len(ticks):
        return
    times = _times(ticks, dt)
    for j, name in enumerate(names):
        rec.send_columns(f"{prefix}/{name}", indexes=times, columns=rr.Scalars.columns(scalars=rows[:, j]))


def log_event(rec: rr.RecordingStream, tick: int, dt: float, text: str, level: str = "INFO") -> None:
    _set_time(rec, tick, dt)
    rec.log("events", rr.TextLog(text, level=level))


def log_grade(rec: rr.RecordingStream, tick: int, dt: float, grade: Any, success: bool | None = None) -> None:
    """The judges' grades of a trial (a :class:`multiform.learn.judge.TrialGrade`) at its end."""
    _set_time(rec, tick, dt)
    for place, score in grade.places.items():
        rec.log(f"judges/{place}", rr.Scalars([float(score)]))
    rec.log("judges/trial", rr.Scalars([float(grade.score)]))
    verdict = "success" if (grade.success if success is None else success) else "failure"
    rec.log("events", rr.TextLog(f"the judges: score {grade.score:.3f}, {verdict}", level="INFO"))


class TrialStream:
    """An executor observer that streams the running trial (see the module docstring).

    State and command rows are sent in batches of ``flush_every`` ticks (0.5 s of simulated time by
    default), firings and events at once; the scene's poses are kept every ``scene_every`` ticks.
    Call :meth:`grade` after the trial to add the judges' grades; the file is complete once the
    trial ends (or after :meth:`grade`, when it is called).
    """

    def __init__(self, apn: APN, path: str | os.PathLike, title: str = "", live: str | None = None,
                 flush_every: int = 500, scene_every: int = 33):
        self.apn, self.title, self.live = apn, title, live
        self.path = Path(path)
        self.flush_every, self.scene_every = int(flush_every), int(scene_every)
        self.recording: Recording | None = None
        self.trace = None

    # -- the executor's calls -------------------------------------------------------------------
    def start(self, executor: Any, seed: int) -> None:
        self.recording = Recording(self.path, self.title or f"trial seed {seed}", self.live)
        rec = self.recording.rec
        self.dt = executor.dt
        self.value_names = tuple(executor.apn.variables) + tuple(executor.apn.derived)   # as the trace keeps them
        self.command_names = tuple(executor.cmd_names)
        self._n = len(self.value_names)
        self._sat = executor.saturator
        self._clips: dict[str, int] = {}
        self._clipping: set[str] = set()
        self._pushing = False
        self._ticks: list[int] = []
        self._values: list[list[float]] = []
        self._cmds: list[list[float]] = []
        self._streamed = 0
        base = executor.env.unwrapped
        self._mj = (base.model, base.data) if hasattr(base, "model") and hasattr(base, "data") else None
        self._pose_ticks: list[int] = []
        self._xpos: list[np.ndarray] = []
        self._xquat: list[np.ndarray] = []
        self._strings: list[list[np.ndarray]] = []
        if self._mj is not None:
            self._bodies = scene.scene_bodies(self._mj[0])
            self._tendons = scene.scene_tendons(self._mj[0])
            scene.log_geometry(rec, self._mj[0], self._bodies)
            self._pose(0)
        log_net(rec, executor.apn)
        self.apn = executor.apn
        log_marking(rec, self.apn, 0, self.dt, executor.runner.marking, None)

    def fired(self, tick: int, runner: Any) -> None:
        log_marking(self.recording.rec, self.apn, tick, self.dt, runner.marking, runner.firings[-1].transition)

    def tick(self, tick: int, values: list[float], command: list[float], info: Mapping[str, Any]) -> None:
        self._ticks.append(tick)
        self._values.append(values[: self._n])
        self._cmds.append(list(command))
        push = float(info.get("disturbance", 0.0) or 0.0)
        if (push != 0.0) != self._pushing:
            self._pushing = push != 0.0
            log_event(self.recording.rec, tick, self.dt, f"push: {push:+.3g} applied" if self._pushing else "push ends",
                      "WARN" if self._pushing else "INFO")
        counts = self._sat.log.counts
        rising = {k for k, v in counts.items() if v != self._clips.get(k, 0)}
        for limit in sorted(rising - self._clipping):     # a clip begins (a run of clipped ticks is one event)
            log_event(self.recording.rec, tick, self.dt, f"safety clip: {limit}", "WARN")
        if rising or self._clipping:
            self._clips, self._clipping = dict(counts), rising
        if self._mj is not None and (tick + 1) % self.scene_every == 0:
            self._pose(tick + 1)
        if len(self._ticks) >= self.flush_every:
            self._flush()

    def end(self, trace: Any) -> None:
        """Send what is left, then the trace's rows the loop did not step (its last tick), the outcome."""
        self._flush()
        rec = self.recording.rec
        rest = np.arange(self._streamed, trace.num_ticks)
        if len(rest):
            log_series(rec, "state", self.value_names, rest, self.dt, trace.values[rest].astype(np.float64))
            log_series(rec, "command", self.command_names, rest, self.dt, trace.commands[rest].astype(np.float64))
        last = max(trace.num_ticks - 1, 0)
        log_event(rec, last, self.dt, f"outcome: {trace.outcome}", "INFO" if trace.success else "WARN")
        self.trace = trace
        self._last = last

    def grade(self, grade: Any, success: bool | None = None) -> None:
        log_grade(self.recording.rec, self._last, self.dt, grade, success)

    def close(self) -> Path:
        """Finish the file (call after :meth:`grade`, if any)."""
        return self.recording.close()

    # -- internals ------------------------------------------------------------------------------
    def _pose(self, tick: int) -> None:
        d = self._mj[1]
        self._pose_ticks.append(tick)
        self._xpos.append(d.xpos[self._bodies].copy())
        self._xquat.append(d.xquat[self._bodies].copy())
        if self._tendons:
            self._strings.append(scene.tendon_paths(d, self._tendons))

    def _flush(self) -> None:
        rec = self.recording.rec
        if self._ticks:
            ticks = np.array(self._ticks)
            log_series(rec, "state", self.value_names, ticks, self.dt, np.array(self._values, np.float32).astype(np.float64))
            log_series(rec, "command", self.command_names, ticks, self.dt, np.array(self._cmds, np.float32).astype(np.float64))
            self._streamed = int(ticks[-1]) + 1
            self._ticks, self._values, self._cmds = [], [], []
        if self._pose_ticks:
            scene.log_poses(rec, self._mj[0], self._bodies, np.array(self._pose_ticks), self.dt,
                            np.array(self._xpos), np.array(self._xquat))
            if self._tendons:
                scene.log_tendons(rec, self._mj[0], self._tendons, self._pose_ticks, self.dt, self._strings)
            self._pose_ticks, self._xpos, self._xquat, self._strings = [], [], [], []


def trial_views(folder: str | os.PathLike, live: str | None = None, name: str = "trial",
                pick: Any = None) -> Any:
    """A factory ``(trial index, executor) -> TrialStream`` that records trial ``k`` to
    ``folder/<name>_<k>.rrd`` (and sends it to ``live``); ``pick(k)`` false skips a trial. Pass it as
    a practice loop's ``observe``; any loop that runs trials by index wires the view in this one line."""
    folder = Path(folder)

    def make(k: int, executor: Any) -> TrialStream | None:
        if pick is not None and not pick(k):
            return None
        return TrialStream(executor.apn, folder / f"{name}_{k:04d}.rrd", title=f"{name} {k}", live=live)
    return make


def read_recording(path: str | os.PathLike) -> dict[str, dict[str, list]]:
    """An ``.rrd`` file read back with rerun's own reader: per entity path, its columns (the
    timelines and each component) as lists, rows in the order they were logged."""
    from rerun.chunk import RrdReader
    out: dict[str, dict[str, list]] = {}
    for chunk in RrdReader(str(path)).store().stream():
        cols = chunk.to_record_batch().to_pydict()
        n = len(next(iter(cols.values()))) if cols else 0
        ent = out.setdefault(str(chunk.entity_path), {})
        have = max((len(v) for v in ent.values()), default=0)
        for name in set(ent) | set(cols):
            ent.setdefault(name, [None] * have).extend(cols.get(name, [None] * n))
    return out
