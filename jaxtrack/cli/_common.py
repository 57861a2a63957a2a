"""What the commands share: the user-error exception and the check of catalogue clip names."""

from __future__ import annotations

from collections.abc import Iterable

__all__ = ["UserError", "check_clips"]


class UserError(Exception):
    """An error caused by the user's input: printed as one line, exit status 2."""


def check_clips(names: Iterable[str], option: str) -> None:
    """Raise :class:`UserError` naming ``option`` when a clip is not in the catalogue."""
    from jaxtrack.data import list_clips

    known = set(list_clips())
    unknown = [name for name in names if name not in known]
    if unknown:
        raise UserError(f"{option}: unknown clip(s) {', '.join(unknown)}; "
                        f"known clips: {', '.join(sorted(known))}")
