"""Fit what a model directory lacks from its demonstrations: every law of the mentor's definition
(successful segments only), a judge per judged place (the mentor's labels), the place regions,
and the auxiliary inverse model (the robot's own babbling, in a process of its own beside the
rest). Pieces already on disk are kept, so an interrupted training resumes."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from .demos.episode import Episode
from .errors import InvalidInput, Problem
from .learn.fusion import estimate_fusion
from .learn.labels import LabelStore
from .learn.training import fit_judge, fit_law, fit_regions, judged_places, mentor_records
from .model import SkillModel
from .petri.net import APN

Log = Callable[[str], None]


def train_model(model: SkillModel, seed: int = 0, log: Log = print,
                inverse_trainer: Callable[..., dict[str, Any]] | None = None, beside: bool = False,
                fusion: bool = True) -> dict[str, Any]:
    """Fit what a model directory lacks from its demonstrations: every law of the original
    definition (successful segments only), a judge per judged place (mentor labels, via the label
    store), the place regions, and (with ``inverse_trainer``) the auxiliary inverse model. Pieces
    already on disk are kept, so an interrupted training resumes.

    ``inverse_trainer(model, seed=, log=, laws_ready=)`` calls ``laws_ready()`` before it first uses
    the laws. With ``beside`` it runs in a forked process from the start: its babbling needs no law,
    so it uses the second core while this one fits the laws, judges and regions. Every fit is
    seeded and single-threaded, so the model is the same either way.

    With demonstrations of several mentors and ``fusion``, how far each is trusted is estimated first
    (:mod:`multiform.learn.fusion`, ``mentors.json``) and every fit weighs them by it; without
    ``fusion`` their data are pooled as if one mentor made them all."""
    done = model.manifest.get("training", {})
    apn = model.history.version(0)
    store = LabelStore(model.path / "labels.jsonl")
    if not len(store):
        store.add_many(mentor_records(apn, model.raw_episodes))
    summary: dict[str, Any] = dict(done)
    if fusion and model.fusion() is None:
        trust = estimate_fusion(apn, model.raw_episodes, seed=seed)
        if trust is not None:
            model.save_fusion(trust)
            summary["mentors"] = trust.table()
            model.update_manifest(training={"mentors": summary["mentors"]})
            log_trust(trust, log)
    eps = model.episodes
    need_inverse = inverse_trainer is not None and ("inverse_model" not in summary
                                                    or not (model.path / "inverse_model.npz").exists())
    other = Beside(inverse_trainer, model, seed) if need_inverse and beside else None
    try:
        _fit_definition(model, apn, eps, store, summary, seed, log,
                        laws_ready=other.laws_ready if other is not None else lambda: None)
        if other is not None:
            summary["inverse_model"] = other.result(log)
        elif need_inverse:
            summary["inverse_model"] = inverse_trainer(model, seed=seed, log=log, laws_ready=lambda: None)
    finally:
        if other is not None:
            other.close()
    model.update_manifest(training=summary)
    return summary


def _fit_definition(model: SkillModel, apn: APN, eps: Sequence[Episode], store: LabelStore, summary: dict[str, Any],
                    seed: int, log: Log, laws_ready: Callable[[], None]) -> None:
    """Laws (then ``laws_ready()``), judges and regions that ``summary`` lacks."""
    laws = summary.setdefault("laws", {})
    for name in apn.laws:
        if name in laws and (model.path / "laws" / f"{name}.npz").exists():
            continue
        t0 = time.perf_counter()
        with _from_demonstrations(model, f"laws.{name}"):
            law, info = fit_law(apn, eps, name, seed=seed, fusion=model.fusion())
        info["fit_seconds"] = round(time.perf_counter() - t0, 2)
        model.save_law(name, law)
        laws[name] = info
        model.update_manifest(training={"laws": laws})
        log(f"  law {name}: n={info['n']} from {info['demos']} demos ({info['mode']}), "
            f"held-out NRMSE {info.get('heldout_nrmse', float('nan')):.3f}, length scales {info['length_scales']}, "
            f"σf {info['signal_std']}, σn {info['noise_std']}")
    laws_ready()
    judges = summary.setdefault("judges", {})
    for place in judged_places(apn):
        if place in judges and (model.path / "judges" / f"{place}.npz").exists():
            continue
        with _from_demonstrations(model, f"places.{place}.judge"):
            judge, info = fit_judge(apn, eps, store, place, seed=seed, fusion=model.fusion())
        model.save_judge(place, judge)
        judges[place] = info
        model.update_manifest(training={"judges": judges})
        cv = info.get("cv_score")
        if not info.get("informative", True):
            log(f"  judge {place}: uninformative: {info['uninformative']}")
            continue
        held = (f", held-out accuracy {info['heldout_accuracy']:.3f} on {info['heldout_segments']} segments"
                if "heldout_accuracy" in info else "")
        log(f"  judge {place}: kernel {info['kernel']}, CV {'-' if cv is None else f'{cv:.3f}'}{held}")
    if "regions" not in summary or model.regions() is None:
        with _from_demonstrations(model, "regions"):
            regions, info = fit_regions(apn, eps, seed=seed)
        model.save_regions(regions)
        summary["regions"] = info
        log(f"  regions over {', '.join(info['variables'])}: " +
            ", ".join(f"{p} ({n} states)" for p, n in info["places"].items()))


@contextlib.contextmanager
def _from_demonstrations(model: SkillModel, element: str) -> Iterator[None]:
    """A fit the demonstrations cannot feed (no successful segment of a maneuver, too few states of a
    place, degenerate data: the fit's ValueError) is bad input: an :class:`InvalidInput` naming the
    demonstration file and what could not be learned."""
    try:
        yield
    except InvalidInput as exc:
        demos = str(model.manifest.get("demos") or "")
        raise InvalidInput([p if p.file else Problem(demos, p.element or element, p.message)
                            for p in exc.problems]) from None
    except ValueError as exc:
        raise InvalidInput(f"the demonstrations cannot train this: {exc}", file=str(model.manifest.get("demos") or ""),
                           element=element) from None


def log_trust(trust: Any, log: Log) -> None:
    """One line per transition (each mentor's weight) and per judged place (each annotator's
    agreement with the fused verdicts)."""
    table = trust.table()
    for t, d in table["maneuvers"].items():
        log(f"  trust in {t}: " + ", ".join(f"{m} {v['weight']:.2f} ({v['successes']}/{v['segments']} ok, precision "
                                            f"{'-' if v.get('precision') is None else format(v['precision'], '.2f')})"
                                            for m, v in d.items()))
    for p, d in table["labels"].items():
        log(f"  labels in {p}: " + ", ".join(f"{w} agrees {100 * v['agreement']:.0f} % of {v['items']}"
                                              for w, v in d.items()))


class Beside:
    """The inverse-model trainer in a forked process, started at once; it waits for
    :meth:`laws_ready` before it uses the laws. Its log lines are replayed here with its result.
    The process is a daemon (it ends with this one), so the trainer may not start processes itself."""

    def __init__(self, trainer: Callable[..., dict[str, Any]], model: SkillModel, seed: int):
        import multiprocessing as mp
        ctx = mp.get_context("fork")
        self._ready = ctx.Event()
        self._recv, send = ctx.Pipe(duplex=False)
        self.process = ctx.Process(target=_train_beside, args=(trainer, str(model.path), seed, self._ready, send),
                                 name="inverse-model", daemon=True)
        self.process.start()
        send.close()

    def laws_ready(self) -> None:
        self._ready.set()

    def result(self, log: Log) -> dict[str, Any]:
        try:
            ok, payload, lines = self._recv.recv()
        except EOFError:
            self.process.join()
            raise RuntimeError(f"the inverse-model process ended without a result (exit code {self.process.exitcode})"
                               ) from None
        for line in lines:
            log(line)
        if not ok:
            raise RuntimeError(f"inverse-model training failed in its process:\n{payload}")
        return payload

    def close(self) -> None:
        """Join the process; one still waiting for laws that will not come (this process failed
        first) is terminated."""
        self.process.join(timeout=5.0 if self._ready.is_set() else 0.0)
        if self.process.is_alive():
            self.process.terminate()
            self.process.join()
        self._recv.close()


def _train_beside(trainer: Callable[..., dict[str, Any]], path: str, seed: int, ready: Any, send: Any) -> None:
    import traceback
    lines: list[str] = []
    try:
        info = trainer(SkillModel(path), seed=seed, log=lines.append, laws_ready=ready.wait)
        send.send((True, info, lines))
    except BaseException:
        send.send((False, traceback.format_exc(), lines))
    finally:
        send.close()
