"""The skill file's elements checked and built into an :class:`~multiform.petri.net.APN`: places,
transitions and their arcs and conditions, laws, derived values, safety limits, the mirror
symmetry. Every problem is collected (:class:`~multiform.errors.Problem`: the file, the element,
what is wrong), so a person fixes a file in one pass; :mod:`.skillfile` reads the YAML."""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import Any

from ..errors import Problem
from .guard import GuardError, parse_guard
from .net import APN, FINAL_KINDS, Condition, Law, Place, Transition, condition_names, is_clock

IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
TOP_KEYS = {"skill", "description", "env", "control_rate", "max_duration", "variables", "derived",
            "commands", "laws", "places", "initial_marking", "transitions", "arcs", "safety",
            "mirror"}
PLACE_KEYS = {"label", "final", "judge"}
TRANSITION_KEYS = {"label", "in", "out", "law", "lambda", "condition"}
LAW_KEYS = {"inputs", "outputs", "mean", "lag", "description", "fit"}
MAX_LAG = 1.0                    # s: a reaction time, not a plan
MAX_TICKS = 1_000_000            # control ticks of one trial (max_duration × control_rate): its trace is kept in memory
MAX_CONTROL_RATE = 100_000.0     # Hz
MAX_LAMBDA = 1e9                 # a firing probability's weight: a sum of them must stay finite
MAX_COUNT = 2**31 - 1            # tokens in a place, weight of an arc (int32, as other PNML tools hold them)
LAW_MEANS = ("constant", "linear")


def build_apn(data: Mapping[str, Any], file: str, problems: list[Problem]) -> APN | None:
    """Build a net from the skill-file data, appending every problem found to ``problems``."""
    def bad(element: str, message: str) -> None:
        problems.append(Problem(file, element, message))

    for key in data:
        if key not in TOP_KEYS:
            bad(str(key), f"unknown key (expected one of {', '.join(sorted(TOP_KEYS))})")
    name = data.get("skill")
    if not isinstance(name, str) or not name:
        bad("skill", "missing or not a name")
        name = "unnamed"
    control_rate = _positive(data.get("control_rate", 1000.0), "control_rate", bad)
    max_duration = _positive(data.get("max_duration", 60.0), "max_duration", bad)
    if control_rate > MAX_CONTROL_RATE:
        bad("control_rate", f"{control_rate:g} Hz is out of range (at most {MAX_CONTROL_RATE:g})")
    elif max_duration * control_rate > MAX_TICKS:
        bad("max_duration", f"{max_duration:g} s at {control_rate:g} Hz is {max_duration * control_rate:.3g} control "
                            f"ticks per trial; at most {MAX_TICKS:,} (a trial's record is kept in memory)")

    variables = _variables(data.get("variables", {}), bad)
    commands = _name_list(data.get("commands", []), "commands", bad)
    places = parse_places(data.get("places"), bad)
    place_ids = {p.id for p in places}
    transitions_raw = data.get("transitions")
    if not isinstance(transitions_raw, Mapping) or not transitions_raw:
        bad("transitions", "missing or empty (a mapping of transition id to its definition)")
        transitions_raw = {}
    transition_ids = {str(t) for t in transitions_raw}
    for tid in transition_ids & place_ids:
        bad(f"transitions.{tid}", "duplicate id: also used by a place")

    derived = _derived(data.get("derived", {}) or {}, variables, place_ids, transition_ids, bad)
    allowed = condition_names(variables, derived, place_ids, transition_ids)

    laws = _laws(data.get("laws"), allowed, tuple(commands), bad)
    safety = parse_safety(data.get("safety"), set(variables) | set(derived), tuple(commands), bad)
    mirror = parse_mirror(data.get("mirror"), set(variables), tuple(commands), bad)
    transitions = parse_transitions(transitions_raw, place_ids, transition_ids, allowed, laws, bad)
    transitions = _extra_arcs(data.get("arcs"), transitions, place_ids, bad)

    initial = _initial_marking(data.get("initial_marking"), place_ids, bad)

    if not any(p.final == "success" for p in places) and places:
        bad("places", "no place is marked 'final: success'")
    apn = APN(name=name, places=tuple(places), transitions=tuple(transitions), initial_marking=initial,
              variables=variables, derived=derived, commands=tuple(commands), laws=laws,
              description=str(data.get("description", "") or ""), env=str(data.get("env", "") or ""),
              control_rate=control_rate, max_duration=max_duration, safety=safety, mirror=mirror)
    if initial and places and not problems:
        _check_final_reachable(apn, bad)
    return apn


def _derived(raw: Any, variables: Mapping[str, str], place_ids: set[str], transition_ids: set[str],
             bad) -> dict[str, Any]:
    """The derived variables, each an expression over the state variables, the clocks and the
    derived variables before it."""
    derived: dict[str, Any] = {}
    if not isinstance(raw, Mapping):
        bad("derived", "must be a mapping of name to expression")
        return derived
    for dname, expr in raw.items():
        el = f"derived.{dname}"
        if not isinstance(dname, str) or not IDENT.match(dname):
            bad(el, "not a valid name")
            continue
        if dname in variables:
            bad(el, "duplicate id: also a state variable")
            continue
        if is_clock(dname):
            bad(el, "reserved for the net's clocks and counters")
            continue
        try:
            derived[dname] = parse_guard(str(expr) if isinstance(expr, (int, float)) else expr,
                                         condition_names(variables, derived, place_ids, transition_ids))
        except GuardError as exc:
            bad(el, str(exc))
    return derived


def _initial_marking(raw: Any, place_ids: set[str], bad) -> dict[str, int]:
    """Place id -> tokens, of the places that hold any."""
    initial: dict[str, int] = {}
    if not isinstance(raw, Mapping) or not raw:
        bad("initial_marking", "no initial marking (a mapping of place id to token count)")
        return initial
    for p, n in raw.items():
        el = f"initial_marking.{p}"
        if p not in place_ids:
            bad(el, f"unknown place {p!r}")
        elif not _is_int(n) or n < 0:
            bad(el, f"token count must be a non-negative integer, got {_shown(n)}")
        elif n > MAX_COUNT:
            bad(el, f"token count {_shown(n)} is out of range (at most {MAX_COUNT})")
        elif n > 0:
            initial[str(p)] = int(n)
    if not initial:
        bad("initial_marking", "no place holds a token")
    return initial


def parse_mirror(raw: Any, variables: set[str], commands: tuple[str, ...], bad) -> dict[str, int]:
    """The ``mirror`` section: the sign (+1 or -1) of each state variable and command in the task's
    mirror image (a swing to the left mirrors a swing to the right). Learners may then learn from
    every demonstration's mirror image too; derived variables follow from the mirrored state."""
    if raw is None:
        return {}
    if not isinstance(raw, Mapping):
        bad("mirror", "must map state variables and commands to their sign in the mirror image (+1 or -1)")
        return {}
    out: dict[str, int] = {}
    for name, sign in raw.items():
        el = f"mirror.{name}"
        if name not in variables and name not in commands:
            bad(el, "not a state variable or command of the skill (derived variables follow from the state)")
        elif _is_int(sign) and int(sign) in (-1, 1):
            out[str(name)] = int(sign)
        else:
            bad(el, f"sign must be +1 or -1, got {sign!r}")
    if out and all(v == 1 for v in out.values()):
        bad("mirror", "every sign is +1: the mirror image would be the task itself")
    return out


def parse_safety(raw: Any, variables: set[str], commands: tuple[str, ...], bad) -> dict[str, Any]:
    """The ``safety`` section: command bounds and rates, workspace limits, divergence threshold."""
    if raw is None:
        return {}
    if not isinstance(raw, Mapping):
        bad("safety", "must be a mapping (commands, workspace, divergence)")
        return {}
    out: dict[str, Any] = {}
    for k in raw:
        if k not in ("commands", "workspace", "divergence"):
            bad(f"safety.{k}", "unknown key (expected commands, workspace, divergence)")
    cmds = raw.get("commands") or {}
    if not isinstance(cmds, Mapping):
        bad("safety.commands", "must map command names to {min, max, rate}")
        cmds = {}
    out["commands"] = {}
    for c, spec in cmds.items():
        el = f"safety.commands.{c}"
        if c not in commands:
            bad(el, f"unknown command {c!r}")
            continue
        if not isinstance(spec, Mapping) or not set(spec) <= {"min", "max", "rate"}:
            bad(el, "must be {min, max, rate}")
            continue
        vals = {k: _number(spec[k], f"{el}.{k}", bad) for k in spec}
        if "min" in vals and "max" in vals and vals["min"] >= vals["max"]:
            bad(el, "min must be below max")
        if vals.get("rate", 1.0) <= 0:
            bad(f"{el}.rate", "must be positive")
        out["commands"][c] = vals
    ws = raw.get("workspace") or {}
    if not isinstance(ws, Mapping):
        bad("safety.workspace", "must map variable names to {min, max, command}")
        ws = {}
    out["workspace"] = {}
    for v, spec in ws.items():
        el = f"safety.workspace.{v}"
        if v not in variables:
            bad(el, f"undeclared variable {v!r}")
            continue
        if not isinstance(spec, Mapping) or not {"min", "max", "command"} <= set(spec):
            bad(el, "must be {min, max, command}")
            continue
        if spec["command"] not in commands:
            bad(f"{el}.command", f"unknown command {spec['command']!r}")
            continue
        lo, hi = _number(spec["min"], f"{el}.min", bad), _number(spec["max"], f"{el}.max", bad)
        if lo >= hi:
            bad(el, "min must be below max")
        out["workspace"][v] = {"min": lo, "max": hi, "command": spec["command"]}
    if "divergence" in raw:
        out["divergence"] = _number(raw["divergence"], "safety.divergence", bad)
    return {k: v for k, v in out.items() if v != {}}


def _number(value: Any, el: str, bad) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        bad(el, f"must be a finite number, got {value!r}")
        return 0.0
    return float(value)


def _positive(value: Any, el: str, bad) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        bad(el, f"must be a positive number, got {value!r}")
        return 1.0
    return float(value)


def _shown(v: Any) -> str:
    """A value for a message: huge numbers by their digit count, not their 4,000 digits."""
    if _is_int(v) and abs(v).bit_length() > 128:
        return f"a number of about {int(abs(v).bit_length() * 0.30103) + 1} digits"
    text = repr(v)
    return text if len(text) <= 60 else f"{text[:40]}...({len(text)} characters)"


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _variables(raw: Any, bad) -> dict[str, str]:
    if raw is None:
        return {}
    if isinstance(raw, list):
        raw = {v: "" for v in raw}
    if not isinstance(raw, Mapping):
        bad("variables", "must be a mapping of name to description (or a list of names)")
        return {}
    out = {}
    for name, desc in raw.items():
        if not isinstance(name, str) or not IDENT.match(name) or name.startswith("__"):
            bad(f"variables.{name}", "not a valid variable name")
        elif is_clock(name):
            bad(f"variables.{name}", "reserved for the net's clocks and counters")
        else:
            out[name] = "" if desc is None else str(desc)
    return out


def _name_list(raw: Any, el: str, bad) -> list[str]:
    if raw is None:
        return []
    if not isinstance(raw, list):
        bad(el, "must be a list of names")
        return []
    out = []
    for i, n in enumerate(raw):
        if not isinstance(n, str) or not IDENT.match(n):
            bad(f"{el}[{i}]", f"not a valid name: {n!r}")
        elif n in out:
            bad(f"{el}[{i}]", f"duplicate id {n!r}")
        else:
            out.append(n)
    return out


def parse_places(raw: Any, bad) -> list[Place]:
    if not isinstance(raw, Mapping) or not raw:
        bad("places", "missing or empty (a mapping of place id to its definition)")
        return []
    out = []
    for pid, spec in raw.items():
        el = f"places.{pid}"
        if not isinstance(pid, str) or not IDENT.match(pid):
            bad(el, "not a valid id (letters, digits, underscore)")
            continue
        spec = spec if spec is not None else {}
        if isinstance(spec, str):
            spec = {"label": spec}
        if not isinstance(spec, Mapping):
            bad(el, "must be a mapping (label, final, judge) or a label")
            continue
        for k in spec:
            if k not in PLACE_KEYS:
                bad(f"{el}.{k}", f"unknown key (expected {', '.join(sorted(PLACE_KEYS))})")
        final = spec.get("final")
        if final is not None and final not in FINAL_KINDS:
            bad(f"{el}.final", f"must be 'success' or 'failure', got {final!r}")
            final = None
        judge = spec.get("judge", []) or []
        if not isinstance(judge, list) or not all(isinstance(j, str) for j in judge):
            bad(f"{el}.judge", "must be a list of variable names")
            judge = []
        out.append(Place(id=pid, label=str(spec.get("label", "") or ""), final=final, judge=tuple(judge)))
    return out


def _laws(raw: Any, allowed: frozenset[str], commands: tuple[str, ...], bad) -> dict[str, Law]:
    if raw is None:
        return {}
    if not isinstance(raw, Mapping):
        bad("laws", "must be a mapping of law name to {inputs, outputs}")
        return {}
    out = {}
    for name, spec in raw.items():
        el = f"laws.{name}"
        if not isinstance(name, str) or not IDENT.match(name):
            bad(el, "not a valid law name")
            continue
        if not isinstance(spec, Mapping):
            bad(el, "must be a mapping with 'inputs'")
            continue
        for k in spec:
            if k not in LAW_KEYS:
                bad(f"{el}.{k}", f"unknown key (expected {', '.join(sorted(LAW_KEYS))})")
        inputs = _name_list(spec.get("inputs"), f"{el}.inputs", bad)
        if not inputs:
            bad(f"{el}.inputs", "a law needs at least one input variable")
        for v in inputs:
            if v not in allowed:
                bad(f"{el}.inputs", f"undeclared variable {v!r}")
        outputs = _name_list(spec.get("outputs", list(commands)), f"{el}.outputs", bad)
        for c in outputs:
            if c not in commands:
                bad(f"{el}.outputs", f"unknown command {c!r} (commands: {', '.join(commands) or 'none'})")
        if not outputs:
            bad(f"{el}.outputs", "a law needs at least one output (declare 'commands')")
        mean = spec.get("mean", "constant")
        if mean not in LAW_MEANS:
            bad(f"{el}.mean", f"must be one of {', '.join(LAW_MEANS)}, got {mean!r}")
        desc = spec.get("description", "")
        if not isinstance(desc, str):
            bad(f"{el}.description", "must be text")
        lag = spec.get("lag", 0.0)
        if isinstance(lag, bool) or not isinstance(lag, (int, float)) or not 0.0 <= lag <= MAX_LAG:
            bad(f"{el}.lag", f"must be a number of seconds from 0 to {MAX_LAG}, got {lag!r}")
            lag = 0.0
        fit = spec.get("fit", "")
        if fit != "" and not (isinstance(fit, str) and IDENT.match(fit)):
            bad(f"{el}.fit", f"must be the name of a fitted law (letters, digits, _), got {fit!r}")
            fit = ""
        out[name] = Law(name=name, inputs=tuple(inputs), outputs=tuple(outputs),
                        mean=mean if mean in LAW_MEANS else "constant", description=desc if isinstance(desc, str) else "",
                        lag=float(lag), fit=fit)
    return out


def _arcs(raw: Any, el: str, place_ids: set[str], transition_ids: set[str], tid: str, incoming: bool,
          bad) -> dict[str, int]:
    if raw is None:
        return {}
    if isinstance(raw, str):
        raw = [raw]
    if isinstance(raw, list):
        pairs = []
        for x in raw:
            pairs.append((x, 1))
    elif isinstance(raw, Mapping):
        pairs = list(raw.items())
    else:
        bad(el, "must be a list of place ids or a mapping of place id to arc weight")
        return {}
    out: dict[str, int] = {}
    for p, w in pairs:
        if p in transition_ids:
            src, dst = (p, tid) if incoming else (tid, p)
            bad(el, f"arc {src} -> {dst} connects two transitions; arcs join a place and a transition")
        elif p not in place_ids:
            bad(el, f"unknown place {p!r}")
        elif not _is_int(w) or w < 1:
            bad(el, f"arc weight for {p!r} must be a positive integer, got {_shown(w)}")
        elif w > MAX_COUNT:
            bad(el, f"arc weight for {p!r} is {_shown(w)}, out of range (at most {MAX_COUNT})")
        elif p in out:
            bad(el, f"duplicate arc to place {p!r}")
        else:
            out[str(p)] = int(w)
    return out


def parse_transitions(raw: Mapping[str, Any], place_ids: set[str], transition_ids: set[str],
                 allowed: frozenset[str], laws: dict[str, Law], bad) -> list[Transition]:
    out = []
    for tid, spec in raw.items():
        el = f"transitions.{tid}"
        if not isinstance(tid, str) or not IDENT.match(tid):
            bad(el, "not a valid id (letters, digits, underscore)")
            continue
        if not isinstance(spec, Mapping):
            bad(el, "must be a mapping (in, out, law, lambda, condition, label)")
            continue
        for k in spec:
            if k not in TRANSITION_KEYS:
                bad(f"{el}.{k}", f"unknown key (expected {', '.join(sorted(TRANSITION_KEYS))})")
        inputs = _arcs(spec.get("in"), f"{el}.in", place_ids, transition_ids, tid, True, bad)
        outputs = _arcs(spec.get("out"), f"{el}.out", place_ids, transition_ids, tid, False, bad)
        lam = spec.get("lambda", 1.0)
        if isinstance(lam, bool) or not isinstance(lam, (int, float)):
            bad(f"{el}.lambda", f"must be a number, got {lam!r}")
            lam = 1.0
        elif math.isnan(lam) or math.isinf(lam):
            bad(f"{el}.lambda", f"must be finite, got {lam!r}")
            lam = 1.0
        elif lam < 0:
            bad(f"{el}.lambda", f"must not be negative, got {lam!r}")
            lam = 1.0
        elif lam > MAX_LAMBDA:
            bad(f"{el}.lambda", f"{_shown(lam)} is out of range (at most {MAX_LAMBDA:g}; λ are relative weights)")
            lam = 1.0
        law = spec.get("law")
        if law is not None:
            if not isinstance(law, str):
                bad(f"{el}.law", f"must be a law name, got {law!r}")
                law = None
            elif laws and law not in laws:
                bad(f"{el}.law", f"unknown law {law!r} (laws: {', '.join(laws)})")
        raw_cond = spec.get("condition", "true")
        cond = parse_condition(raw_cond, f"{el}.condition", allowed, bad,
                               transition_ids - {tid} if isinstance(raw_cond, Mapping) else frozenset())
        out.append(Transition(id=tid, inputs=inputs, outputs=outputs, law=law, lam=float(lam),
                              condition=cond, label=str(spec.get("label", "") or "")))
    return out


def parse_condition(raw: Any, el: str, allowed: frozenset[str], bad,
                    transitions: set[str] | frozenset[str] = frozenset()) -> Condition:
    """An expression, or ``{model: <name>}`` with optional ``unless: <transition id(s)>`` among
    ``transitions`` (the other transitions of the net) and ``within: <expression>``."""
    if isinstance(raw, bool):
        raw = "true" if raw else "false"
    if isinstance(raw, Mapping):
        model = raw.get("model")
        if not set(raw) <= {"model", "unless", "within"} or not isinstance(model, str) or not IDENT.match(model):
            bad(el, "a learned condition is written {model: <name>}, optionally with unless: [<transition>, ...] "
                    "and within: <expression>")
            return Condition.always()
        within = None
        if "within" in raw:
            if not isinstance(raw["within"], str):
                bad(f"{el}.within", f"must be an expression, got {raw['within']!r}")
                return Condition.always()
            try:
                within = parse_guard(raw["within"], allowed)
            except GuardError as exc:
                bad(f"{el}.within", str(exc))
                return Condition.always()
        unless = raw.get("unless", [])
        unless = [unless] if isinstance(unless, str) else unless
        if not isinstance(unless, list) or not all(isinstance(u, str) for u in unless):
            bad(f"{el}.unless", f"must be a transition id or a list of them, got {raw.get('unless')!r}")
            return Condition.always()
        unknown = [u for u in unless if u not in transitions]
        if unknown:
            bad(f"{el}.unless", f"unknown transition(s) {', '.join(map(repr, unknown))} "
                                f"(others: {', '.join(sorted(transitions)) or 'none'})")
            return Condition.always()
        return Condition.learned(model, unless, within)
    if not isinstance(raw, str):
        bad(el, f"must be an expression or {{model: <name>}}, got {raw!r}")
        return Condition.always()
    try:
        return Condition.expression(raw, allowed)
    except GuardError as exc:
        bad(el, str(exc))
        return Condition.always()


def _extra_arcs(raw: Any, transitions: list[Transition], place_ids: set[str], bad) -> list[Transition]:
    """The optional top-level ``arcs`` list ({from, to, weight}), added to the transitions' own."""
    if raw is None:
        return transitions
    if not isinstance(raw, list):
        bad("arcs", "must be a list of {from, to, weight}")
        return transitions
    by_id = {t.id: t for t in transitions}
    for i, arc in enumerate(raw):
        el = f"arcs[{i}]"
        if not isinstance(arc, Mapping) or "from" not in arc or "to" not in arc:
            bad(el, "an arc is {from: <id>, to: <id>, weight: <n>}")
            continue
        src, dst, w = arc["from"], arc["to"], arc.get("weight", 1)
        if not _is_int(w) or w < 1 or w > MAX_COUNT:
            bad(el, f"weight must be a positive integer up to {MAX_COUNT}, got {_shown(w)}")
            continue
        kinds = ["place" if x in place_ids else "transition" if x in by_id else None for x in (src, dst)]
        if None in kinds:
            missing = src if kinds[0] is None else dst
            bad(el, f"unknown place or transition {missing!r}")
        elif kinds[0] == kinds[1]:
            bad(el, f"arc {src} -> {dst} connects two {kinds[0]}s; arcs join a place and a transition")
        elif kinds[0] == "place":
            t = by_id[dst]
            by_id[dst] = Transition(t.id, {**t.inputs, src: w}, t.outputs, t.law, t.lam, t.condition, t.label)
        else:
            t = by_id[src]
            by_id[src] = Transition(t.id, t.inputs, {**t.outputs, dst: w}, t.law, t.lam, t.condition, t.label)
    return [by_id[t.id] for t in transitions]


def _check_final_reachable(apn: APN, bad) -> None:
    """Structural check: some final place must be reachable from the initially marked places (a
    worklist over the transitions, linear in the net's size)."""
    missing = {t.id: len(set(t.inputs)) for t in apn.transitions}
    waiting: dict[str, list[Transition]] = {}
    for t in apn.transitions:
        for p in set(t.inputs):
            waiting.setdefault(p, []).append(t)
    ready = [t for t in apn.transitions if not t.inputs]
    reached: set[str] = set()
    todo = list(apn.initial_marking)
    while todo or ready:
        while ready:
            todo.extend(p for p in ready.pop().outputs if p not in reached)
        if todo:
            p = todo.pop()
            if p in reached:
                continue
            reached.add(p)
            for t in waiting.get(p, ()):
                missing[t.id] -= 1
                if missing[t.id] == 0:
                    ready.append(t)
    if not any(p in reached for p in apn.final_places):
        bad("places", "no final place is reachable from the initial marking")
