"""Several people's demonstration files joined into one: the same skill, env and control period,
each demo keeping its mentor (robomimic's filter key per mentor) and labels."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from ..errors import InvalidInput
from .dataset import Dataset, read_dataset, write_dataset
from .episode import Episode, check_mentor_name


def merge_datasets(paths: Sequence[str | os.PathLike], out: str | os.PathLike,
                   mentors: Mapping[str, str] | None = None, split_seed: int = 0) -> Path:
    """Write the demonstrations of several files (several people's) into one file ``out``, in the
    order given, each demo keeping its mentor and labels (every mentor gets its filter key).

    The files must hold the same skill, env (id and arguments), observation and command names and
    control period: a file that differs from the first is refused, named with what differs.
    ``mentors`` names the mentor of a file's demos that record none (file path as given → name); a
    demo without a mentor is refused, as is a name given for a file whose demos have their own.
    Nothing is written unless every file passes."""
    if not paths:
        raise InvalidInput("no demonstration files to merge", file=str(out))
    mentors = dict(mentors or {})
    unknown = sorted(set(mentors) - {str(p) for p in paths})
    if unknown:
        raise InvalidInput(f"names a mentor for {unknown[0]!r}, which is not among the files to merge",
                           element="mentor")
    sets = [read_dataset(p) for p in paths]
    first = sets[0]
    want = _merge_key(first)
    episodes: list[Episode] = []
    for p, ds in zip(paths, sets):
        got = _merge_key(ds)
        for what, a, b in zip(("skill", "env", "env arguments", "observation names", "command names",
                               "control period dt"), want, got):
            if a != b:
                raise InvalidInput(f"its {what} {b!r} differ from {a!r} of {paths[0]}; only demonstrations of one "
                                   f"skill on one env merge", file=str(p), element="data")
        given = mentors.get(str(p))
        if given is not None:
            check_mentor_name(given, element=f"mentor {p}={given}")
        for i, ep in enumerate(ds.episodes):
            if ep.mentor and given is not None and ep.mentor != given:
                raise InvalidInput(f"demo_{i} was recorded by {ep.mentor!r}; a file's recorded mentors are kept, "
                                   f"not renamed to {given!r}", file=str(p), element=f"data/demo_{i}")
            who = ep.mentor or given
            if not who:
                raise InvalidInput(f"demo_{i} records no mentor; name the file's mentor (mentor {p}=NAME)",
                                   file=str(p), element=f"data/demo_{i}")
            episodes.append(replace(ep, mentor=who))
    return write_dataset(out, episodes, first.skill, first.env_name, first.env_kwargs, obs_dtype=first.meta["obs_dtype"],
                         split_seed=split_seed)


def _merge_key(ds: Dataset) -> tuple[Any, ...]:
    return (ds.skill, ds.env_name, ds.env_kwargs, tuple(ds.meta["observation_names"]),
            tuple(ds.meta["command_names"]), float(ds.meta["dt"]))
