"""From a sample's pixel and index to its camera ray and its radiance.

A sample is named by two integers, the pixel (row-major, ``y·width + x``) and its
index ``sub`` among the pixel's ``spp``, so that a pass of any run of pixels or of
samples is one ``arange`` away (mimarble/mitsuba/rendering/passes.py). Whitted mode puts
sample ``sub`` at the centre of stratum ``(sub mod n, ⌊sub / n⌋)`` of an n×n grid
(spp = n²); path mode draws it from the scene's sampler (in spectral variants its
wavelengths next, and its spectrum becomes sRGB as Mitsuba's film makes it). Every number
that differs between renders (width, spp, the pass's seed) is opaque, so one kernel serves
them all.
"""

from __future__ import annotations

from mimarble.runtime import environment
from mimarble.mitsuba.plugins.registration import largest_component
from mimarble.scene.model import samples_per_axis

dr, mi = environment.import_drjit_and_mitsuba()


class PassNumbers:
    """The numbers of one pass that vary between passes and renders, as opaque Dr.Jit
    values (one kernel serves them all, and a recording takes them as inputs): the
    first pixel and sample of the pass, samples per pixel in the pass, the spp's
    stratum count per axis and its reciprocal, the differentials' scale 1/√spp, the
    sampler's seed (path mode), and where an adaptive round starts in each cell's order of
    strata (``cell_offset``, :func:`nested_stratum`; 0 in any other pass)."""

    DRJIT_STRUCT = {"first_pixel": object, "first_sample": object, "samples": object,
                    "per_axis": object, "stratum": object, "differential_scale": object,
                    "seed": object, "cell_offset": object}

    def __init__(self, first_pixel: int, first_sample: int, samples: int, spp: int,
                 seed: int, whitted: bool, cell_offset: int = 0):
        """``whitted``: the samples are the n×n stratum centres (spp = n²)."""
        u32, f32 = (lambda v: dr.opaque(mi.UInt32, v)), (lambda v: dr.opaque(mi.Float, v))
        n = samples_per_axis(spp) if whitted else 1
        self.first_pixel, self.first_sample, self.samples = \
            u32(first_pixel), u32(first_sample), u32(samples)
        # Reciprocals in float64, then rounded, as they were always made.
        self.per_axis, self.stratum = u32(n), f32(1.0 / n)
        self.differential_scale = f32(1.0 / spp ** 0.5)
        self.seed = u32(seed)
        self.cell_offset = u32(cell_offset)


#: The order in which a cell of the m grid gets its 8 other strata of the 3m grid: (dx,
#: dy) ∈ {0, 1, 2}², two bits each, pairs symmetric about the centre (1, 1) — both
#: diagonals, then the middles of the sides — so that a cell with its centre and the
#: first 2k of them is exact for a linear integrand, as the midpoint rule is.
CELL_ORDER = ((0, 0), (2, 2), (2, 0), (0, 2), (1, 0), (1, 2), (0, 1), (2, 1))
_DX = sum(dx << 2 * r for r, (dx, _) in enumerate(CELL_ORDER))
_DY = sum(dy << 2 * r for r, (_, dy) in enumerate(CELL_ORDER))


def nested_stratum(new, parent_axis: int, per_cell: int, cell_offset, parity):
    """The stratum (column, row) in the 3m×3m grid (m = ``parent_axis``) of the ``new``-th
    sample an adaptive round adds to a pixel whose samples lie on that grid: each cell of
    the m grid holds its centre and its first ``cell_offset`` (opaque) other strata
    (:data:`CELL_ORDER`), and gets ``per_cell`` more. ``parent_axis`` and ``per_cell`` are
    Python numbers, literals of the kernel: a division by an opaque integer is a scalar loop
    in a vector kernel (it made a round's lanes markedly dearer: docs/benchmarks.md,
    "Figures moved out of the code"), by a literal a multiplication.

    The centre of stratum (i, j) of the m grid, ((i + ½)/m, (j + ½)/m), is the centre of
    stratum (3i + 1, 3j + 1) of the 3m grid — an odd refinement keeps every old centre.
    Sample ``new`` is in cell c = ⌊new / per_cell⌋, the (offset + new mod per_cell)-th of
    its order; in cells where ``parity`` (UInt32, per lane: the pixel's x + y) plus the
    cell's column and row is odd the order is mirrored left to right, so that neighbouring
    cells take the two diagonals in turn."""
    m = parent_axis
    cell = new // per_cell
    r = cell_offset + (new - cell * per_cell)
    cy = cell // m
    cx = cell - cy * m
    dx = (mi.UInt32(_DX) >> (2 * r)) & 3
    dy = (mi.UInt32(_DY) >> (2 * r)) & 3
    dx = dr.select(((parity + cx + cy) & 1) == 1, 2 - dx, dx)
    return 3 * cx + dx, 3 * cy + dy


class PixelTracer:
    """Radiance of samples given by pixel index and sample index within the pixel."""

    def __init__(self, mitsuba_scene, mode: str, sampler=None):
        """``sampler``: what path mode draws from (default: a clone of the sensor's);
        whitted mode draws nothing."""
        self.scene = mitsuba_scene
        self.sensor = mitsuba_scene.sensors()[0]
        self.integrator = mitsuba_scene.integrator()
        self.width, self.height = (int(x) for x in self.sensor.film().crop_size())
        self.whitted = mode == "whitted"
        self.sampler = self.sensor.sampler().clone() if sampler is None else sampler
        # Mitsuba's perspective camera starts a ray at the near clip plane but its two
        # differential rays at that same point, not at the eye: pixel footprints came out
        # (t − near)/t of their size (half, for fig11a). They start at the eye here.
        self.eye = mi.Point3f(self.sensor.world_transform().translation())
        f32 = self.f32
        self.columns = self.u32(self.width)
        # Reciprocals, as Dr.Jit makes of a division by a constant: Mitsuba's own image bit for bit.
        self.inv_film = mi.Point2f(f32(1.0 / self.width), f32(1.0 / self.height))

    @staticmethod
    def u32(value):
        return dr.opaque(mi.UInt32, value)

    @staticmethod
    def f32(value):
        return dr.opaque(mi.Float, value)

    def ray(self, pixel, sub, numbers: PassNumbers):
        """(ray with differentials, weight) of sample ``sub`` in ``pixel`` (whitted mode: an
        index, or the stratum's (column, row))."""
        y = pixel // self.columns
        x = pixel - y * self.columns
        wavelength_sample = 0.0
        if self.whitted:
            column, row = sub if isinstance(sub, tuple) else \
                (sub % numbers.per_axis, sub // numbers.per_axis)
            offset = (mi.Point2f(mi.Float(column), mi.Float(row)) + 0.5) * numbers.stratum
        else:
            self.sampler.seed(numbers.seed, dr.width(pixel))
            offset = self.sampler.next_2d()
            if mi.is_spectral:    # the wavelengths next, as Mitsuba's render_sample draws them
                wavelength_sample = self.sampler.next_1d()
        position = (mi.Point2f(mi.Float(x), mi.Float(y)) + offset) * self.inv_film
        ray, weight = self.sensor.sample_ray_differential(
            mi.Float(self.sensor.shutter_open()), wavelength_sample, position, mi.Point2f(0.5))
        if ray.has_differentials:
            ray.scale_differential(numbers.differential_scale)
            ray.o_x = ray.o_y = self.eye
        return ray, weight

    def trace(self, pixel, sub, numbers: PassNumbers, with_shapes: bool):
        """(weighted radiance, first shape hit or 0, when ``with_shapes``) of each lane:
        sample ``sub`` in pixel ``pixel``. The shape comes from the
        integrator's own intersection where it offers one (``whitted``'s
        ``sample_and_shape``), else from a second ``ray_intersect``."""
        ray, weight = self.ray(pixel, sub, numbers)
        shape = None
        if with_shapes and hasattr(self.integrator, "sample_and_shape"):
            radiance, _, _, shape = self.integrator.sample_and_shape(
                self.scene, self.sampler, ray, None, True)
        else:
            radiance = self.integrator.sample(self.scene, self.sampler, ray, None, True)[0]
            if with_shapes:
                shape = self._shape(ray)
        if mi.is_spectral:        # the sample's spectrum as sRGB, as Mitsuba's film takes it
            return mi.spectrum_to_srgb(weight * radiance, ray.wavelengths), shape
        return weight * radiance, shape

    def trace_with_doubts(self, pixel, sub, numbers: PassNumbers):
        """(weighted radiance, first shape hit or 0, weighted doubt) of each lane, from
        ``whitted``'s ``shade`` with doubts (mimarble/mitsuba/rendering/adaptive.py)."""
        ray, weight = self.ray(pixel, sub, numbers)
        radiance, shape, doubt = self.integrator.shade(self.scene, ray, True, doubts=True)
        return weight * radiance, shape, largest_component(weight) * doubt

    def first_shape(self, pixel, sub, numbers: PassNumbers):
        """The id of the first shape each (whitted) sample hits, 0 for a miss."""
        return self._shape(self.ray(pixel, sub, numbers)[0])

    def _shape(self, ray):
        return dr.reinterpret_array(mi.UInt32, self.scene.ray_intersect(ray).shape)
