"""Numbers given to the Python API: one rule for NumPy's.

A NumPy scalar (``np.int64(4)``, ``np.float32(0.5)``, ``np.bool_(True)``) or a 0-d array
is taken as the Python number it holds (``.item()``) wherever the API takes a Python
number — ``mimarble.render``'s and ``reference.render``'s ``spp``, ``seed``, ``width``,
``height``, ``tolerance``, ``edge_spp``, ``adaptive`` and ``max_spp``; ``mimarble.sweep``'s
``spp``, ``stop_after``, ``workers``, ``worker_threads`` and the values of its settings —
and then the Python number's rule applies unchanged: a bool is no count (``spp=True`` and
``spp=np.bool_(True)`` are refused alike), an integral float is one where the rule takes
it (``width=16.0`` and ``width=np.float64(16)`` alike). Arrays (``np.linspace``) are the
lists of such numbers where a list is taken (a sweep's values).

Standard library only: NumPy is recognised by its types' module, not imported.
"""

from __future__ import annotations


def plain_number(value):
    """``value`` as the Python number it holds if it is a NumPy scalar or 0-d array; any
    other value as it is (its own rule says what is wrong with it)."""
    if type(value).__module__ == "numpy" and getattr(value, "shape", None) == () \
            and hasattr(value, "item"):
        return value.item()
    return value


def plain_numbers(*values) -> tuple:
    """:func:`plain_number` of each of ``values``."""
    return tuple(plain_number(v) for v in values)
