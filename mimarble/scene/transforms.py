"""A marble's pattern transform: its steps as the language writes them, and their matrix.

    marble { period 1.3 transform { rotate < 0 0 30 > translate < 0.5 0 0 > scale 2 } }

Each step moves the *pattern* in world space, in the order written (POV-Ray's rule for
its ``translate``, ``rotate`` and ``scale``): the steps S₁, S₂, … Sₙ compose into
M = Sₙ ⋯ S₂ · S₁, the marble's ``to_world``, and the marble at a world point p is the
untransformed marble at M⁻¹·p, then scaled by the marble's own ``scale`` (a frequency):
v = scale · M⁻¹ · p (mimarble/texture/mapping.py).

* ``translate < x y z >``: the pattern moves by (x, y, z);
* ``rotate < a b c >``: about the x axis by a degrees, then about y by b, then about z
  by c (POV-Ray's order), each counter-clockwise as seen from the axis' positive end
  looking at the origin (the right-hand rule of the language's right-handed axes):
  ``rotate < 0 0 90 >`` turns +x into +y;
* ``scale s`` or ``scale < sx sy sz >``: the pattern grows s times (``scale 2``: veins
  twice as wide) — POV-Ray's meaning, the inverse of the marble's own ``scale``, which
  multiplies the frequency. No factor may be 0; a negative one mirrors the pattern.

The numbers of each matrix are POV-Ray's own (its ``Compute_Rotation_Transform``, with
row vectors, is this module's Rz·Ry·Rx with column vectors); what differs is that POV-Ray's
axes are left-handed: docs/coming-from-povray.md says how a
POV-Ray transform is written here. The matrices are composed in double precision; the
reference tracer composes its own (mimarble/reference/marble.py). Standard library only.
"""

from __future__ import annotations

import math

from .limits import FLT_MAX, FLT_MIN_NORMAL

__all__ = ["STEPS", "IDENTITY", "step_matrix", "compose", "step_problem", "matrix_problem"]

#: The steps of a transform block, in documentation order.
STEPS: tuple[str, ...] = ("translate", "rotate", "scale")

Matrix = tuple[tuple[float, float, float, float], ...]

#: The identity: no transform.
IDENTITY: Matrix = tuple(tuple(float(i == j) for j in range(4)) for i in range(4))


def _rotation(axis: int, degrees: float) -> list[list[float]]:
    """The right-handed rotation about coordinate ``axis`` by ``degrees`` (3×3)."""
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    i, j = [k for k in range(3) if k != axis]     # x: (y, z), y: (x, z), z: (x, y)
    if axis == 1:                                  # about y: z turns into x
        s = -s
    m = [[float(r == q) for q in range(3)] for r in range(3)]
    m[i][i], m[i][j], m[j][i], m[j][j] = c, -s, s, c
    return m


def _product(a, b) -> list[list[float]]:
    n = len(a)
    return [[math.fsum(a[r][k] * b[k][q] for k in range(n)) for q in range(n)] for r in range(n)]


def step_matrix(kind: str, vector) -> Matrix:
    """The 4×4 matrix (rows) of one step: ``translate``, ``rotate`` or ``scale`` by the
    three numbers ``vector``."""
    x, y, z = (float(v) for v in vector)
    m = [list(row) for row in IDENTITY]
    if kind == "translate":
        m[0][3], m[1][3], m[2][3] = x, y, z
    elif kind == "scale":
        m[0][0], m[1][1], m[2][2] = x, y, z
    elif kind == "rotate":
        linear = _product(_rotation(2, z), _product(_rotation(1, y), _rotation(0, x)))
        for r in range(3):
            m[r][:3] = linear[r]
    else:
        raise ValueError(f"a transform step is {', '.join(STEPS[:-1])} or {STEPS[-1]}, "
                         f"found {kind!r}")
    return tuple(tuple(row) for row in m)


def compose(steps) -> Matrix:
    """M = Sₙ ⋯ S₁ of the steps ``(kind, (x, y, z))`` in the order written (rows)."""
    m = [list(row) for row in IDENTITY]
    for kind, vector in steps:
        m = _product(step_matrix(kind, vector), m)
    return tuple(tuple(row) for row in m)


def step_problem(kind: str, vector) -> str | None:
    """What is wrong with one step's numbers: a scale factor of 0."""
    if kind == "scale" and any(v == 0 for v in vector):
        return "a transform's scale must not be 0 (it would flatten the pattern)"
    return None


def _determinant(m) -> float:
    return (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]))


def matrix_problem(matrix: Matrix) -> str | None:
    """What keeps the renderer (single precision) from using ``matrix`` and its inverse:
    an entry past float32's range, a 3×3 part that the marble plugin finds singular
    (|det| ≤ (10⁻⁶·max|entry|)³, mimarble/texture/mapping.py) or whose determinant
    leaves float32's range."""
    entries = [abs(v) for row in matrix[:3] for v in row]
    if not all(v <= FLT_MAX for v in entries):
        return f"the transform's numbers grow past single precision's range ({FLT_MAX!r})"
    largest = max(abs(v) for row in matrix[:3] for v in row[:3])
    det = abs(_determinant(matrix))
    if largest == 0 or not det > (1e-6 * largest) ** 3 or not FLT_MIN_NORMAL <= det <= FLT_MAX:
        return (f"the transform squeezes some direction too far to invert in single precision "
                f"(its 3×3 part: determinant {det:.3g}, largest entry {largest:.3g})")
    return None
