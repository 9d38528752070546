"""Skill files: YAML (safe loader) in, an :class:`~multiform.petri.net.APN` out, every problem named.

Validation collects *all* problems of a file before failing, each naming the file, the element
(``transitions.t1.condition``) and what is wrong, so a person fixes a file in one pass. The format
is documented in docs/skill-files.md.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from ..errors import InvalidInput, MissingInput, Problem
from ..io import read_bytes
from .net import APN
from .skill_schema import build_apn

MAX_FILE_BYTES = 16 << 20        # a skill file (a 10,000-place net is about 1 MB)
MAX_NODES = 2_000_000            # YAML nodes with every alias expanded (an "alias bomb" expands to billions)


class _UniqueKeyLoader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):     # libyaml's parser: 5x faster
    """A safe loader that records duplicate mapping keys instead of silently keeping the last."""

    duplicates: list[tuple[str, int]]


def _construct_mapping(loader: _UniqueKeyLoader, node: yaml.MappingNode, deep: bool = False):
    seen: set[Any] = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        if key in seen:
            loader.duplicates.append((str(key), key_node.start_mark.line + 1))
        try:
            seen.add(key)
        except TypeError:
            pass
    return yaml.SafeLoader.construct_mapping(loader, node, deep)


_UniqueKeyLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)
# YAML 1.2 floats: PyYAML (YAML 1.1) reads 1e4 or 1.0e4 as strings; a skill author means numbers.
_UniqueKeyLoader.yaml_implicit_resolvers = {k: list(v) for k, v in yaml.SafeLoader.yaml_implicit_resolvers.items()}
_UniqueKeyLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"))


def bundled_skills() -> dict[str, Path]:
    """Skill files shipped with the package, by name (``pendulum``, ``nunchaku``, ...)."""
    root = resources.files("multiform") / "skills"
    return {Path(str(p)).stem: Path(str(p)) for p in root.iterdir() if str(p).endswith(".yaml")}


def resolve_skill(name_or_path: str | os.PathLike) -> Path:
    """A path as given (a model directory: its ``skill.yaml``), or a bundled skill by name."""
    p = Path(name_or_path)
    if p.is_dir() and (p / "skill.yaml").is_file():
        return p / "skill.yaml"
    if p.exists() or p.suffix in (".yaml", ".yml"):
        return p
    skills = bundled_skills()
    if str(name_or_path) in skills:
        return skills[str(name_or_path)]
    raise MissingInput(f"no such file, and not a bundled skill ({', '.join(sorted(skills))})",
                       file=str(name_or_path))


def load_skill(path: str | os.PathLike) -> APN:
    """Read and validate a skill file (a path or a bundled skill name)."""
    path = resolve_skill(path)
    data = read_bytes(path, "skill file", limit=MAX_FILE_BYTES)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InvalidInput(f"cannot read ({exc})", file=str(path)) from None
    return parse_skill(text, str(path))


def parse_skill(text: str, file: str = "<string>") -> APN:
    """Parse skill YAML text; raises :class:`InvalidInput` listing every problem."""
    if len(text) > MAX_FILE_BYTES:
        raise InvalidInput(f"{len(text)} characters; a skill file is at most {MAX_FILE_BYTES}", file=file)
    loader = _UniqueKeyLoader(text)
    loader.duplicates = []
    try:
        node = loader.get_single_node()
        if node is not None and "&" in text:          # aliases need an anchor
            _check_expanded_size(node, file)
        data = loader.construct_document(node) if node is not None else None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}" if mark is not None else ""
        problem = str(getattr(exc, "problem", exc))
        if "nesting depth" in problem:       # libyaml's own bound
            raise InvalidInput("not a skill file: lists or mappings nested too deeply", file=file, element=where) from None
        raise InvalidInput(f"not valid YAML ({problem})", file=file, element=where) from None
    except RecursionError:
        raise InvalidInput("not a skill file: lists or mappings nested too deeply", file=file) from None
    except InvalidInput:
        raise
    except ValueError as exc:       # a number with more digits than Python converts
        raise InvalidInput(f"not a skill file: {exc}", file=file) from None
    finally:
        loader.dispose()
    problems = [Problem(file, f"line {line}", f"duplicate id {key!r}") for key, line in loader.duplicates]
    if not isinstance(data, Mapping):
        problems.append(Problem(file, "", "a skill file must be a mapping at the top level"))
        raise InvalidInput(problems)
    apn = build_apn(data, file, problems)
    if problems:
        raise InvalidInput(problems)
    assert apn is not None
    return apn


def _check_expanded_size(root: yaml.Node, file: str) -> None:
    """Refuse a document whose nodes, every alias expanded, number more than :data:`MAX_NODES`, or
    that holds itself: anchors and aliases let a few lines stand for billions of nodes (or for an
    endless one), which no reader can hold."""
    size: dict[int, int] = {}
    open_: set[int] = set()
    stack: list[tuple[yaml.Node, bool]] = [(root, False)]
    while stack:
        node, children_done = stack.pop()
        kids = ([n for pair in node.value for n in pair] if isinstance(node, yaml.MappingNode)
                else list(node.value) if isinstance(node, yaml.SequenceNode) else [])
        if children_done:
            open_.discard(id(node))
            size[id(node)] = 1 + sum(size[id(k)] for k in kids)
            if size[id(node)] > MAX_NODES:
                raise InvalidInput(f"expands to more than {MAX_NODES:,} YAML nodes (through anchors and aliases); "
                                   "not a skill file", file=file, element=f"line {node.start_mark.line + 1}")
            continue
        if id(node) in size:
            continue
        if id(node) in open_:
            raise InvalidInput("an alias refers to the list or mapping that holds it; not a skill file", file=file,
                               element=f"line {node.start_mark.line + 1}")
        open_.add(id(node))
        stack.append((node, True))
        stack.extend((k, False) for k in kids if id(k) not in size)


def skill_from_data(data: Mapping[str, Any], file: str = "<data>") -> APN:
    """Build a net from skill-file data (:func:`skill_to_data`'s inverse); raises
    :class:`InvalidInput` listing every problem."""
    problems: list[Problem] = []
    apn = build_apn(data, file, problems)
    if problems:
        raise InvalidInput(problems)
    assert apn is not None
    return apn


def skill_to_data(apn: APN) -> dict[str, Any]:
    """The skill-file mapping of a net (``load(dump(net)) == net``)."""
    out: dict[str, Any] = {"skill": apn.name}
    if apn.description:
        out["description"] = apn.description
    if apn.env:
        out["env"] = apn.env
    out["control_rate"] = apn.control_rate
    out["max_duration"] = apn.max_duration
    if apn.variables:
        out["variables"] = dict(apn.variables)
    if apn.derived:
        out["derived"] = {k: g.text for k, g in apn.derived.items()}
    if apn.commands:
        out["commands"] = list(apn.commands)
    if apn.laws:
        out["laws"] = {k: law.to_data(apn.commands) for k, law in apn.laws.items()}
    if apn.safety:
        out["safety"] = {k: v for k, v in apn.safety.items() if v}
    if apn.mirror:
        out["mirror"] = dict(apn.mirror)
    out["places"] = {p.id: p.to_data() for p in apn.places}
    out["initial_marking"] = dict(apn.initial_marking)
    out["transitions"] = {t.id: t.to_data() for t in apn.transitions}
    return out


def dump_skill(apn: APN) -> str:
    """The net as skill-file YAML text."""
    return yaml.safe_dump(skill_to_data(apn), sort_keys=False, allow_unicode=True, width=100)
