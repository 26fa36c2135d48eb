"""Lists in Mitsuba properties: ``NAME_0``, ``NAME_1``, … (XML cannot repeat a name)."""

from __future__ import annotations

import re


def numbered_properties(props, name: str) -> list[str] | None:
    """The keys ``NAME_0``, ``NAME_1``, … of ``props`` in order; None when there are none;
    ValueError when they have gaps."""
    pattern = re.compile(rf"{re.escape(name)}_(\d+)$")
    numbered = sorted((int(m.group(1)), key) for key in props.keys() if (m := pattern.match(key)))
    if not numbered:
        return None
    if [k for k, _ in numbered] != list(range(len(numbered))):
        raise ValueError(f"{name}_0, {name}_1, … must be numbered without gaps, got "
                         f"{', '.join(key for _, key in numbered)}")
    return [key for _, key in numbered]
