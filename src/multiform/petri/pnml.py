"""PNML (ISO/IEC 15909-2) export and import, so skill nets open in other Petri net tools.

The file is a plain P/T net (``ptnet``) on one page. λ goes into the
``<toolspecific tool="StochasticPetriNet" version="0.2">`` block as ``<property key="weight">``
(the convention pm4py and ProM read); conditions, law names, final places, judges and the skill's
variables/laws travel in a ``<toolspecific tool="multiform">`` block of our own, which other tools
ignore. Reading is lenient about the namespace and a missing ``<page>``.
"""

from __future__ import annotations

import json
import os
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

from ..errors import InvalidInput, Problem
from ..io import write_text
from .net import APN
from .skillfile import build_apn, skill_to_data

NS = "http://www.pnml.org/version-2009/grammar/pnml"
PTNET = "http://www.pnml.org/version-2009/grammar/ptnet"
TOOL = "multiform"
TOOL_VERSION = "1"


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


def _find(el: ET.Element, name: str) -> ET.Element | None:
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


def _json(el: ET.Element | None, what: str, file: str, element: str) -> dict[str, Any]:
    if el is None or not (el.text or "").strip():
        return {}
    try:
        out = json.loads(el.text)
    except json.JSONDecodeError as exc:
        raise InvalidInput(f"{what} data is not JSON ({exc})", file=file, element=element) from None
    if not isinstance(out, dict):
        raise InvalidInput(f"{what} data must be a JSON object", file=file, element=element)
    return out


def from_pnml(text: str, file: str = "<string>") -> APN:
    """Read a PNML P/T net; our toolspecific data restores conditions, laws and final places."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise InvalidInput(f"not well-formed XML ({exc})", file=file) from None
    net = root if _local(root.tag) == "net" else _find(root, "net")
    if net is None:
        raise InvalidInput("no <net> element", file=file)
    pages = _findall(net, "page")
    containers = pages or [net]
    nodes: list[ET.Element] = []
    for c in containers:
        nodes.extend(c)
        nodes.extend(x for sub in _findall(c, "page") for x in sub)  # nested pages, flattened
    name = _text_of(_find(net, "name")) or net.get("id") or Path(file).stem
    skill = _json(_find(_tool(net, TOOL), "skill") if _tool(net, TOOL) is not None else None, "skill", file, "net")
    data: dict[str, Any] = {"skill": name, **skill}
    places: dict[str, Any] = {}
    marking: dict[str, int] = {}
    transitions: dict[str, Any] = {}
    problems: list[Problem] = []
    for el in nodes:
        kind = _local(el.tag)
        pid = el.get("id")
        if kind in ("place", "transition") and not pid:
            problems.append(Problem(file, kind, "element without an id"))
            continue
        if kind == "place":
            label = _text_of(_find(el, "name"))
            extra = _json(_find(_tool(el, TOOL), "place") if _tool(el, TOOL) is not None else None,
                          "place", file, f"place {pid}")
            spec = {"label": extra.get("label", label if label != pid else "") or ""}
            if extra.get("final"):
                spec["final"] = extra["final"]
            if extra.get("judge"):
                spec["judge"] = extra["judge"]
            places[pid] = spec
            m = _text_of(_find(el, "initialMarking"))
            if m:
                try:
                    marking[pid] = int(m)
                except ValueError:
                    problems.append(Problem(file, f"place {pid}", f"initial marking {m!r} is not an integer"))
        elif kind == "transition":
            label = _text_of(_find(el, "name"))
            extra = _json(_find(_tool(el, TOOL), "transition") if _tool(el, TOOL) is not None else None,
                          "transition", file, f"transition {pid}")
            spec: dict[str, Any] = {"in": {}, "out": {}, "label": extra.get("label", label if label != pid else "") or ""}
            sto = _tool(el, "StochasticPetriNet")
            if sto is not None:
                for prop in _findall(sto, "property"):
                    if prop.get("key") == "weight":
                        try:
                            spec["lambda"] = float((prop.text or "").strip())
                        except ValueError:
                            spec["lambda"] = (prop.text or "").strip()
            if extra.get("law"):
                spec["law"] = extra["law"]
            if "condition" in extra:
                spec["condition"] = extra["condition"]
            transitions[pid] = spec
    for el in nodes:
        if _local(el.tag) != "arc":
            continue
        src, dst = el.get("source"), el.get("target")
        w_text = _text_of(_find(el, "inscription"))
        try:
            w = int(w_text) if w_text else 1
        except ValueError:
            problems.append(Problem(file, f"arc {el.get('id')}", f"inscription {w_text!r} is not an integer"))
            continue
        if src in places and dst in transitions:
            transitions[dst]["in"][src] = w
        elif src in transitions and dst in places:
            transitions[src]["out"][dst] = w
        elif src in places and dst in places:
            problems.append(Problem(file, f"arc {el.get('id')}", f"arc {src} -> {dst} connects two places"))
        elif src in transitions and dst in transitions:
            problems.append(Problem(file, f"arc {el.get('id')}", f"arc {src} -> {dst} connects two transitions"))
        else:
            problems.append(Problem(file, f"arc {el.get('id')}", f"unknown source or target ({src} -> {dst})"))
    data["places"] = places
    data["transitions"] = transitions
    data["initial_marking"] = marking
    apn = build_apn(data, file, problems)
    if problems:
        raise InvalidInput(problems)
    return apn


def read_pnml(path: str | os.PathLike) -> APN:
    """Read a PNML file."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InvalidInput(f"cannot read ({exc})", file=str(path)) from None
    return from_pnml(text, str(path))
