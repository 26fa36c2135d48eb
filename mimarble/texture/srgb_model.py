"""RGB colours as smooth spectra, per lane: Mitsuba's sRGB model in Dr.Jit.

In spectral variants a Mitsuba texture returns its value at the lane's wavelengths
(``si.wavelengths``). Mitsuba's own ``bitmap`` and ``srgb`` turn RGB into a spectrum with
the model of Jakob & Hanika (2019): a colour c maps to three coefficients
(:func:`coefficients`), and the spectrum is the sigmoid of a quadratic in λ,

    S(λ) = ½ + ½ · q / √(1 + q²),    q = c₀λ² + c₁λ + c₂,

(``mi.srgb_model_eval``). Mitsuba fetches the coefficients on the host only
(``mi.srgb_model_fetch`` takes one ``ScalarColor3f``): ``bitmap`` upsamples its texels when
it is loaded. A marble's colour is made per lane, so the fetch is written here in Dr.Jit,
the same arithmetic as ``rgb2spec_fetch`` (github.com/mitsuba-renderer/rgb2spec, the commit
Mitsuba 3.9.1 pins) on the same table, Mitsuba's ``data/srgb.coeff``:

* each component clamped to [0, 1] (the model holds reflectances; Mitsuba clamps too);
* a grey r = g = b = v in closed form: q ≡ (v − ½)/√(v(1 − v)), so S ≡ v exactly
  (v ≤ 0: q = −8192, v ≥ 1: q = 8192, which the sigmoid takes to 0 and 1 in float32);
* otherwise the largest component z = c_i picks one of three tables, the other two divided by
  z give (x, y) ∈ [0, 1]² on a uniform grid of ``res`` points, z its own non-uniform grid
  (``scale``, found by a branch-free binary search), and the coefficients are the trilinear
  interpolation of the table's eight neighbours.

Every index is clamped into the table by construction (x, y ≤ res − 1 because c_i is the
largest; the search never passes res − 2), and a NaN colour, which no comparison passes,
is sent through the grey branch and given a NaN spectrum at the end: no lane reads out of
bounds. Piecewise linear in c, so a derivative flows from the spectrum to the colour.
"""

from __future__ import annotations

import functools

import numpy as np

from mimarble.runtime import environment

dr, mi = environment.import_drjit_and_mitsuba()

#: Where Mitsuba keeps the model (resolved by its file resolver, as ``srgb_model_fetch`` does).
MODEL_FILE = "data/srgb.coeff"
#: Coefficients per colour (a quadratic in λ).
COEFFICIENTS = 3
#: The grey colours' closed form maps black and white to ∓ this (rgb2spec's choice: large
#: enough that float32's sigmoid gives exactly 0 and 1, small enough that q² is finite).
GREY_LIMIT = 8192.0


def variant_problem(plugin_name: str) -> str | None:
    """One sentence when the current variant is not one mimarble's plugins give colours
    in (``environment.colour_variant``: RGB or spectral), else None."""
    variant = mi.variant()
    if variant is None or environment.colour_variant(variant):
        return None
    return (f"{plugin_name}: variant {variant} is not supported; use an RGB or spectral "
            f"variant (llvm_ad_rgb, cuda_ad_rgb, scalar_rgb, llvm_ad_spectral, …)")


class ModelTable:
    """Mitsuba's sRGB model as Dr.Jit arrays: ``scale`` (the z grid, ``res`` floats) and
    ``data`` (3 tables of res³ points of 3 coefficients, flat). A texture holds one as its
    member, so that Dr.Jit's traversal (a recording of its kernels) finds the arrays."""

    DRJIT_STRUCT = {"scale": object, "data": object}

    def __init__(self, res: int, scale, data):
        self.res = res
        self.scale, self.data = scale, data


def model_problem(raw: bytes) -> str | None:
    """Why ``raw`` is not an sRGB model file (``SPEC``, res, scale[res], data[3·res³·3]),
    or None."""
    if len(raw) < 8 or raw[:4] != b"SPEC":
        return "it does not start with SPEC"
    res = int(np.frombuffer(raw[4:8], dtype="<u4")[0])
    if not 2 <= res <= 1024 or len(raw) < 8 + 4 * (res + 3 * res ** 3 * COEFFICIENTS):
        return f"its resolution {res} does not fit its {len(raw)} bytes"
    return None


@functools.lru_cache(maxsize=None)
def _model(variant: str) -> ModelTable:
    path = str(mi.file_resolver().resolve(MODEL_FILE))
    with open(path, "rb") as f:
        raw = f.read()
    problem = model_problem(raw)
    if problem:
        raise RuntimeError(f"Mitsuba's sRGB model {path} cannot be read: {problem}")
    res = int(np.frombuffer(raw[4:8], dtype="<u4")[0])
    scale = np.frombuffer(raw, dtype="<f4", count=res, offset=8)
    data = np.frombuffer(raw, dtype="<f4", count=3 * res ** 3 * COEFFICIENTS,
                         offset=8 + 4 * res)
    return ModelTable(res, mi.Float(scale), mi.Float(data))


def model_table() -> ModelTable | None:
    """The model for the current variant, loaded once (None outside JIT spectral variants:
    the scalar variant fetches with Mitsuba's own ``srgb_model_fetch``)."""
    if not (mi.is_spectral and dr.is_jit_v(mi.Float)):
        return None
    return _model(mi.variant())


def coefficients(table: ModelTable | None, colour):
    """The model's coefficients of each lane's RGB ``colour`` (see the module docstring);
    ``table`` from :func:`model_table`."""
    if table is None:        # the scalar variant: one colour, Mitsuba's own fetch
        c = [float(colour[k]) for k in range(3)]
        if any(x != x for x in c):
            return mi.Array3f(0.0, 0.0, float("nan"))
        return mi.Array3f(*mi.srgb_model_fetch(mi.ScalarColor3f(*c)))
    Float, UInt32 = mi.Float, mi.UInt32
    res = table.res
    # Clamped to [0, 1] by comparisons a NaN fails (it becomes 0 here; its lane is made
    # NaN by :func:`spectrum`).
    r, g, b = (dr.select(c > 0.0, dr.select(c < 1.0, c, 1.0), 0.0)
               for c in (colour[0], colour[1], colour[2]))
    grey = (r == g) & (g == b)
    # Grey: the closed form (r itself, for r in (0, 1)).
    inside = (r > 0.0) & (r < 1.0)
    grey_q = dr.select(inside, (r - 0.5) / dr.sqrt(dr.select(inside, r * (1.0 - r), 1.0)),
                       dr.select(r >= 1.0, GREY_LIMIT, -GREY_LIMIT))
    # The largest component (the last of equals, as rgb2spec) and the two after it.
    i = dr.select(b >= dr.select(g >= r, g, r), UInt32(2), dr.select(g >= r, UInt32(1), UInt32(0)))
    z = dr.select(i == 2, b, dr.select(i == 1, g, r))
    a1 = dr.select(i == 0, g, dr.select(i == 1, b, r))      # component (i + 1) mod 3
    a2 = dr.select(i == 0, b, dr.select(i == 1, r, g))      # component (i + 2) mod 3
    z = dr.select(grey, 1.0, z)             # grey lanes (black too) read a valid cell
    s = (res - 1) / z
    x, y = a1 * s, a2 * s
    xi = dr.minimum(UInt32(x), res - 2)
    yi = dr.minimum(UInt32(y), res - 2)
    # zi: the largest k ≤ res − 2 with scale[k] ≤ z (scale[0] = 0 < z), by halving steps.
    zi = UInt32(0)
    step = 1 << (max(res - 2, 1).bit_length() - 1)
    while step:
        candidate = dr.minimum(zi + step, res - 2)
        zi = dr.select(dr.gather(Float, table.scale, candidate) <= z, candidate, zi)
        step >>= 1
    z_lo = dr.gather(Float, table.scale, zi)
    z_hi = dr.gather(Float, table.scale, zi + 1)
    x1, y1 = x - Float(xi), y - Float(yi)
    x0, y0 = 1.0 - x1, 1.0 - y1
    z1 = (z - z_lo) / (z_hi - z_lo)
    z0 = 1.0 - z1
    base = ((i * res + zi) * res + yi) * res + xi           # in units of three coefficients
    dy, dz = res, res * res

    def at(offset):
        return dr.gather(mi.Array3f, table.data, base + offset)

    found = (((at(0) * x0 + at(1) * x1) * y0 + (at(dy) * x0 + at(dy + 1) * x1) * y1) * z0
             + ((at(dz) * x0 + at(dz + 1) * x1) * y0
                + (at(dz + dy) * x0 + at(dz + dy + 1) * x1) * y1) * z1)
    return dr.select(grey, mi.Array3f(0.0, 0.0, grey_q), found)


def spectrum(table: ModelTable | None, colour, wavelengths):
    """Each lane's RGB ``colour`` as a smooth spectrum at its ``wavelengths``: Mitsuba's
    ``srgb_model_eval`` of :func:`coefficients`; NaN where the colour has a NaN."""
    value = mi.srgb_model_eval(coefficients(table, colour), wavelengths)
    nan = dr.isnan(colour[0]) | dr.isnan(colour[1]) | dr.isnan(colour[2])
    return dr.select(nan, dr.nan, value)


def mean(table: ModelTable | None, colour):
    """The spectral mean of ``colour``'s spectrum: ``mi.srgb_model_mean``, its average over
    16 wavelengths evenly spaced over 360–830 nm (Mitsuba's ``srgb`` gives this for its one
    colour; ``bitmap`` the average of it over its texels, which is not this of their mean
    colour: the model is not linear)."""
    return mi.srgb_model_mean(coefficients(table, colour))
