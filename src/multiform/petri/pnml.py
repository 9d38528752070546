"""PNML (ISO/IEC 15909-2) export and import, so skill nets open in other Petri net tools.

The file is a plain P/T net (``ptnet``) on one page. λ goes into the
``<toolspecific tool="StochasticPetriNet" version="0.2">`` block as ``<property key="weight">``
(the convention pm4py and ProM read); the success places are the net's ``<finalmarkings>`` (one
``<marking>`` per success place; pm4py reads them as its final marking); conditions, law names,
final places, judges and the skill's variables/laws travel in a ``<toolspecific tool="multiform">``
block of our own, which other tools ignore.

Reading is lenient about the namespace and a missing ``<page>``, honours the XML encoding
declaration, and takes nets other tools wrote (pm4py's constructors and miners): a *foreign* net
(one without our net-level block) gets valid ids made from its names or ids (``({'a'}, {'b'})`` →
``a_b``, a UUID transition labelled ``a`` → ``a``), the original names kept as labels; a place and a
transition may share an id there (arcs tell which is meant); its final places are those of its
final markings (any other sink place that a transition feeds, a dead end, is a failure place), or, with none given, its
sink places; a net named as tools name the nets they make (``imported_1733312345.67``,
``imdf_net_1733312345``) takes the file's name instead. Other tools keep the structure, the names
and the markings but drop the ``multiform`` block: conditions become ``true`` and laws are
unassigned. Duplicate ids of one kind, counts out of range and data nested too deeply are refused
by name.
"""

from __future__ import annotations

import json
import os
import re
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

from ..errors import InvalidInput, Problem
from ..io import read_bytes, write_text
from .net import APN
from .skill_schema import IDENT, MAX_COUNT, build_apn
from .skillfile import skill_to_data

NS = "http://www.pnml.org/version-2009/grammar/pnml"
PTNET = "http://www.pnml.org/version-2009/grammar/ptnet"
TOOL = "multiform"
TOOL_VERSION = "1"
# the names tools give nets they make: pm4py's "imported_<time>", "imdf_net_<time>", ... (a Unix time)
GENERATED_NAME = re.compile(r"^[A-Za-z_]+_\d{9,}(\.\d+)?$")
MAX_JSON_CHARS = 1_000_000       # one toolspecific block; the bundled skills need < 10 kB
MAX_JSON_DEPTH = 32              # skill data nests 5 levels deep


def _text_child(parent: ET.Element, tag: str, text: str) -> ET.Element:
    el = ET.SubElement(parent, tag)
    ET.SubElement(el, "text").text = text
    return el


def to_pnml(apn: APN) -> str:
    """The net as PNML text."""
    root = ET.Element("pnml", {"xmlns": NS})
    net = ET.SubElement(root, "net", {"id": apn.name, "type": PTNET})
    _text_child(net, "name", apn.name)
    page = ET.SubElement(net, "page", {"id": "page0"})
    for p in apn.places:
        el = ET.SubElement(page, "place", {"id": p.id})
        _text_child(el, "name", p.label or p.id)
        n = apn.initial_marking.get(p.id, 0)
        if n:
            _text_child(el, "initialMarking", str(n))
        extra = {k: v for k, v in (("final", p.final), ("judge", list(p.judge))) if v}
        if extra or p.label:
            ts = ET.SubElement(el, "toolspecific", {"tool": TOOL, "version": TOOL_VERSION})
            ET.SubElement(ts, "place").text = json.dumps({"label": p.label, **extra})
    for t in apn.transitions:
        el = ET.SubElement(page, "transition", {"id": t.id})
        _text_child(el, "name", t.label or t.id)
        sto = ET.SubElement(el, "toolspecific", {"tool": "StochasticPetriNet", "version": "0.2"})
        for key, val in (("distributionType", "IMMEDIATE"), ("priority", "1"), ("invisible", "false"),
                         ("weight", repr(float(t.lam)))):
            ET.SubElement(sto, "property", {"key": key}).text = val
        ts = ET.SubElement(el, "toolspecific", {"tool": TOOL, "version": TOOL_VERSION})
        ET.SubElement(ts, "transition").text = json.dumps(
            {"label": t.label, "law": t.law, "condition": t.condition.to_data()})
    k = 0
    for t in apn.transitions:
        for src, dst, w in [(p, t.id, w) for p, w in t.inputs.items()] + [(t.id, p, w) for p, w in t.outputs.items()]:
            arc = ET.SubElement(page, "arc", {"id": f"a{k}", "source": src, "target": dst})
            _text_child(arc, "inscription", str(w))
            k += 1
    finals = ET.SubElement(net, "finalmarkings")
    for pid, kind in apn.final_places.items():
        if kind == "success":
            _text_child(ET.SubElement(finals, "marking"), "place", "1").set("idref", pid)
    skill = skill_to_data(apn)
    for key in ("places", "transitions", "initial_marking"):
        skill.pop(key)
    ts = ET.SubElement(net, "toolspecific", {"tool": TOOL, "version": TOOL_VERSION})
    ET.SubElement(ts, "skill").text = json.dumps(skill)
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def write_pnml(apn: APN, path: str | os.PathLike) -> None:
    """Write the net as a PNML file, atomically."""
    write_text(path, to_pnml(apn))


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def _find(el: ET.Element | None, name: str) -> ET.Element | None:
    if el is None:
        return None
    for c in el:
        if _local(c.tag) == name:
            return c
    return None


def _findall(el: ET.Element, name: str) -> list[ET.Element]:
    return [c for c in el if _local(c.tag) == name]


def _text_of(el: ET.Element | None) -> str | None:
    if el is None:
        return None
    t = _find(el, "text")
    return (t.text or "").strip() if t is not None else None


def _tool(el: ET.Element, tool: str) -> ET.Element | None:
    for c in _findall(el, "toolspecific"):
        if c.get("tool") == tool:
            return c
    return None


def _json_depth(text: str) -> int:
    """How deeply ``[`` and ``{`` nest in JSON text (outside strings), without parsing it."""
    depth = deepest = 0
    in_str = escaped = False
    for ch in text:
        if in_str:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_str = False
        elif ch == '"':
            in_str = True
        elif ch in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif ch in "]}":
            depth -= 1
    return deepest


def _json(el: ET.Element | None, what: str, file: str, element: str) -> dict[str, Any]:
    if el is None or not (el.text or "").strip():
        return {}
    if len(el.text) > MAX_JSON_CHARS:
        raise InvalidInput(f"{what} data is {len(el.text)} characters, more than {MAX_JSON_CHARS}",
                           file=file, element=element)
    depth = _json_depth(el.text)
    if depth > MAX_JSON_DEPTH:
        raise InvalidInput(f"{what} data nests {depth} levels deep, more than {MAX_JSON_DEPTH}",
                           file=file, element=element)
    try:
        out = json.loads(el.text)
    except (ValueError, RecursionError) as exc:        # ValueError: also a number of > 4,300 digits
        raise InvalidInput(f"{what} data is not JSON ({str(exc)[:120]})", file=file, element=element) from None
    if not isinstance(out, dict):
        raise InvalidInput(f"{what} data must be a JSON object", file=file, element=element)
    return out


_COUNT = re.compile(r"^\+?[0-9]+$")


def _count(text: str, what: str, element: str, file: str, problems: list[Problem]) -> int | None:
    """A token count or arc weight: a whole number from 0 to MAX_COUNT, else a problem and None."""
    if not _COUNT.match(text):
        shown = text if len(text) <= 40 else f"{text[:20]}...({len(text)} characters)"
        problems.append(Problem(file, element, f"{what} {shown!r} is not a non-negative integer"))
        return None
    digits = text.lstrip("+").lstrip("0") or "0"
    if len(digits) > len(str(MAX_COUNT)) or int(digits) > MAX_COUNT:
        shown = digits if len(digits) <= 40 else f"a {len(digits)}-digit number"
        problems.append(Problem(file, element, f"{what} {shown} is out of range (at most {MAX_COUNT})"))
        return None
    return int(digits)


def _valid_ids(nodes: list[tuple[str, str, str | None]]) -> dict[tuple[str, str], str]:
    """(kind, original id) -> a valid id unique over places and transitions: the original where it
    is one, else one made from the element's name (or id), e.g. ``({'a'}, {'b'})`` -> ``a_b``."""
    out: dict[tuple[str, str], str] = {}
    used: set[str] = set()
    for kind, oid, _ in nodes:
        if IDENT.match(oid) and not oid.startswith("__") and oid not in used:
            out[(kind, oid)] = oid
            used.add(oid)
    for kind, oid, name in nodes:
        if (kind, oid) in out:
            continue
        base = re.sub(r"[^A-Za-z0-9_]+", "_", name or oid).strip("_")[:40]
        if not base or base[0].isdigit() or base.startswith("__"):
            base = f"{kind[0]}_{base}".rstrip("_")
        new, k = base, 2
        while new in used:
            new, k = f"{base}_{k}", k + 1
        out[(kind, oid)] = new
        used.add(new)
    return out


def _parse_xml(text: str | bytes, file: str) -> ET.Element:
    try:
        return ET.fromstring(text)
    except ET.ParseError as exc:
        raise InvalidInput(f"not well-formed XML ({exc})", file=file) from None
    except (LookupError, UnicodeError, ValueError) as exc:   # an encoding Python does not know
        raise InvalidInput(f"cannot decode the XML ({exc})", file=file) from None


def from_pnml(text: str | bytes, file: str = "<string>") -> APN:
    """Read a PNML P/T net; our toolspecific data restores conditions, laws and final places.

    Bytes are decoded as the XML declaration says (default UTF-8).
    """
    root = _parse_xml(text, file)
    net = root if _local(root.tag) == "net" else _find(root, "net")
    if net is None:
        raise InvalidInput("no <net> element", file=file)
    pages = _findall(net, "page")
    containers = pages or [net]
    nodes: list[ET.Element] = []
    for c in containers:
        nodes.extend(c)
        nodes.extend(x for sub in _findall(c, "page") for x in sub)  # nested pages, flattened
    ours = _tool(net, TOOL)
    name = _text_of(_find(net, "name")) or net.get("id") or ""
    if ours is None and (not name or GENERATED_NAME.match(name)):
        name = re.sub(r"[^A-Za-z0-9_]+", "_", Path(file).stem).strip("_") or "imported_net"
    skill = _json(_find(ours, "skill"), "skill", file, "net")
    data: dict[str, Any] = {"skill": name, **skill}
    problems: list[Problem] = []

    elements, order = _elements(nodes, file, problems)
    ids = _valid_ids(order) if ours is None else {(k, o): o for k, o, _ in order}
    final_ids = _final_marking(net, {o for k, o in elements if k == "place"}, file, problems)

    places: dict[str, Any] = {}
    marking: dict[str, int] = {}
    transitions: dict[str, Any] = {}
    for (kind, oid), el in elements.items():
        pid = ids[(kind, oid)]
        label = _text_of(_find(el, "name"))
        if not label and pid != oid:
            label = oid
        label = label if label != pid else ""
        where = f"{kind} {oid}"
        if kind == "place":
            places[pid] = _place_spec(el, label, oid in final_ids, where, file)
            m = _text_of(_find(el, "initialMarking"))
            if m:
                n = _count(m, "initial marking", where, file, problems)
                if n:
                    marking[pid] = n
        else:
            transitions[pid] = _transition_spec(el, label, where, file)

    _add_arcs(nodes, elements, ids, transitions, file, problems)
    if ours is None:
        _foreign_finals(places, transitions, marking, bool(final_ids))
    data["places"] = places
    data["transitions"] = transitions
    data["initial_marking"] = marking
    apn = build_apn(data, file, problems)
    if problems:
        raise InvalidInput(problems)
    return apn


def _foreign_finals(places: dict[str, Any], transitions: dict[str, Any], marking: dict[str, int],
                    has_final_marking: bool) -> None:
    """Final places of a net another tool wrote (which keeps no ``final:`` of its own): the places
    of its final marking are successes; with none, every sink place is. A sink place outside a
    final marking (a dead end such as a skill's ``failure``, whose kind only multiform's block
    carried) is a failure: where the skill stops without success, not a deadlock."""
    feeding = {p for t in transitions.values() for p in t["in"]}
    fed = {p for t in transitions.values() for p in t["out"]}
    for pid, spec in places.items():
        if pid in feeding or pid in marking or spec.get("final"):
            continue
        if not has_final_marking:
            spec["final"] = "success"
        elif pid in fed:
            spec["final"] = "failure"


def _elements(nodes: list[ET.Element], file: str, problems: list[Problem]
              ) -> tuple[dict[tuple[str, str], ET.Element], list[tuple[str, str, str | None]]]:
    """Places and transitions by (kind, id), and (kind, id, name) in document order."""
    elements: dict[tuple[str, str], ET.Element] = {}
    order: list[tuple[str, str, str | None]] = []
    for el in nodes:
        kind = _local(el.tag)
        if kind not in ("place", "transition"):
            continue
        oid = el.get("id")
        if not oid:
            problems.append(Problem(file, kind, "element without an id"))
        elif (kind, oid) in elements:
            problems.append(Problem(file, f"{kind} {oid}", f"duplicate id: a second <{kind}> with id {oid!r}"))
        else:
            elements[(kind, oid)] = el
            order.append((kind, oid, _text_of(_find(el, "name"))))
    return elements, order


def _place_spec(el: ET.Element, label: str, in_final_marking: bool, where: str, file: str) -> dict[str, Any]:
    """A place's skill-file entry; without our data, a place of the final marking is a success."""
    extra = _json(_find(_tool(el, TOOL), "place"), "place", file, where)
    spec: dict[str, Any] = {"label": extra.get("label", label) or ""}
    if extra.get("final"):
        spec["final"] = extra["final"]
    elif "final" not in extra and in_final_marking:
        spec["final"] = "success"
    if extra.get("judge"):
        spec["judge"] = extra["judge"]
    return spec


def _transition_spec(el: ET.Element, label: str, where: str, file: str) -> dict[str, Any]:
    """A transition's skill-file entry (arcs still empty): λ from the stochastic weight, the rest
    from our toolspecific data."""
    extra = _json(_find(_tool(el, TOOL), "transition"), "transition", file, where)
    spec: dict[str, Any] = {"in": {}, "out": {}, "label": extra.get("label", label) or ""}
    sto = _tool(el, "StochasticPetriNet")
    if sto is not None:
        for prop in _findall(sto, "property"):
            if prop.get("key") == "weight":
                w = (prop.text or "").strip()
                try:
                    spec["lambda"] = float(w)
                except ValueError:
                    spec["lambda"] = w if len(w) <= 40 else f"{w[:20]}...({len(w)} characters)"
    if extra.get("law"):
        spec["law"] = extra["law"]
    if "condition" in extra:
        spec["condition"] = extra["condition"]
    return spec


def _add_arcs(nodes: list[ET.Element], elements: dict[tuple[str, str], ET.Element],
              ids: dict[tuple[str, str], str], transitions: dict[str, Any], file: str,
              problems: list[Problem]) -> None:
    """Enter every <arc> into its transition's ``in`` or ``out``, each problem named."""
    for el in nodes:
        if _local(el.tag) != "arc":
            continue
        src, dst = el.get("source"), el.get("target")
        where = f"arc {el.get('id')}"
        w_text = _text_of(_find(el, "inscription"))
        w = _count(w_text, "inscription", where, file, problems) if w_text else 1
        if w is None:
            continue
        if w == 0:
            problems.append(Problem(file, where, "inscription 0: an arc weight is at least 1"))
            continue
        if ("place", src) in elements and ("transition", dst) in elements:
            arcs = transitions[ids[("transition", dst)]]["in"]
            p = ids[("place", src)]
        elif ("transition", src) in elements and ("place", dst) in elements:
            arcs = transitions[ids[("transition", src)]]["out"]
            p = ids[("place", dst)]
        else:
            kinds = ["place" if ("place", x) in elements else "transition" if ("transition", x) in elements
                     else None for x in (src, dst)]
            if None in kinds:
                problems.append(Problem(file, where, f"unknown source or target ({src} -> {dst})"))
            else:
                problems.append(Problem(file, where, f"arc {src} -> {dst} connects two {kinds[0]}s"))
            continue
        if p in arcs:
            problems.append(Problem(file, where, f"duplicate arc {src} -> {dst}"))
        else:
            arcs[p] = w


def _final_marking(net: ET.Element, place_ids: set[str], file: str, problems: list[Problem]) -> set[str]:
    """The places holding tokens in the net's ``<finalmarkings>`` (every ``<marking>`` in it)."""
    out: set[str] = set()
    for fm in _findall(net, "finalmarkings"):
        for marking in _findall(fm, "marking"):
            for pl in _findall(marking, "place"):
                ref = pl.get("idref")
                where = f"finalmarkings place {ref}"
                if ref not in place_ids:
                    problems.append(Problem(file, where, "no place with this id"))
                    continue
                n = _count(_text_of(pl) or "1", "token count", where, file, problems)
                if n:
                    out.add(ref)
    return out


def read_pnml(path: str | os.PathLike) -> APN:
    """Read a PNML file (its encoding as the XML declaration says)."""
    path = Path(path)
    return from_pnml(read_bytes(path, "PNML file", limit=64 << 20), str(path))
