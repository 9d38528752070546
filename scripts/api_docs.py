"""Write docs/api.md, the API reference, from the docstrings of the names ``multiform`` exports.

Run ``python scripts/api_docs.py`` after changing a public name or its docstring; a test checks
the page is up to date.
"""

from __future__ import annotations

import inspect
import sys
from pathlib import Path

import multiform

PAGE = Path(__file__).resolve().parent.parent / "docs" / "api.md"


def _signature(obj: object) -> str:
    try:
        return str(inspect.signature(obj))
    except (TypeError, ValueError):
        return ""


def _section(name: str) -> list[str]:
    obj = getattr(multiform, name)
    kind = "class" if inspect.isclass(obj) else "function" if callable(obj) else "value"
    out = [f"### `{name}`", "", f"{kind} `{obj.__module__}.{obj.__qualname__}{_signature(obj)}`", ""]
    out += [inspect.getdoc(obj) or "(no docstring)", ""]
    if inspect.isclass(obj):
        for attr, member in sorted(vars(obj).items()):
            if attr.startswith("_") or not (inspect.isfunction(member) or isinstance(member, (classmethod, property))):
                continue
            fn = member.__func__ if isinstance(member, classmethod) else member
            doc = (inspect.getdoc(fn) or "").split("\n\n")[0].replace("\n", " ")
            sig = "" if isinstance(member, property) else _signature(fn)
            out.append(f"- `{attr}{sig}` — {doc}" if doc else f"- `{attr}{sig}`")
        out.append("")
    return out


def render() -> str:
    lines = ["# API reference", "",
             "Generated from the docstrings by `python scripts/api_docs.py`; every name is imported with",
             "`import multiform` (on first use). The tutorial, [your-own-skill.md](your-own-skill.md),",
             "uses them from start to end.", ""]
    lines += [f"- [`{n}`](#{n.lower()})" for n in multiform.__all__] + [""]
    for name in multiform.__all__:
        lines += _section(name)
    return "\n".join(lines).rstrip() + "\n"


if __name__ == "__main__":
    PAGE.write_text(render())
    print(f"wrote {PAGE}", file=sys.stderr)
