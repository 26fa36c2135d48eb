"""``channel_material``: the paper's material, channels bound to colours or marble.

A BSDF plugin that carries the three channels of the paper's §3.2 — ``ambient``,
``diffuse``, ``specular``, each any Mitsuba texture (``rgb`` for the paper's
ChannelColor, ``marble`` for ChannelMarble) or absent — and a Phong exponent
``shininess``. The ``whitted`` integrator reads the channels through
:meth:`channels`; a texture given twice as the same object (a ``ref`` in the scene
dict), also inside ``channel_expression`` operands, is evaluated once.

.. list-table::
   :header-rows: 1

   * - Parameter
     - Type
     - Description
   * - ``ambient``, ``diffuse``, ``specular``
     - texture (absent: black, and no work)
     - The channels ka, kd, ks.
   * - ``shininess``
     - float (32)
     - Phong exponent of the specular channel.

Under any other integrator it behaves as a Lambertian BSDF with reflectance
``diffuse`` (so ``path`` and the ``aov`` albedo still make sense); in spectral variants
that reflectance is the channel's spectrum (its textures upsample their colours as
Mitsuba's ``bitmap`` does), while the ``whitted`` integrator, which reads the channels as
colours, stays RGB-only.
"""

from __future__ import annotations

from mimarble.runtime import environment
from mimarble.mitsuba.plugins.registration import (Kept, describe, first_number, plugin,
    recording_key)
from .shared_evaluations import (evaluate, evaluate_alternate, shared_evaluations,
                                 textures_within)

dr, mi = environment.import_drjit_and_mitsuba()

CHANNELS = ("ambient", "diffuse", "specular")


@plugin("bsdf", "channel_material")
class ChannelMaterial:
    """The paper's Material: ambient/diffuse/specular channels and a shininess."""

    def __init__(self, props):
        mi.BSDF.__init__(self, props)
        # get_texture turns an inline rgb into a texture, as C++ plugins do
        self._hold_channels(tuple(props.get_texture(name) if name in props else None
                                  for name in CHANNELS))
        shininess = props.get("shininess", 32.0)
        _check_shininess(shininess)
        self.shininess = mi.Float(shininess) if dr.is_jit_v(mi.Float) else \
            dr.scalar.ArrayXf([shininess])   # scalar_rgb: a container mi.traverse can write
        self.parameters_changed()
        self.m_flags = mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide
        self.m_components = [self.m_flags]

    def _hold_channels(self, textures: tuple) -> None:
        """Hold the channels' ``textures`` (in :data:`CHANNELS`' order, None: absent),
        each object once: ``_textures`` the distinct ones, ``_slots`` each channel's
        place among them. A recorded pass walks the material's attributes at every replay
        (Dr.Jit's ``freeze``, mimarble/mitsuba/rendering/replay.py), several times a call;
        held once, a marble bound to two channels (the paper's ambient and diffuse) is
        walked once (docs/design-decisions.md, "Adaptive samples: the pass's fixed cost")."""
        distinct = []
        for texture in textures:
            if texture is not None and not any(texture is seen for seen in distinct):
                distinct.append(texture)
        self._textures = tuple(distinct)
        self._slots = tuple(None if texture is None else
                            next(k for k, seen in enumerate(distinct) if seen is texture)
                            for texture in textures)

    def _channel(self, number: int):
        slot = self._slots[number]
        return None if slot is None else self._textures[slot]

    ambient = property(lambda self: self._channel(0), doc="ka: a texture, or None.")
    diffuse = property(lambda self: self._channel(1), doc="kd: a texture, or None.")
    specular = property(lambda self: self._channel(2), doc="ks: a texture, or None.")

    # -- what the whitted integrator calls --------------------------------------

    def channels(self, si, active=True):
        """(ka, kd, ks, shininess) at the surface point ``si``; absent channels are 0.

        A texture object met more than once — the same marble in two channels, or
        inside expressions of several — is evaluated once (``shared_evaluations``)."""
        values = {}
        with shared_evaluations():
            for name in CHANNELS:
                texture = getattr(self, name)
                values[name] = dr.zeros(mi.Color3f, dr.width(si.p)) if texture is None \
                    else evaluate(texture, si, active)
        return values["ambient"], values["diffuse"], values["specular"], self.exponent

    def channels_and_doubts(self, si, active=True):
        """:meth:`channels`, and each channel's doubt: |its colour − its second estimate|
        (``Marble.eval_and_alternate``, combined through expressions), 0 for a channel
        without a marble. Needs the footprint and :meth:`prepare_alternates` first."""
        values, doubts = {}, {}
        width = dr.width(si.p)
        with shared_evaluations(alternates=True):
            for name in CHANNELS:
                texture = getattr(self, name)
                values[name] = dr.zeros(mi.Color3f, width) if texture is None \
                    else evaluate(texture, si, active)
            for name in CHANNELS:
                texture = getattr(self, name)
                doubts[name] = dr.zeros(mi.Color3f, width) if texture is None \
                    else dr.abs(evaluate_alternate(texture, si, active) - values[name])
        return (values["ambient"], values["diffuse"], values["specular"], self.exponent,
                doubts["ambient"], doubts["diffuse"], doubts["specular"])

    def prepare_alternates(self) -> None:
        """Every marble within the channels makes what its second estimate reads."""
        for name in CHANNELS:
            for texture in textures_within(getattr(self, name)):
                if hasattr(texture, "prepare_alternate"):
                    texture.prepare_alternate()

    def has_channel(self, name: str) -> bool:
        return getattr(self, name) is not None

    def needs_differentials(self) -> bool:
        """Some channel is, or holds, a filtered marble: the integrator must provide footprints."""
        return any(getattr(texture, "filter", "none") != "none"
                   for name in CHANNELS for texture in textures_within(getattr(self, name)))

    # -- a Lambertian BSDF for every other integrator -------------------------

    def _albedo(self, si, active):
        """The diffuse channel's value: a colour, or in spectral variants a spectrum."""
        if self.diffuse is None:
            return dr.zeros(mi.UnpolarizedSpectrum, dr.width(si.p))
        return self.diffuse.eval(si, active)

    def sample(self, ctx, si, sample1, sample2, active=True):
        cos_i = mi.Frame3f.cos_theta(si.wi)
        bs = dr.zeros(mi.BSDFSample3f)
        bs.wo = mi.warp.square_to_cosine_hemisphere(sample2)
        bs.pdf = mi.warp.square_to_cosine_hemisphere_pdf(bs.wo)
        bs.eta = 1.0
        bs.sampled_type = mi.UInt32(+mi.BSDFFlags.DiffuseReflection)
        bs.sampled_component = 0
        ok = active & (cos_i > 0) & (bs.pdf > 0)
        return bs, dr.select(ok, self._albedo(si, ok), 0.0)

    def eval(self, ctx, si, wo, active=True):
        cos_o = mi.Frame3f.cos_theta(wo)
        ok = active & (mi.Frame3f.cos_theta(si.wi) > 0) & (cos_o > 0)
        return dr.select(ok, self._albedo(si, ok) * dr.inv_pi * cos_o, 0.0)

    def pdf(self, ctx, si, wo, active=True):
        ok = active & (mi.Frame3f.cos_theta(si.wi) > 0) & (mi.Frame3f.cos_theta(wo) > 0)
        return dr.select(ok, mi.warp.square_to_cosine_hemisphere_pdf(wo), 0.0)

    def eval_pdf(self, ctx, si, wo, active=True):
        return self.eval(ctx, si, wo, active), self.pdf(ctx, si, wo, active)

    def eval_diffuse_reflectance(self, si, active=True):
        return self._albedo(si, active)

    def traverse(self, cb):
        for name in CHANNELS:
            texture = getattr(self, name)
            if texture is not None:
                cb.put(name, texture, mi.ParamFlags.Differentiable)
        cb.put("shininess", self.shininess, mi.ParamFlags.Differentiable)

    def parameters_changed(self, keys=[]):
        """Check ``shininess`` as an edit left it: refused (and the last valid value put
        back) unless positive and finite."""
        if dr.is_jit_v(mi.Float):   # opaque first: reading an evaluated value launches nothing
            dr.make_opaque(self.shininess)
        try:
            _check_shininess(first_number(self.shininess))
        except ValueError:
            if hasattr(self, "_last_shininess"):
                mi.set_property(self.shininess, self._last_shininess.value)
            raise
        self._last_shininess = Kept(type(self.shininess)(self.shininess))
        if dr.is_jit_v(mi.Float):   # the kernel reads the traversed value itself, opaque
            self.exponent = self.shininess
        else:                       # the scalar variant computes on a Python float
            self.exponent = first_number(self.shininess)

    def recording_key(self) -> tuple:
        """Its channels' keys (see ``Marble.recording_key``): which are present, and
        what each traces."""
        return ("channel_material",) + tuple(recording_key(getattr(self, name))
                                             for name in CHANNELS)

    def to_string(self):
        fields = {name: getattr(self, name) for name in CHANNELS if self.has_channel(name)}
        fields["shininess"] = first_number(self.shininess)
        return describe("ChannelMaterial", fields)


def _check_shininess(shininess) -> None:
    if isinstance(shininess, bool) or not isinstance(shininess, (int, float)) \
            or not 0 < shininess < float("inf"):
        raise ValueError(f"channel_material: shininess={shininess!r} must be a positive number")
