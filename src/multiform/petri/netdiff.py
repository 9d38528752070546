"""Two versions of a net side by side, element by element, changes marked."""

from __future__ import annotations

import difflib

from .net import APN
from .skillfile import dump_skill


def side_by_side(a: APN, b: APN, title_a: str = "a", title_b: str = "b", width: int = 100) -> str:
    """The skill-file text of ``a`` and ``b`` in two columns; ``|`` changed, ``<``/``>`` only on one side."""
    left, right = dump_skill(a).splitlines(), dump_skill(b).splitlines()
    col = max(20, (width - 3) // 2)

    def cut(s: str) -> str:
        return s if len(s) <= col else s[: col - 1] + "…"

    rows = [f"{cut(title_a):<{col}}   {cut(title_b)}", f"{'-' * col}   {'-' * col}"]
    n_changes = 0
    for op, i1, i2, j1, j2 in difflib.SequenceMatcher(a=left, b=right, autojunk=False).get_opcodes():
        if op == "equal":
            rows += [f"{cut(x):<{col}}   {cut(x)}" for x in left[i1:i2]]
            continue
        n_changes += 1
        ls, rs = left[i1:i2], right[j1:j2]
        for k in range(max(len(ls), len(rs))):
            lx = ls[k] if k < len(ls) else ""
            rx = rs[k] if k < len(rs) else ""
            mark = "|" if lx and rx else ("<" if lx else ">")
            rows.append(f"{cut(lx):<{col}} {mark} {cut(rx)}")
    rows.append(f"{n_changes} change(s)" if n_changes else "identical")
    return "\n".join(rows)
