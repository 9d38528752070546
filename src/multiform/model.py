"""A skill model directory: everything the robot has learned about one skill, pickle-free.

::

    MODEL_DIR/
      skill.yaml             the mentor's definition, copied once and never written again
      skill.history.jsonl    the robot's revisions of it (JSON lines)
      model.json             manifest: skill, env, the demonstrations it learned from, summaries
      laws/<fit>.npz         GP control laws (the mentor-only fit is named for its law; refits from
                             practice get new names, and the net says which fit each law runs)
      experience/            the robot's own graded practice: segments.jsonl (provenance) + traces
      judges/<place>.npz     SVM judges
      conditions/<name>.npz  learned conditions (switch SVMs, region conditions)
      regions.npz            place regions
      inverse_model.npz      the auxiliary inverse model (optional)
      labels.jsonl           every label: the mentor's and later ones
      mentors.json           with several mentors: how far each is trusted, per maneuver and place,
                             with its evidence and how practice moved it

Everything is ``.npz`` + JSON, loaded with ``allow_pickle=False``; a shared model directory can
never run code: its env must be registered (a ``module:`` id is refused unless the caller names
the module). ``model.json`` lists every learned artifact with its kind and SHA-256, and
:meth:`SkillModel.verify` checks them all (present, unchanged, loadable, finite) before any trial.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import hashlib
import os
import re
import shutil
import tempfile
from collections.abc import Iterator, Mapping, Sequence
from functools import cached_property
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from .demos.dataset import read_dataset
from .demos.episode import Episode
from .errors import InvalidInput, MissingInput, Problem
from .io import plain_data_problems, read_json, write_json
from .lock import exclusive
from .learn.condition import load_condition
from .learn.fusion import FILE as FUSION_FILE, Fusion
from .learn.gp import GPLaw
from .learn.judge import Judge, TrialGrade, credit_handovers, grade_episode
from .learn.labels import LabelStore
from .learn.region import PlaceRegions, share_regions
from .learn.views import place_episode
from .petri.net import APN
from .petri.revision import History
from .petri.skillfile import load_skill, resolve_skill
from .registry import register_envs
from .runtime.executor import Executor
from .runtime.trace import Trace

MANIFEST_VERSION = 2
# where each kind of learned artifact lives in a model directory
ARTIFACT_FOLDERS = {"laws": "law", "judges": "judge", "conditions": "condition"}
ARTIFACT_FILES = {"regions.npz": "regions", "inverse_model.npz": "inverse_model"}


class SkillModel:
    """Opens (or creates with :meth:`create`) a model directory; pieces load lazily.

    ``env_modules`` names the modules a ``module:Env-v0`` env id in ``model.json`` may import
    (none by default: a model directory never makes the library import code)."""

    def __init__(self, path: str | os.PathLike, env_modules: Sequence[str] = ()):
        self.path = Path(path)
        if not self.path.exists():
            raise MissingInput("no such model directory", file=str(self.path))
        if not (self.path / "skill.yaml").is_file():
            raise InvalidInput("not a skill model directory (no skill.yaml)", file=str(self.path))
        self.history = History(self.path / "skill.yaml", self.path / "skill.history.jsonl")
        self.env_modules = tuple(env_modules)
        self._verified: str | None = None        # the state last verified (see verify)
        self._verified_to_run: str | None = None

    @classmethod
    def create(cls, path: str | os.PathLike, skill: str | os.PathLike, demos: str | os.PathLike | None = None,
               env_id: str | None = None, env_kwargs: Mapping[str, Any] | None = None) -> SkillModel:
        """Start a model directory from a skill file (copied) and, optionally, a demonstration file.
        The model runs ``env_id`` (the demonstrations' env), else the skill file's ``env:``; a skill
        file whose ``env:`` names another env is refused rather than silently ignored."""
        path = Path(path)
        src = resolve_skill(skill)
        apn = load_skill(src)                          # validate before writing anything
        if env_id and apn.env and env_id != apn.env:
            raise InvalidInput(f"the skill file says env: {apn.env}, but the demonstrations were recorded on "
                               f"{env_id}; the model runs the demonstrations' env: correct the skill file's env: "
                               "or record on its env", file=str(src), element="env")
        env_id = env_id or apn.env
        register_envs()
        if env_id and env_id in gym.registry:          # arguments the env refuses (read from the demos file)
            where = str(demos) if demos else str(path / "model.json")
            problems = plain_data_problems(dict(env_kwargs or {}), "env_kwargs")
            if problems:
                raise InvalidInput([Problem(where, e, msg) for e, msg in problems])
            make_env(env_id, dict(env_kwargs or {}), where).close()
        path.mkdir(parents=True, exist_ok=True)
        dst = path / "skill.yaml"
        if dst.exists():
            if dst.read_bytes() != src.read_bytes():
                raise InvalidInput("holds a different skill definition; use a new directory", file=str(dst))
        else:
            shutil.copyfile(src, dst)
        manifest = {"format_version": MANIFEST_VERSION, "skill": apn.name,
                    "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
                    "env": env_id, "env_kwargs": dict(env_kwargs or {}),
                    "demos": str(Path(demos).resolve()) if demos else None, "training": {},
                    "artifacts": {"skill.yaml": {"kind": "skill", "sha256": _sha256(dst)}}}
        old = path / "model.json"
        if old.exists():
            manifest = {**read_json(old), **{k: v for k, v in manifest.items() if v is not None and k != "created"}}
        write_json(old, manifest)
        return cls(path)

    # -- manifest ---------------------------------------------------------------------------------
    @property
    def manifest(self) -> dict[str, Any]:
        where = str(self.path / "model.json")
        m = read_json(self.path / "model.json", "model manifest")
        if not isinstance(m, dict):
            raise InvalidInput("must be a JSON object", file=where)
        if m.get("format_version") != MANIFEST_VERSION:
            raise InvalidInput(f"manifest version {m.get('format_version')!r}, this multiform reads version "
                               f"{MANIFEST_VERSION} (retrain the model)", file=where)
        types = {"env": str, "env_kwargs": dict, "training": dict, "artifacts": dict}
        problems = [Problem(where, k, f"must be {t.__name__ if t is not str else 'a string'}, got "
                                      f"{type(m.get(k)).__name__}")
                    for k, t in types.items() if not isinstance(m.get(k), t)]
        if m.get("demos") is not None and not isinstance(m["demos"], str):
            problems.append(Problem(where, "demos", f"must be a file name, got {type(m['demos']).__name__}"))
        if isinstance(m.get("env_kwargs"), dict):
            problems += [Problem(where, e, msg) for e, msg in plain_data_problems(m["env_kwargs"], "env_kwargs")]
        if problems:
            raise InvalidInput(problems)
        return m

    def update_manifest(self, **items: Any) -> None:
        """Merge ``items`` into ``model.json`` (nested dicts merged at every level)."""
        def merge(old: dict[str, Any], new: Mapping[str, Any]) -> dict[str, Any]:
            out = dict(old)
            for k, v in new.items():
                out[k] = merge(out[k], v) if isinstance(v, Mapping) and isinstance(out.get(k), dict) else v
            return out
        with exclusive(self.path / "model.json", wait=True):   # a trainer beside writes it too
            write_json(self.path / "model.json", merge(self.manifest, items))

    def _register(self, path: Path, kind: str) -> None:
        """List a newly written artifact in ``model.json`` with its kind and SHA-256."""
        rel = path.relative_to(self.path).as_posix()
        self.update_manifest(artifacts={rel: {"kind": kind, "sha256": _sha256(path)}})

    # -- integrity --------------------------------------------------------------------------------
    def problems(self, to_run: bool = True) -> list[Problem]:
        """Everything wrong with the directory: artifacts missing, changed, unlisted, unreadable or
        not finite; a history that does not replay; and, for running the skill (``to_run``), the
        net's laws and conditions without a fit, a torque-driven env without its inverse model, an
        env id that is not allowed or arguments the env refuses, demonstrations that are not a file."""
        return directory_problems(self, to_run)

    def verify(self, to_run: bool = True) -> None:
        """Raise :class:`InvalidInput` listing every problem (see :meth:`problems`); a model that
        passed is not checked again until ``model.json`` or its history changes."""
        h = hashlib.sha256()
        for f in (self.path / "model.json", self.history.path):
            h.update(f.read_bytes() if f.is_file() else b"-")
        h.update(b"run" if to_run else b"")
        key = h.hexdigest()
        if key in (self._verified, self._verified_to_run):
            return
        problems = self.problems(to_run)
        if problems:
            raise InvalidInput(problems)
        if to_run:
            self._verified_to_run = key
        else:
            self._verified = key

    # -- the net ----------------------------------------------------------------------------------
    @property
    def apn(self) -> APN:
        """The latest version of the net (original + revisions)."""
        return self.history.latest()

    @property
    def version(self) -> int:
        return len(self.history.revisions())

    # -- demonstrations ---------------------------------------------------------------------------
    @cached_property
    def raw_episodes(self) -> list[Episode]:
        """The demonstrations with their labels as the mentors gave them."""
        demos = self.manifest.get("demos")
        if not demos:
            raise InvalidInput("the model has no demonstration file", file=str(self.path / "model.json"))
        return list(read_dataset(demos))

    @property
    def episodes(self) -> list[Episode]:
        """The demonstrations the learners read: as recorded with one mentor; with several, each stay
        the fused verdicts overrule relabelled (:meth:`~multiform.learn.fusion.Fusion.fused`)."""
        fusion = self.fusion()
        if fusion is None:
            return self.raw_episodes
        key = (id(fusion), len(fusion.items))
        if getattr(self, "_fused_key", None) != key:
            self._fused = fusion.fused(self.history.version(0), self.raw_episodes)
            self._fused_key = key
        return self._fused

    # -- several mentors ----------------------------------------------------------------------------
    def fusion(self) -> Fusion | None:
        """How far each of several mentors is trusted (``mentors.json``); None with one mentor."""
        p = self.path / FUSION_FILE
        if not p.exists():
            return None
        stamp = p.stat().st_mtime_ns
        if getattr(self, "_fusion_stamp", None) != stamp:
            self._fusion_cache = Fusion.load(p)
            self._fusion_stamp = stamp
        return self._fusion_cache

    def save_fusion(self, fusion: Fusion) -> None:
        """Write ``mentors.json`` (atomically) and note its estimates in the manifest."""
        fusion.save(self.path / FUSION_FILE)
        self._fusion_cache, self._fusion_stamp = fusion, (self.path / FUSION_FILE).stat().st_mtime_ns

    # -- learned pieces ---------------------------------------------------------------------------
    def save_law(self, name: str, law: GPLaw) -> None:
        self._save(law, f"laws/{name}.npz", "law")

    def _save(self, artifact: Any, rel: str, kind: str) -> None:
        if not IDENT_FILE.fullmatch(Path(rel).stem):
            raise InvalidInput(f"{Path(rel).stem!r} is not a valid artifact name", file=str(self.path))
        path = self.path / rel
        artifact.save(path)
        self._register(path, kind)

    def laws(self, apn: APN | None = None) -> dict[str, GPLaw]:
        """The fitted laws ``apn`` (default: the latest net) runs, by law name: each law's current
        fit (``laws/<fit>.npz``; a refit from practice is a new file, the earlier fits stay)."""
        apn = self.apn if apn is None else apn
        out = {}
        for name, spec in apn.laws.items():
            p = self.path / "laws" / f"{spec.fit_name}.npz"
            if p.exists():
                out[name] = GPLaw.load(p)
        return out

    def save_judge(self, place: str, judge: Judge) -> None:
        self._save(judge, f"judges/{place}.npz", "judge")

    def judges(self) -> dict[str, Judge]:
        apn = self.apn
        out = {}
        for p in sorted((self.path / "judges").glob("*.npz")):
            if p.stem in apn.place_ids:
                out[p.stem] = Judge.load(p, variables=apn.place(p.stem).judge or None)
        return out

    def save_condition(self, name: str, model: Any) -> None:
        self._save(model, f"conditions/{name}.npz", "condition")

    def conditions(self) -> dict[str, Any]:
        conds = {p.stem: load_condition(p) for p in sorted((self.path / "conditions").glob("*.npz"))}
        share_regions(conds)
        return conds

    def save_regions(self, regions: PlaceRegions) -> None:
        self._save(regions, "regions.npz", "regions")

    def regions(self) -> PlaceRegions | None:
        p = self.path / "regions.npz"
        return PlaceRegions.load(p) if p.exists() else None

    @property
    def labels(self) -> LabelStore:
        return LabelStore(self.path / "labels.jsonl")

    def adopt(self, other: SkillModel, kinds: Sequence[str]) -> list[str]:
        """Copy ``other``'s artifacts of ``kinds`` (law, judge, regions, inverse_model, ...) into this
        model, listed with their hashes: a baseline made from a trained model. ``other`` is checked
        first; returns the copied files."""
        other.verify(to_run=False)
        copied = []
        for rel, info in other.manifest["artifacts"].items():
            if info["kind"] in kinds:
                dst = self.path / rel
                dst.parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(other.path / rel, dst)
                self._register(dst, info["kind"])
                copied.append(rel)
        return copied

    def save_inverse_model(self, inverse: Any) -> None:
        self._save(inverse, "inverse_model.npz", "inverse_model")

    def inverse_model(self):
        """The learned inverse model, or None if the model has none (the env then takes commands)."""
        p = self.path / "inverse_model.npz"
        if not p.exists():
            return None
        from .learn.inverse import InverseDynamicsModel
        return InverseDynamicsModel.load(p)

    # -- running ----------------------------------------------------------------------------------
    def make_env(self, **overrides: Any) -> gym.Env:
        """The env the skill runs on (the manifest's id and arguments; ``overrides`` win)."""
        m = self.manifest
        return make_env(m["env"], m["env_kwargs"], str(self.path / "model.json"), self.env_modules, **overrides)

    def executor(self, env: gym.Env, apn: APN | None = None, use_inverse_model: bool = True) -> Executor:
        """An executor for ``apn`` (default: the latest net) with this model's laws and conditions."""
        self.verify()
        apn = apn or self.apn
        inverse = self.inverse_model() if use_inverse_model else None
        if inverse is None and needs_inverse_model(self.manifest) and \
                tuple(env.action_space.shape) != (len(env.get_wrapper_attr("command_names")),):
            raise InvalidInput("the env takes joint torques; a run without the inverse model needs the env in "
                               "command mode", file=str(self.path / "model.json"), element="env_kwargs")
        return Executor(apn, env, self.laws(apn), self.conditions(), inverse, net_version=self.version)

    def grade(self, trace: Trace, source: str, judges: Mapping[str, Judge] | None = None,
              apn: APN | None = None) -> TrialGrade:
        """The judges' grades of a trial: every sub-procedure and the whole trial. ``apn`` is the
        net that ran it (default: the latest, read from disk; a caller grading many trials of one
        net passes it)."""
        apn = self.apn if apn is None else apn
        judges = self.judges() if judges is None else judges
        if trace.outcome == "diverged" or not judges:
            return TrialGrade(score=0.0)
        grade = grade_episode(place_episode(apn, trace.to_episode()), judges, lambda p: p, source=source,
                              labels=self.labels.effective(sources=[source]))
        tags = trace.tags()
        return credit_handovers(grade, lambda g: str(tags[g.start]) in self._ways_forward, list(judges))

    @cached_property
    def _ways_forward(self) -> frozenset[str]:
        """The transitions of the skill as written that do not lead to failure (version 0 never changes)."""
        written = self.history.version(0)
        return frozenset(t.id for t in written.transitions if not written.leads_to_failure(t.id))



def directory_problems(model: SkillModel, to_run: bool = True) -> list[Problem]:
    """What :meth:`SkillModel.problems` finds."""
    try:
        m = model.manifest
        apn = model.apn
    except InvalidInput as exc:
        return list(exc.problems)
    listed: dict[str, dict[str, Any]] = m["artifacts"]
    out: list[Problem] = []
    for rel, info in listed.items():
        out += _check_artifact(model.path, rel, info)
    for folder in ARTIFACT_FOLDERS:
        for p in sorted((model.path / folder).glob("*.npz")):
            rel = p.relative_to(model.path).as_posix()
            if rel not in listed:
                out.append(Problem(str(p), "", "not listed in model.json's artifacts (not written by multiform "
                                               "for this model)"))
    for name in ARTIFACT_FILES:
        if (model.path / name).exists() and name not in listed:
            out.append(Problem(str(model.path / name), "", "not listed in model.json's artifacts"))
    if not to_run:
        return out
    for name, spec in apn.laws.items():
        if f"laws/{spec.fit_name}.npz" not in listed:
            out.append(Problem(str(model.path / "laws" / f"{spec.fit_name}.npz"), f"laws.{name}",
                               "the net runs this fit, but the model has none (train first)"))
    for t in apn.transitions:
        if t.condition.is_learned and f"conditions/{t.condition.model}.npz" not in listed:
            out.append(Problem(str(model.path / "conditions" / f"{t.condition.model}.npz"),
                               f"transitions.{t.id}.condition", "the learned condition is missing"))
    if needs_inverse_model(m) and "inverse_model.npz" not in listed:
        out.append(Problem(str(model.path / "inverse_model.npz"), "",
                           f"missing: the env takes joint torques (env_kwargs {m['env_kwargs']}), and without "
                           f"the inverse model nothing turns the skill's commands into torques"))
    demos = m.get("demos")
    if demos and os.path.lexists(demos) and not os.path.isfile(demos):
        out.append(Problem(demos, "", "not a regular file (a folder, FIFO or device); model.json names it as "
                                      "the model's demonstrations"))
    try:
        model.make_env().close()          # the env's id and the arguments it takes, before any trial
    except InvalidInput as exc:
        out += exc.problems
    return out


def registered_env_id(env_id: Any, file: str, env_modules: Sequence[str] = ()) -> str:
    """``env_id`` (read from ``file``) if it is a registered Gymnasium env; a ``module:Env-v0`` id,
    which would import the module, only if the caller names the module in ``env_modules``."""
    register_envs()
    if not isinstance(env_id, str):
        raise InvalidInput(f"must be a Gymnasium env id, got {type(env_id).__name__}", file=file, element="env")
    if ":" in env_id:
        module = env_id.split(":", 1)[0]
        if module not in env_modules:
            raise InvalidInput(f"{env_id!r} would import the module {module!r}; a file never makes multiform run "
                               f"code (name the module yourself to allow it: --env-module {module})",
                               file=file, element="env")
        return env_id
    if env_id not in gym.registry:
        raise InvalidInput(f"{env_id!r} is not a registered Gymnasium env", file=file, element="env")
    return env_id


def make_env(env_id: Any, env_kwargs: Mapping[str, Any], file: str, env_modules: Sequence[str] = (),
             **overrides: Any) -> gym.Env:
    """The env ``env_id`` with ``env_kwargs``, both read from ``file`` (``overrides`` win): an id that
    is not registered, or arguments the env refuses in any way, are an :class:`InvalidInput` naming
    the file (an env's constructor may fail on a wrong type with any exception)."""
    env_id = registered_env_id(env_id, file, env_modules)
    # Gymnasium's passive checker wraps every step (≈ 10 µs at 1 kHz); our envs pass its full
    # check_env in their tests, so the skill's runs go without it.
    try:
        return gym.make(env_id, disable_env_checker=True, **{**env_kwargs, **overrides})
    except InvalidInput:
        raise
    except Exception as exc:
        raise InvalidInput(f"cannot make {env_id} with these arguments ({type(exc).__name__}: {exc})", file=file,
                           element="env_kwargs") from None


@contextlib.contextmanager
def staged_model_dir(final: str | os.PathLike, keep_on_error: bool = False) -> Iterator[Path]:
    """Build a model directory in a hidden sibling and move it to ``final`` only when the block ends
    without error, so a failed or killed training never leaves a half-made model where a model is
    expected.

    The lock of ``final`` is held throughout: a second training into the same directory is refused
    before it makes or removes anything. The staging folder belongs to this call: it has a name of
    its own (``.NAME.partial-<random>``), and this call alone removes it (on error). A folder left by
    a killed training is never reused, named or removed by another one. With ``keep_on_error`` (the
    main job, whose run folder is its own and locked) the folder is ``.NAME.partial``, kept on error,
    and resumed by the next run of the same job."""
    final = Path(final)
    with exclusive(final):
        if final.exists():
            raise InvalidInput("exists already; train into a new directory", file=str(final))
        try:
            final.parent.mkdir(parents=True, exist_ok=True)
            if keep_on_error:
                partial = final.with_name(f".{final.name}.partial")
                partial.mkdir(exist_ok=True)
            else:
                partial = Path(tempfile.mkdtemp(prefix=f".{final.name}.partial-", dir=final.parent))
                umask = os.umask(0)
                os.umask(umask)
                os.chmod(partial, 0o777 & ~umask)       # a model directory gets the usual mode
        except OSError as exc:
            raise InvalidInput(f"cannot create the model directory here ({exc.strerror})", file=str(final)) from None
        done = False
        try:
            yield partial
            os.rename(partial, final)
            done = True
        finally:
            if not done and not keep_on_error:
                shutil.rmtree(partial, ignore_errors=True)


IDENT_FILE = re.compile(r"[A-Za-z_][A-Za-z0-9_\-]*")


def needs_inverse_model(manifest: Mapping[str, Any]) -> bool:
    """Whether the env takes joint torques, so the skill's commands need the inverse model."""
    return manifest.get("env_kwargs", {}).get("action_mode") == "torque"


def _check_artifact(root: Path, rel: str, info: Any) -> list[Problem]:
    """What is wrong with one artifact ``model.json`` lists under ``root`` (none: it is sound)."""
    where = str(root / "model.json")
    if not isinstance(info, dict) or not isinstance(info.get("sha256"), str) or "kind" not in info:
        return [Problem(where, f"artifacts.{rel}", "must be an object with kind and sha256")]
    parts = Path(rel).parts
    ok_place = (rel == "skill.yaml" or rel in ARTIFACT_FILES
                or (len(parts) == 2 and ARTIFACT_FOLDERS.get(parts[0]) == info["kind"] and rel.endswith(".npz")))
    if not ok_place or ".." in parts or Path(rel).is_absolute():
        return [Problem(where, f"artifacts.{rel}", "not a place for a model artifact")]
    path = root / rel
    if not path.is_file():
        return [Problem(str(path), "", f"missing (model.json lists this {info['kind']})")]
    if _sha256(path) != info["sha256"]:
        return [Problem(str(path), "", "changed since multiform wrote it (SHA-256 differs from model.json)")]
    if rel == "skill.yaml":
        return []
    try:
        _load_artifact(path, info["kind"])
    except InvalidInput as exc:
        return list(exc.problems)
    bad = _non_finite_arrays(path)
    return [Problem(str(path), f"array {a!r}", "has non-finite values") for a in bad]


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _load_artifact(path: Path, kind: str) -> Any:
    """Load one artifact with its own reader (kind, version and shapes checked there)."""
    if kind == "law":
        return GPLaw.load(path)
    if kind == "judge":
        return Judge.load(path)
    if kind == "condition":
        return load_condition(path)
    if kind == "regions":
        return PlaceRegions.load(path)
    if kind == "inverse_model":
        from .learn.inverse import InverseDynamicsModel
        return InverseDynamicsModel.load(path)
    raise InvalidInput(f"unknown artifact kind {kind!r}", file=str(path))


def _non_finite_arrays(path: Path) -> list[str]:
    with np.load(path, allow_pickle=False) as npz:
        return [k for k in npz.files if npz[k].dtype.kind in "fc" and not np.isfinite(npz[k]).all()]
