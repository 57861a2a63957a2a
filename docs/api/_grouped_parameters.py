"""Griffe extension: read ``a, b: description`` in an ``Args:`` section as one entry per name.

jaxtrack's docstrings document parameters that share a meaning on one line; the Google-style
parser would read ``a, b`` as one unknown name (a warning, so a strict build fails). This
rewrites such a line into one line per name, each with the shared description, before
parsing; names that are not in the signature are still reported.
"""

from __future__ import annotations

import re

import griffe

_SECTION = re.compile(r"^(\s*)(Args|Arguments|Parameters|Attributes):\s*$")
_GROUPED = re.compile(r"^(\s+)(\*{0,2}\w+(?:\s*,\s*\*{0,2}\w+)+)\s*:(.*)$")


def split_grouped(text: str) -> str:
    """Split every ``a, b: description`` entry of the parameter sections into one per name."""
    lines = text.splitlines()
    out: list[str] = []
    section_indent: int | None = None
    index = 0
    while index < len(lines):
        line = lines[index]
        header = _SECTION.match(line)
        if header:
            section_indent = len(header.group(1))
        elif line.strip() and section_indent is not None and (
                len(line) - len(line.lstrip()) <= section_indent):
            section_indent = None
        grouped = _GROUPED.match(line) if section_indent is not None else None
        if grouped is None:
            out.append(line)
            index += 1
            continue
        indent, names, first = grouped.groups()
        entry_indent = len(indent)
        continuation = []
        index += 1
        while index < len(lines) and (
                not lines[index].strip()
                or len(lines[index]) - len(lines[index].lstrip()) > entry_indent):
            continuation.append(lines[index])
            index += 1
        for name in (part.strip() for part in names.split(",")):
            out.append(f"{indent}{name}:{first}")
            out.extend(continuation)
    return "\n".join(out)


class GroupedParameters(griffe.Extension):
    """Rewrites grouped parameter entries of every docstring (see the module docstring)."""

    def on_instance(self, *, obj: griffe.Object, **kwargs) -> None:
        if obj.docstring is not None and "," in obj.docstring.value:
            obj.docstring.value = split_grouped(obj.docstring.value)
