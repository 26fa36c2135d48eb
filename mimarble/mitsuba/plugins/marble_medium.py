"""``marble_medium``: a heterogeneous scattering medium whose albedo and density are textures
(issue 26, "Translucent marble": a material's ``subsurface``, rendered by ``volpath``).

At a point p inside (mimarble/scene/model.py, ``Subsurface``)::

    d(p)   = clamp(mean(density(p)), 0, density_bound)   (1 everywhere without a density)
    σ_t(p) = scale · d(p)                                 (scale = 1 / mean_free_path)
    α(p)   = clamp(albedo(p), 0, 1)  componentwise, or, given a reflectance instead,
    α(p)   = inversion(clamp(reflectance(p), 0, 1), F̄(ior))   (subsurface_reflectance.py)
    σ_s    = α · σ_t,    σ_n = σ̄ − σ_t,    σ̄ = scale · density_bound   (the majorant)

Mitsuba samples a tentative collision at rate σ̄ (``Medium::sample_interaction``) and keeps
it as a real one with probability σ_t/σ̄ (delta tracking): σ̄ ≥ σ_t everywhere is what makes
that unbiased, hence the clamp of d to the bound — a bound below the density renders the
clipped medium rather than negative null probabilities. The same σ̄ in every channel and
``has_spectral_extinction`` False (one scalar density) let ``volpath`` weigh a real
collision by σ_s/σ_t = α alone. A constant density at its bound has σ_n = 0: no null
collisions, the homogeneous medium's random walk exactly. The albedo does not enter the
majorant, so a reflectance changes nothing of the sampling but the weights.

A ``reflectance`` C(p) is the colour a thick piece of the medium shows under even light
behind its boundary (docs/rendering-model.md, "The colour you see: reflectance"): per
component α = 1 − s², s from van de Hulst's fit of the spherical albedo after the
boundary's mean Fresnel reflectance F̄(ior) is taken out, computed in Dr.Jit at each point
(every variant; differentiable through the texture). F̄ is computed once, when the medium
is made, by quadrature of ``mi.fresnel``
(:func:`~mimarble.mitsuba.plugins.subsurface_reflectance.diffuse_fresnel_reflectance`).

The textures are any Mitsuba textures (``marble``, ``channel_expression``, ``rgb``,
``srgb``, …), evaluated at a :class:`SurfaceInteraction3f` holding only the point (and
time, wavelengths): no normal, (u, v) = (0, 0), no footprint (``duv_dx``, ``duv_dy`` are
zero; a filtered marble is its colour at the point, as under Mitsuba's own integrators).
Each texture carries its own placement (a marble's ``to_world``), so the medium has no
transform of its own.

Without a ``density_bound`` the kernel reads the density texture's own held maximum
(``plugins.held_maximum``: a marble's, made from its ramp; an expression's, from its
operands'), not a copy made when the medium was last told of a change: ``mi.traverse``
tells only a texture's first parent of an edit, and a density shared with a surface is
often first reached through the surface. Mitsuba's textures give their ``max()``, read
when the kernel is traced (inside a recording: as read for its key just before) and part
of the recording's key (:meth:`recording_key`).

The medium is unbounded (``intersect_aabb``: [0, ∞) for every ray, as ``homogeneous``):
the shape whose ``interior`` it is bounds it.

.. list-table::
   :header-rows: 1

   * - Parameter
     - Type
     - Description
   * - ``albedo``
     - texture, colour or float
     - Single-scattering albedo α, clamped to [0, 1] per component (default 0.75, as
       Mitsuba's media, when no ``reflectance`` is given either). Traversed as
       ``albedo.…``, differentiable through the texture. Not with ``reflectance``.
   * - ``reflectance``
     - texture, colour or float
     - Instead of ``albedo``: the colour seen (the multiple-scattering albedo), clamped to
       [0, 1] per component; α = inversion(reflectance(p), F̄(ior)) at each point (above).
       Traversed as ``reflectance.…``, differentiable through the texture.
   * - ``ior``
     - float > 0 (default 1)
     - With ``reflectance`` only: the boundary's relative index (inside over outside),
       for F̄(ior) = ∫₀¹ F(μ, ior) 2μ dμ (0 at 1, 0.0918 at 1.5). Not traversed.
   * - ``density``
     - texture (optional)
     - d before the clamp: the mean of its three components (none: 1 everywhere) — of its
       RGB colour in every variant (``eval_3`` in spectral ones, where a density without
       one, Mitsuba's ``srgb`` or ``bitmap``, is refused). Traversed as ``density.…``,
       differentiable.
   * - ``scale``
     - float > 0 (default 1)
     - σ_t = scale · d, in inverse scene units. Traversed, differentiable, the majorant
       with it (below).
   * - ``density_bound``
     - float ≥ 0
     - An upper bound of d. Given: as given (traversed, not differentiable), whatever
       the density becomes. Not given: 1 without a density, else the density texture's
       maximum as it is when the kernel runs (below), not traversed.
   * - ``grid_origin``, ``grid_spacing``, ``grid_counts``
     - 3 floats, float > 0, 3 whole numbers ≥ 2 (optional, all three or none)
     - The albedo grid (mimarble/scene/albedo_grid.py; the scene translation gives one):
       α is evaluated once per update at the nodes origin + spacing·(i, j, k), i <
       counts[0], …, and each collision reads one corner of its cell drawn with its
       trilinear weight (:meth:`grid_albedo`) instead of evaluating the textures — a
       stated bias (the trilinear interpolation's; docs/rendering-model.md, "The albedo
       grid"). At most ``contract.MAX_GRID_NODES`` nodes, checked before anything is
       allocated. Made again when the colour texture's traversed values change: at an
       update of the medium, or :meth:`refresh_grid` (the pass renderer calls it before
       each render; an edit Mitsuba told only another parent of is refused in one
       sentence when a kernel is traced with the old grid). Differentiable through the
       nodes. Ignored in the scalar and spectral variants (α evaluated at each collision).
   * - ``sample_emitters``
     - bool (default true)
     - Mitsuba's: shadow rays from inside (useless behind a boundary that is not ``null``,
       as ``subsurface_boundary``: they stop at it).
   * - (nested)
     - phase function
     - Mitsuba's: default ``isotropic``; a microflake phase is refused (its σ_t would need
       its projected area, which this medium does not apply).
"""

from __future__ import annotations

import math

from mimarble.runtime import environment
from mimarble.texture import srgb_model
from mimarble.mitsuba.plugins.registration import (Kept, describe, first_number, held_maximum,
    plugin, recording_key)
from mimarble.contract import FLT_MAX, MAX_GRID_NODES
from .channel_expression import gives_rgb
from .subsurface_reflectance import diffuse_fresnel_reflectance, single_scattering_albedo

dr, mi = environment.import_drjit_and_mitsuba()

#: Mitsuba's default single-scattering albedo of its media (src/media/homogeneous.cpp).
DEFAULT_ALBEDO = 0.75


def _half_types():
    """(Dr.Jit's half-precision float of the variant's backend, its 4-vector)."""
    backend = dr.cuda.ad if dr.backend_v(mi.Float) == dr.JitBackend.CUDA else dr.llvm.ad
    return backend.Float16, backend.Array4f16


class MarbleMediumError(ValueError):
    """An invalid ``marble_medium``; the message names the parameter."""


def _number_problem(name: str, value, least: float, strict: bool) -> str | None:
    """What is wrong with a number that must be finite and > (or ≥) ``least``, or None."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not math.isfinite(value) or (value <= least if strict else value < least):
        return (f"marble_medium: {name}={value!r} must be a finite number "
                f"{'>' if strict else '≥'} {least:g}")
    return None


def _host_number(value, read: bool):
    """A traversed number as the host holds it: read when ``read`` (at load; the scalar
    variant), else only a literal's (copied without waiting); None: on the device."""
    if read or not dr.is_jit_v(mi.Float):
        return first_number(value)
    return value[0] if value.state == dr.VarState.Literal else None


def _three_numbers(value) -> list | None:
    """``value`` (a property's: a list, a vector) as three Python floats, or None where it
    is not three numbers."""
    try:
        numbers = [float(v) for v in value]
    except (TypeError, ValueError):
        return None
    return numbers if len(numbers) == 3 else None


def _held(value: float):
    """A traversed number in a container ``mi.traverse`` can write into, in every variant:
    ``mi.Float`` in JIT variants, a one-element ``ArrayXf`` in scalar_rgb (where mi.Float is
    a Python float)."""
    return mi.Float(value) if dr.is_jit_v(mi.Float) else dr.scalar.ArrayXf([value])


@plugin("medium", "marble_medium")
class MarbleMedium:
    """Heterogeneous medium with texture albedo (or reflectance) and density: see
    mimarble/mitsuba/plugins/marble_medium.py for the parameters and the math."""

    def __init__(self, props):
        # The base takes the nested phase function (else makes an isotropic one) and
        # sample_emitters; it leaves the two flags below to the subclass.
        mi.Medium.__init__(self, props)
        variant_problem = srgb_model.variant_problem("marble_medium")
        if variant_problem:
            raise MarbleMediumError(variant_problem)
        self.m_is_homogeneous = False          # d varies: null collisions, a full intersection
        self.m_has_spectral_extinction = False  # one scalar density: σ̄ is grey
        phase = self.phase_function()
        if mi.has_flag(phase.flags(), mi.PhaseFunctionFlags.Microflake):
            raise MarbleMediumError("marble_medium: a microflake phase function is not "
                                    "supported; use isotropic (the default) or hg")
        self._albedo_and_reflectance(props)
        self._grid_layout(props)
        self.density = props.get_texture("density") if "density" in props else None
        if mi.is_spectral and self.density is not None and not gives_rgb(self.density):
            # d is a number made from the density's RGB colour (density_at), the same in
            # every variant; in spectral variants Mitsuba's srgb and bitmap keep spectra.
            raise MarbleMediumError(
                f"marble_medium: in a spectral variant the density must keep an RGB colour "
                f"(a marble, a channel_expression of such, a number), not "
                f"{self.density.class_name()}")
        scale = props.get("scale", 1.0)
        problem = _number_problem("scale", scale, 0.0, strict=True)
        self._bound_given = "density_bound" in props
        bound = props.get("density_bound") if self._bound_given else self._derived_bound()
        problem = problem or _number_problem("density_bound", bound, 0.0, strict=False)
        if problem:
            raise MarbleMediumError(problem)
        self.editable = {"scale": _held(float(scale))}
        if self._bound_given:
            self.editable["density_bound"] = _held(float(bound))
        self.parameters_changed([])

    def _grid_layout(self, props):
        """The albedo grid's layout (``grid_origin``, ``grid_spacing``, ``grid_counts``: all
        three or none), checked before anything is allocated; None without one, and in
        spectral variants, where α depends on the wavelength and is evaluated directly."""
        names = ("grid_origin", "grid_spacing", "grid_counts")
        given = [name in props for name in names]
        self.grid_layout = self.grid = None
        if not any(given):
            return
        if not all(given):
            raise MarbleMediumError("marble_medium: grid_origin, grid_spacing and grid_counts "
                                    "go together (the albedo grid), not one without the others")
        origin, counts = (_three_numbers(props.get(name)) for name in ("grid_origin",
                                                                          "grid_counts"))
        spacing = props.get("grid_spacing")
        problem = _number_problem("grid_spacing", spacing, 0.0, strict=True)
        if not problem and not (origin and all(math.isfinite(v) for v in origin)):
            problem = (f"marble_medium: grid_origin={props.get('grid_origin')!r:.60} must be "
                       f"three finite numbers")
        if not problem and not (counts and all(c.is_integer() and c >= 2 for c in counts)):
            problem = (f"marble_medium: grid_counts={props.get('grid_counts')!r:.60} must be "
                       f"three whole numbers ≥ 2 (nodes along x, y, z)")
        if not problem and math.prod(counts) > MAX_GRID_NODES:
            problem = (f"marble_medium: an albedo grid of {math.prod(counts):.0f} nodes is "
                       f"past the limit of {MAX_GRID_NODES} (a coarser grid_spacing, or none)")
        if problem:
            raise MarbleMediumError(problem)
        if not mi.is_spectral and dr.is_jit_v(mi.Float):
            self.grid_layout = (tuple(origin), float(spacing), tuple(int(c) for c in counts))

    def _albedo_and_reflectance(self, props):
        """``albedo`` (default 0.75) or ``reflectance`` with its ``ior`` (default 1), F̄(ior)
        computed here; both, or an ior without a reflectance, refused."""
        self.albedo = self.reflectance = None
        if "reflectance" in props:
            if "albedo" in props:
                raise MarbleMediumError("marble_medium: give albedo (single-scattering) or "
                                        "reflectance (the colour seen), not both")
            self.reflectance = props.get_texture("reflectance")
            self.ior = props.get("ior", 1.0)
            problem = _number_problem("ior", self.ior, 0.0, strict=True)
            if problem:
                raise MarbleMediumError(problem)
            self.fresnel_mean = diffuse_fresnel_reflectance(float(self.ior))
            return
        if "ior" in props:
            raise MarbleMediumError("marble_medium: ior is the boundary's index for a "
                                    "reflectance's inversion; without a reflectance it has "
                                    "no use")
        self.albedo = props.get_texture("albedo") if "albedo" in props \
            else mi.load_dict({"type": "uniform", "value": DEFAULT_ALBEDO})

    def _derived_bound(self) -> float:
        """The bound when none is given, read back (for the checks): 1 without a density
        texture (d = 1); else the texture's maximum, an upper bound of every component,
        hence of their mean."""
        if self.density is None:
            return 1.0
        try:
            return max(0.0, first_number(held_maximum(self.density)[0]))
        except RuntimeError:         # Texture::max(): not implemented (checkerboard, …)
            raise MarbleMediumError(f"marble_medium: the density texture "
                                    f"({self.density.class_name()}) gives no max(); "
                                    f"give density_bound") from None

    def density_bound(self):
        """The bound the kernel reads: as given (the traversed value); else 1 without a
        density, or the density's held maximum (at least 0) as it is now — a Dr.Jit value
        for a mimarble texture, which follows every edit of it (module docstring)."""
        if self._bound_given:
            return self.bound
        if self.density is None:
            return 1.0
        return dr.maximum(held_maximum(self.density)[0], 0.0)

    # -- Mitsuba object protocol -------------------------------------------

    def traverse(self, cb):
        mi.Medium.traverse(self, cb)             # phase_function
        cb.put("scale", self.editable["scale"], mi.ParamFlags.Differentiable)
        if self._bound_given:
            cb.put("density_bound", self.editable["density_bound"],
                   mi.ParamFlags.NonDifferentiable)
        if self.reflectance is not None:
            cb.put("reflectance", self.reflectance, mi.ParamFlags.Differentiable)
        else:
            cb.put("albedo", self.albedo, mi.ParamFlags.Differentiable)
        if self.density is not None:
            cb.put("density", self.density, mi.ParamFlags.Differentiable)

    def parameters_changed(self, keys=[]):
        """Check scale and density_bound as ``mi.traverse`` left them (an invalid edit
        raises and puts the last valid values back). Both are opaque: a new value reuses
        the kernel. Read only where that costs no wait for the device (at load; a Python
        number set through ``mi.traverse``, a literal): a value computed on the device (an
        optimiser's) is checked in the kernel instead — while scale ≤ 0, a bound < 0 or
        their product past float32's range, every collision in the medium is NaN
        (:meth:`_defined`; docs/design-decisions.md, "The update path")."""
        jit = dr.is_jit_v(mi.Float)
        loading = not keys or not jit
        held = {name: _host_number(value, loading) for name, value in self.editable.items()}
        if jit:
            dr.make_opaque(*self.editable.values())
        scale = held["scale"]
        bound = held["density_bound"] if self._bound_given else \
            self._derived_bound() if loading else None
        problem = (scale is not None and _number_problem("scale", scale, 0.0, strict=True)) \
            or (bound is not None and _number_problem("density_bound", bound, 0.0,
                                                       strict=False))
        if not problem and scale is not None and bound is not None \
                and not scale * bound <= FLT_MAX:   # σ̄ = ∞: every step 0 long
            problem = (f"marble_medium: the majorant scale·density_bound = {scale * bound:.3g} "
                       f"is past float32's {FLT_MAX:.3g}")
        if problem:
            for name, value in getattr(self, "_last_valid", {}).items():
                mi.set_property(self.editable[name], _held(value))   # in place: traverse holds them
            raise MarbleMediumError(problem)
        last = dict(getattr(self, "_last_valid", {}))
        last.update({name: value for name, value in (("scale", scale), ("density_bound", bound))
                     if value is not None})
        self._last_valid = last
        if not self._bound_given:
            self._last_valid.pop("density_bound", None)
        if jit:   # the kernel reads the traversed values themselves
            self.scale, self.bound = self.editable["scale"], self.editable.get("density_bound")
        else:     # the scalar variant computes on Python floats
            self.scale, self.bound = scale, bound
        self.refresh_grid()

    def _colour_values(self) -> tuple:
        """(the Dr.Jit variables — JIT and AD indices — of every traversed value of the
        colour texture, reflectance or albedo, expressions' operands included; the values
        themselves): an edit through ``mi.traverse`` puts a new variable in place, enabling
        a gradient adds an AD one."""
        params = mi.traverse(self.reflectance if self.reflectance is not None else self.albedo)
        # Own references to the variables (a copy shares them), not the objects
        # themselves: an edit writes a new variable into the same object. Copied with the
        # gradients resumed: under dr.suspend_grad (mi.render's primal pass of a
        # differentiated render) a copy would be a detached variable, another index.
        with dr.resume_grad():
            values = tuple(type(params[key])(params[key]) if dr.is_array_v(params[key])
                           else params[key] for key in params.keys())
        state = tuple((key, tuple(dr.detail.collect_indices(value)))
                      for key, value in zip(params.keys(), values))
        return state, values

    def _grid_is_current(self) -> bool:
        """Whether the colour's values are the ones the grid was baked from. The baked
        values are held (:meth:`refresh_grid`), so their variables stay alive and Dr.Jit
        cannot give a later value one of their indices: equal indices are the same values."""
        baked = getattr(self, "_baked", None)
        return baked is not None and self._colour_values()[0] == baked.value[0]

    def refresh_grid(self) -> None:
        """Bake the grid again if the colour texture's traversed values are not those it was
        baked from. Called at each update of the medium and before each render
        (``replay.refresh_derived``: the pass renderer and ``mimarble.render``'s
        ``mi.render``): ``mi.traverse`` tells only an edited texture's first parent, which
        may be another medium of the same material or a surface."""
        if self.grid_layout is not None and not self._grid_is_current():
            state, values = self._colour_values()
            self._bake()
            # Held outside what a recording walks (Kept): the indices' owners.
            self._baked = Kept((state, values))

    def _bake(self):
        """α at every node of the grid, into ``self.grid``, evaluated now in one kernel with
        the textures as they are — attached: a gradient of a texture parameter reaches it
        through the lookups. Node (i, j, k) is origin + spacing·(i, j, k). Held as 1 − α in
        half precision, four a node (RGB and a pad: a corner is one aligned 8-byte packet
        gather): half the memory of float32, so a grid twice as fine fits the cache as
        well; 1 − α, not α, because white marble's α ≈ 0.999 needs its distance from 1 (a
        half rounds it to 2⁻¹¹ of itself; α itself would round to 2⁻¹¹)."""
        origin, spacing, (nx, ny, nz) = self.grid_layout
        index = dr.arange(mi.UInt32, nx * ny * nz)
        i, rest = index % nx, index // nx
        j, k = rest % ny, rest // ny
        si = dr.zeros(mi.SurfaceInteraction3f, nx * ny * nz)
        si.p = mi.Point3f(*(o + spacing * mi.Float(n) for o, n in zip(origin, (i, j, k))))
        albedo = self.albedo_at(si)
        half = _half_types()[0]
        grid = dr.zeros(half, 4 * nx * ny * nz)
        for c in range(3):
            dr.scatter(grid, half(1.0 - albedo[c]), 4 * index + c)
        dr.eval(grid)
        self.grid = grid

    def grid_albedo(self, p, active=True):
        """α at world points ``p`` from the grid's nodes, one corner of the cell around p
        drawn with its trilinear weight (stochastic filtering, Pharr et al. 2024): u =
        (p − origin)/spacing clamped to the grid, the cell [⌊u⌋, ⌊u⌋ + 1] (its last one at
        the far faces), on each axis the upper node with probability u − ⌊u⌋, so that a
        corner's probability is its trilinear weight and the expectation of what is read is
        the trilinear interpolation. One 8-byte gather instead of eight. The numbers drawn
        are a hash of p's bits (TEA, 4 rounds: x and z in one word, y in the other; 24,
        24 and 16 bits): the medium has no sampler, and p itself is a draw of the walk —
        no two collisions share it."""
        origin, spacing, counts = self.grid_layout
        bits = [dr.reinterpret_array(mi.UInt32, p[axis]) for axis in range(3)]
        a, b = mi.sample_tea_32(bits[0] ^ ((bits[2] << 16) | (bits[2] >> 16)), bits[1], 4)
        draws = (mi.Float(a >> 8) * 2.0 ** -24, mi.Float(b >> 8) * 2.0 ** -24,
                 mi.Float((a & 0xFF) | ((b & 0xFF) << 8)) * 2.0 ** -16)
        node = []
        for axis in range(3):
            u = dr.clip((p[axis] - origin[axis]) * (1.0 / spacing), 0.0, counts[axis] - 1.0)
            cell = dr.minimum(mi.UInt32(u), counts[axis] - 2)
            node.append(dr.select(draws[axis] < u - mi.Float(cell), cell + 1, cell))
        index = node[0] + counts[0] * (node[1] + counts[1] * node[2])
        kept = dr.gather(_half_types()[1], self.grid, index, active)
        return 1.0 - mi.Color3f(mi.Float(kept.x), mi.Float(kept.y), mi.Float(kept.z))

    def _defined(self):
        """Whether scale and the bound keep their rules as they are now (scale > 0 and
        finite, bound ≥ 0, σ̄ within float32): what the kernel checks of a value the host
        did not read. The scalar variant checked its values at the update."""
        if not dr.is_jit_v(mi.Float):
            return True
        scale, bound = dr.detach(self.scale), dr.detach(mi.Float(self.density_bound()))
        return (scale > 0.0) & dr.isfinite(scale) & (bound >= 0.0) \
            & (scale * bound <= FLT_MAX)

    def recording_key(self) -> tuple:
        """What decides the code traced besides Dr.Jit's variables (see
        ``Marble.recording_key``): whether there is a density, the textures' own keys, and
        the host values a bound not given is made of (a Mitsuba texture's ``max()``), and a
        reflectance's F̄ (a literal in the kernel)."""
        derived = not self._bound_given and self.density is not None
        colour = ("albedo", recording_key(self.albedo)) if self.reflectance is None else \
            ("reflectance", recording_key(self.reflectance), self.fresnel_mean)
        return ("marble_medium", self.density is None, colour, self.grid_layout,
                recording_key(self.density), self._bound_given,
                held_maximum(self.density)[1] if derived else ())

    def to_string(self):
        colour = {"albedo": self.albedo} if self.reflectance is None else \
            {"reflectance": self.reflectance, "ior": self.ior, "fresnel_mean": self.fresnel_mean}
        return describe("MarbleMedium", {
            **colour,
            "density": "1 (none given)" if self.density is None else self.density,
            "scale": first_number(self.scale),
            "density_bound": first_number(self.density_bound()),
            "majorant": first_number(self.majorant),
            "phase_function": self.phase_function()})

    # -- The medium ------------------------------------------------------------

    def intersect_aabb(self, ray):
        """Unbounded, as ``homogeneous``: every ray is inside over [0, ∞) (the boundary
        shape ends it)."""
        return mi.Bool(True), mi.Float(0.0), mi.Float(dr.inf)

    @property
    def majorant(self):
        """σ̄ = scale · density_bound, with scale's derivative (below)."""
        return self.scale * self.density_bound()

    def get_majorant(self, mei, active=True):
        """σ̄, the same in every channel.

        It keeps scale's derivative. ``prbvolpath`` differentiates the null-collision
        path weight Π exp(−σ̄ t_i) · Π σ_n · Π σ_s, whose expectation does not depend on σ̄:
        with σ̄ detached, the transmittance's derivative would come only through null
        collisions, which are never sampled where σ_n = 0 (a constant density: the
        derivative of exp(−σ_t t) lost). With σ̄ = scale · bound attached, d log weight =
        −Σ t_i dσ̄ + Σ dσ_n/σ_n + Σ dσ_s/σ_s, over a sampling whose support (σ_n > 0)
        does not move with scale: unbiased. The textures are evaluated at the detached
        point (:meth:`get_scattering_coefficients`), so the sampled distance's own
        dependence on σ̄ adds nothing. Where :meth:`_defined` fails, FLT_MAX: every ray
        collides where it enters, at a NaN coefficient."""
        return mi.UnpolarizedSpectrum(dr.select(self._defined(), self.majorant, FLT_MAX))

    def _texture_point(self, mei):
        """What a texture reads at the medium point: the point, time and wavelengths;
        every other field zero (no normal, (u, v) = (0, 0), no footprint)."""
        si = dr.zeros(mi.SurfaceInteraction3f, dr.width(mei.p)) if dr.is_jit_v(mi.Float) \
            else dr.zeros(mi.SurfaceInteraction3f)
        # Detached: Mitsuba samples the point at a distance −log(1 − u)/σ̄, which moves
        # with scale; the sampling decision is not part of what is differentiated.
        si.p, si.time, si.wavelengths = dr.detach(mei.p), mei.time, mei.wavelengths
        return si

    def density_at(self, si, active=True):
        """d = clamp(mean of the density's three components, 0, density_bound); 1 without
        a density texture (at most density_bound, so that the majorant bounds σ_t)."""
        bound = self.density_bound()
        if self.density is None:
            return dr.minimum(mi.Float(1.0), bound)
        # Spectral variants: the RGB colour (eval_3), not its spectrum: d is no colour.
        c = self.density.eval_3(si, active) if mi.is_spectral else self.density.eval(si, active)
        return dr.clip((c[0] + c[1] + c[2]) / 3.0, 0.0, bound)

    def albedo_at(self, si, active=True):
        """α at the texture point: the albedo clamped to [0, 1], or the reflectance's
        inversion for F̄(ior) (module docstring)."""
        if self.reflectance is None:
            return dr.clip(mi.UnpolarizedSpectrum(self.albedo.eval(si, active)), 0.0, 1.0)
        colour = mi.UnpolarizedSpectrum(self.reflectance.eval(si, active))
        return single_scattering_albedo(colour, self.fresnel_mean)

    def get_scattering_coefficients(self, mei, active=True):
        """(σ_s, σ_n, σ_t) at ``mei.p``; zero where ``active`` is False (as ``homogeneous``
        gives: Mitsuba asks at points past the medium too, p = ray(∞) there)."""
        if self.grid is not None and not self._grid_is_current():
            raise MarbleMediumError(
                "marble_medium: its colour texture was edited after the albedo grid was made "
                "(mi.traverse told another parent of it); call refresh_grid() on the medium "
                "before mi.render (mimarble.render does)")
        si = self._texture_point(mei)
        sigma_t = dr.select(self._defined(), self.scale * self.density_at(si, active), dr.nan)
        albedo = self.albedo_at(si, active) if self.grid is None \
            else mi.UnpolarizedSpectrum(self.grid_albedo(si.p, active))
        sigma_s = albedo * sigma_t
        sigma_n = self.majorant - sigma_t
        zero = mi.UnpolarizedSpectrum(0.0)
        return (dr.select(active, sigma_s, zero),
                dr.select(active, mi.UnpolarizedSpectrum(sigma_n), zero),
                dr.select(active, mi.UnpolarizedSpectrum(sigma_t), zero))
