"""Errors that name the file, the element and what is wrong."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Problem:
    """One thing wrong with an input: where (file, element) and what."""

    file: str
    element: str
    message: str

    def __str__(self) -> str:
        where = f"{self.file}: " if self.file else ""
        elem = f"{self.element}: " if self.element else ""
        return f"{where}{elem}{self.message}"


class MultiformError(Exception):
    """Base class of the library's errors."""


class InvalidInput(MultiformError, ValueError):
    """Bad input (a skill file, a dataset, a saved model); lists every problem found.

    ``problems`` holds one :class:`Problem` per finding, so a caller (the CLI, a test) can show all
    of them rather than the first.
    """

    def __init__(self, problems: list[Problem] | Problem | str, file: str = "", element: str = ""):
        if isinstance(problems, str):
            problems = [Problem(file, element, problems)]
        elif isinstance(problems, Problem):
            problems = [problems]
        self.problems: list[Problem] = list(problems)
        super().__init__("\n".join(str(p) for p in self.problems))


class MissingInput(InvalidInput):
    """An input file or folder that does not exist (the command line exits with its own status, 66,
    so a script can tell "the file is missing" from "the file is wrong")."""
