"""Trials, demonstrations and whole pipelines as Ray tasks, on one machine or a cluster.

No shared filesystem is assumed. A model directory travels as bytes through Ray's object store
(only the files a trial reads: the manifest, the skill and its history, the labels and the
artifacts ``model.json`` lists, each checked against its SHA-256 before it leaves); a worker writes
it once into a node-local temporary folder named for its digest and verifies it there. Trial
records and episodes come back as plain data and only the driver writes files. A task whose worker
dies is run again (``max_retries``); a trial is a function of (model, task, seed) alone, so where
it ran does not change its record.

Every node needs the same multiform installed (``pip install 'multiform[ray]'``); a worker with
another version refuses the work.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future
from dataclasses import replace
from pathlib import Path
from typing import Any

import ray

from . import __version__
from .errors import InvalidInput

MAX_RETRIES = 3                       # reruns of a task whose worker or node died
OBJECT_STORE_BYTES = 200 * 2**20      # of a cluster started here (`--ray local`); models are small
MODEL_EXTRA_FILES = ("skill.history.jsonl", "labels.jsonl")


# -- connecting -------------------------------------------------------------------------------------

def connect(address: str, num_cpus: int | None = None) -> None:
    """Join the Ray cluster at ``address`` once per process: ``auto`` (the running cluster this
    machine belongs to), ``local`` (start one here with ``num_cpus`` CPUs), or ``HOST:PORT`` /
    ``ray://HOST:PORT``."""
    if ray.is_initialized():
        return
    env = {"runtime_env": {"env_vars": {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
                                        "MKL_NUM_THREADS": "1", "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}}}
    if address not in ("auto", "local"):
        _reachable(address)
    try:
        if address == "local":
            # Ray runs its workers at nice 15 (below its own services); here the workers are the work
            os.environ.setdefault("RAY_worker_niceness", "0")
            ray.init(num_cpus=num_cpus, include_dashboard=False, object_store_memory=OBJECT_STORE_BYTES,
                     logging_level="WARNING", configure_logging=True, **env)
        else:
            ray.init(address=address, logging_level="WARNING", **env)
    except (ConnectionError, ValueError, RuntimeError) as exc:
        raise InvalidInput(f"cannot join the Ray cluster at {address!r}: {str(exc).splitlines()[0]}",
                           element="--ray") from None


def _reachable(address: str, seconds: float = 10.0) -> None:
    """Refuse at once an address where nothing listens (Ray itself would retry for minutes)."""
    import socket
    host, _, port = address.removeprefix("ray://").rpartition(":")
    try:
        socket.create_connection((host or "127.0.0.1", int(port)), timeout=seconds).close()
    except ValueError:
        raise InvalidInput(f"{address!r} is not auto, local, HOST:PORT or ray://HOST:PORT", element="--ray") from None
    except OSError as exc:
        raise InvalidInput(f"cannot reach the Ray cluster at {address!r} ({exc.strerror or exc})",
                           element="--ray") from None


_REMOTE: dict[str, Any] = {}


def _remote(fn: Callable[..., Any], **options: Any) -> Any:
    """``fn`` as a Ray remote function (made once per process)."""
    key = f"{fn.__module__}.{fn.__qualname__}"
    if key not in _REMOTE:
        _REMOTE[key] = ray.remote(max_retries=MAX_RETRIES, num_cpus=1, **options)(fn)
    return _REMOTE[key]


def _future(ref: ray.ObjectRef) -> Future:
    """A :class:`concurrent.futures.Future` of ``ref``; a task's own error is re-raised as itself
    (a bad model shows as the same one-line error as on the local pool)."""
    out: Future = Future()

    def done(f: Future) -> None:
        try:
            out.set_result(f.result())
        except ray.exceptions.RayTaskError as exc:
            cause = getattr(exc, "cause", None)
            out.set_exception(cause if isinstance(cause, InvalidInput) else exc)
        except BaseException as exc:  # noqa: BLE001  (handed to the caller of result())
            out.set_exception(exc)
    ref.future().add_done_callback(done)
    return out


def _same_version(version: str) -> None:
    if version != __version__:
        raise RuntimeError(f"this Ray worker runs multiform {__version__}, the driver {version}; install the same "
                           f"version on every node")


# -- a model directory as bytes ---------------------------------------------------------------------

def pack_model(path: str | os.PathLike, attempts: int = 5, env_modules: Sequence[str] = ()) -> dict[str, Any]:
    """The files of model directory ``path`` that a trial reads, as ``{"digest", "files": {name:
    bytes}}``. The model is verified first (its env id may import ``env_modules``); a file that
    changes while it is read (a job revising the model meanwhile) is read again."""
    from .model import SkillModel
    root = Path(path)
    SkillModel(root, env_modules=env_modules).verify()
    for _ in range(attempts):
        manifest = (root / "model.json").read_bytes()
        listed = json.loads(manifest)["artifacts"]
        files = {"model.json": manifest, **{rel: (root / rel).read_bytes() for rel in listed}}
        files.update({n: (root / n).read_bytes() for n in MODEL_EXTRA_FILES if (root / n).is_file()})
        if all(hashlib.sha256(files[rel]).hexdigest() == info["sha256"] for rel, info in listed.items()):
            return {"digest": pack_digest(files), "files": files}
        time.sleep(0.2)
    raise InvalidInput("kept changing while it was read for the cluster", file=str(root))


def pack_digest(files: dict[str, bytes]) -> str:
    """The digest of a packed model's files (their names and SHA-256s)."""
    h = hashlib.sha256()
    for name in sorted(files):
        h.update(name.encode() + b"\0" + hashlib.sha256(files[name]).digest())
    return h.hexdigest()


def materialise(pack: dict[str, Any], root: str | os.PathLike | None = None, env_modules: Sequence[str] = ()
                ) -> Path:
    """Write a packed model into ``root`` (default: this node's temporary folder) as
    ``multiform-models/<digest>``, once per node, and verify it (its env id may import
    ``env_modules``); returns the folder."""
    from .model import SkillModel
    files: dict[str, bytes] = pack["files"]
    if pack_digest(files) != pack["digest"]:
        raise InvalidInput("arrived damaged (digest differs)", file=f"packed model {pack['digest'][:12]}")
    base = Path(root or tempfile.gettempdir()) / "multiform-models"
    final = base / pack["digest"]
    if not final.is_dir():
        base.mkdir(parents=True, exist_ok=True)
        partial = Path(tempfile.mkdtemp(prefix=".partial-", dir=base))
        for rel, data in files.items():
            parts = Path(rel).parts
            if Path(rel).is_absolute() or ".." in parts or not parts:
                raise InvalidInput("not a place for a model file", file=f"packed model {pack['digest'][:12]}",
                                   element=rel)
            (partial / rel).parent.mkdir(parents=True, exist_ok=True)
            (partial / rel).write_bytes(data)
        try:
            os.rename(partial, final)
        except OSError:                   # another worker of this node wrote it first
            shutil.rmtree(partial, ignore_errors=True)
    SkillModel(final, env_modules=env_modules).verify()
    return final


_MODELS: dict[str, Path] = {}


def _local_model(digest: str, box: list[ray.ObjectRef], env_modules: Sequence[str] = ()) -> Path:
    """This worker's copy of the packed model ``digest`` (fetched from the object store once)."""
    if digest not in _MODELS:
        _MODELS[digest] = materialise(ray.get(box[0]), env_modules=env_modules)
    return _MODELS[digest]


# -- evaluation trials ------------------------------------------------------------------------------

def evaluation_trial(version: str, run: Callable[..., dict[str, Any]], task: str, env_overrides: dict[str, Any],
                     variant: Any, digest: str, box: list[ray.ObjectRef], spec: Any) -> dict[str, Any]:
    """One evaluation trial on a Ray worker: ``run(task, env_overrides, variant, spec)`` (the
    evaluation's :func:`~multiform.evaluation.trial_in_worker`) on this node's copy of the model.
    ``box`` holds the packed model's reference unresolved, so only a worker without the model
    fetches it."""
    _same_version(version)
    local = _local_model(digest, box, variant.env_modules)
    return run(task, env_overrides, replace(variant, model_dir=str(local)), spec)


class RayTrials:
    """The Ray side of :class:`~multiform.evaluation.Evaluator`: trials as tasks, one CPU each, each
    ``run(task, env_overrides, variant, spec)``."""

    def __init__(self, run: Callable[..., dict[str, Any]], task: str, env_overrides: dict[str, Any], address: str,
                 num_cpus: int | None = None):
        connect(address, num_cpus)
        self.run, self.task, self.env_overrides = run, task, env_overrides
        self._packs: dict[str, ray.ObjectRef] = {}
        self._refs: list[ray.ObjectRef] = []

    def submit(self, variant: Any, trials: Sequence[Any]) -> list[Future]:
        pack = pack_model(variant.model_dir, env_modules=variant.env_modules)
        digest = pack["digest"]
        if digest not in self._packs:
            self._packs[digest] = ray.put(pack)
        fn = _remote(evaluation_trial)
        refs = [fn.remote(__version__, self.run, self.task, self.env_overrides, variant, digest, [self._packs[digest]],
                          spec) for spec in trials]
        self._refs += refs
        return [_future(r) for r in refs]

    def close(self) -> None:
        """Cancel the trials not yet finished (nothing waits for them any more)."""
        _, pending = ray.wait(self._refs, num_returns=len(self._refs), timeout=0) if self._refs else ([], [])
        for r in pending:
            ray.cancel(r)
        self._refs, self._packs = [], {}


# -- demonstrations ---------------------------------------------------------------------------------

def demonstration(version: str, run: Callable[..., Any], task: str, env_kwargs: dict[str, Any],
                  mentor_kwargs: dict[str, Any], seed: int) -> Any:
    """One scripted-mentor demonstration on a Ray worker: ``run(task, env_kwargs, mentor_kwargs,
    seed)`` (the recorder's :func:`~multiform.teach.record.demonstration_in_worker`; an Episode)."""
    _same_version(version)
    return run(task, env_kwargs, mentor_kwargs, seed)


def record_demos(run: Callable[..., Any], task: str, seeds: Sequence[int], env_kwargs: dict[str, Any],
                 mentor_kwargs: dict[str, Any], address: str, num_cpus: int | None = None,
                 progress: Callable[[int, int], None] | None = None) -> list[Any]:
    """One demonstration per seed as Ray tasks (each ``run(task, env_kwargs, mentor_kwargs, seed)``),
    in seed order."""
    connect(address, num_cpus)
    fn = _remote(demonstration)
    refs = [fn.remote(__version__, run, task, env_kwargs, mentor_kwargs, s) for s in seeds]
    out = []
    for i, ref in enumerate(refs):
        out.append(_future(ref).result())
        if progress:
            progress(i + 1, len(refs))
    return out


# -- anything else: whole pipelines -----------------------------------------------------------------

def run_tasks(fn: Callable[..., Any], calls: Sequence[tuple], address: str, num_cpus: int | None = None,
              cpus_per_task: int = 1) -> Iterator[tuple[int, Any]]:
    """``fn(*call)`` for every call as a Ray task; yields (index, result) as each finishes.
    ``fn`` must return plain data; it runs in a worker's own temporary folder if it writes."""
    connect(address, num_cpus)
    remote = ray.remote(max_retries=MAX_RETRIES, num_cpus=cpus_per_task)(fn)
    index = {remote.remote(*call): i for i, call in enumerate(calls)}
    pending = list(index)
    while pending:
        done, pending = ray.wait(pending, num_returns=1)
        yield index[done[0]], _future(done[0]).result()
