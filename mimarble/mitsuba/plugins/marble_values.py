"""What the host holds of a marble's traversed values: told, read, checked, put back.

A marble's parameters are edited in place through ``mi.traverse``. The host knows an
edited value when it is a literal (a Python number), or was told it (:meth:`hold`);
otherwise it is on the device, and the rules the host cannot check there are checked in
the kernel (:meth:`HeldValues._kernel_check`: NaN everywhere while one is broken).
:class:`HeldValues` is that bookkeeping, the base of the texture's update path
(mimarble/mitsuba/plugins/marble_update.py), which decides from the values what the texture
evaluates.
"""

from __future__ import annotations

import numpy as np

from mimarble.runtime import environment
from mimarble.parameters import (BY_NAME, COLOURS, INTEGER, MAX_LACUNARITY, POSITIONS,
    ParameterError, checked, parse_positions, parse_ramp, ramp_count_problem)
from mimarble.mitsuba.plugins.registration import Kept, first_number, transform_matrix
from mimarble.texture.ramp import positions_storage, ramp_storage

dr, mi = environment.import_drjit_and_mitsuba()


class HeldValues:
    """The host's view of a texture's traversed values (``editable``, ``ramp``,
    ``mapping``): what it holds of each, checked with the table's rules."""

    def hold(self, name: str, value) -> None:
        """Tell the texture the value of traversed ``name`` that was just written through
        ``mi.traverse`` (call it after writing, before ``params.update()``), as the host
        holds it: a number, the ramp's colours (RGB triples or its string), the positions,
        to_world (a transform or a 4×4 matrix). A value written as a Dr.Jit array (a ramp's
        ``Color3f``, positions) is never a literal, so without this it counts as on the
        device and decisions that need it take the value-independent choice (every octave);
        told, it is taken as the host's, as a fresh load takes it: the same bits as a
        texture loaded with that value. Remembered with the Dr.Jit variable now in place,
        so a later edit of the same key (a new variable) is not taken for it. Only a value
        the host truly holds; it is checked at the update as a literal edit is. (The
        loaded-scene cache tells each value it writes, mimarble/mitsuba/rendering/loaded_scenes.py.)"""
        if name not in self.editable:
            raise ParameterError(f"marble: {name!r} is not a traversed parameter "
                                 f"({', '.join(self.editable)})")
        if not dr.is_jit_v(mi.Float):    # the scalar variant reads every value anyway
            return
        if name == "to_world":
            matrix = transform_matrix(value) if hasattr(value, "matrix") else value
            host = np.array(matrix, dtype=np.float64).reshape(4, 4)
        elif BY_NAME[name].kind == COLOURS:
            host = parse_ramp(value, name)
        elif BY_NAME[name].kind == POSITIONS:
            host = parse_positions(value, name)
        else:
            host = value if isinstance(value, (bool, int, float)) else float(value)
        # Until the update: should it refuse the value, the last valid one put back is
        # still the one told of before.
        self._pending.value[name] = _told(self.editable[name], host)


    def _take_edit(self, keys: set) -> dict:
        """The values after an edit of ``keys``, as the host holds them (None: on the
        device), checked; an invalid one raises and puts the last valid values back."""
        jit = dr.is_jit_v(mi.Float)
        held = dict(self._held.value)
        for name in keys & set(self.editable):
            held[name] = self._host_value(name)
        if jit:
            # Opaque, next: a new value reuses the compiled kernel, a recording of it
            # (dr.freeze) takes every one as an input, copies too.
            dr.make_opaque(*self.editable.values())
        try:
            for name in keys:
                if held.get(name) is not None and name in BY_NAME:
                    held[name] = checked(BY_NAME[name], held[name])
            self._check_counts()
            if held["to_world"] is not None:
                self.mapping.check(held["to_world"])
        except ParameterError:
            self._pending = Kept({})
            for name, value in getattr(self, "_last_valid", Kept({})).value.items():
                # In place: mi.traverse holds these very objects.
                mi.set_property(self.editable[name], value)
            raise
        self._last_valid = Kept({name: type(value)(value) for name, value in self.editable.items()})
        self._held = Kept(held)
        if jit:
            # What the host holds, by the variable now in place (make_opaque gave a literal
            # edit a new one): read again at a later update that names the key (a full
            # update names every key) while that variable stays; none for a value on the
            # device. A key not named keeps its entry: its variable is as it was.
            told = dict(self._told.value)
            for name in (keys or set(self.editable)) & set(self.editable):
                if held.get(name) is not None:
                    told[name] = _told(self.editable[name], held[name])
                else:
                    told.pop(name, None)
            self._told, self._pending = Kept(told), Kept({})
        return held

    def _host_value(self, name):
        """The value of traversed ``name`` as the table holds it, if the host holds it —
        told (:meth:`hold`, or held since it was read or loaded) for the very variable in
        place, or a literal — or it is structural (read: it decides the kernel); else None."""
        value = self.editable[name]
        if dr.is_jit_v(mi.Float):
            for told in (self._pending.value.get(name), self._told.value.get(name)):
                if told is not None and told[0] == _indices(value):
                    return told[2]
            if name != "octaves" and not _literal(value):
                return None
        if name == "to_world":
            return host_matrix(value)
        parameter = BY_NAME[name]
        if parameter.kind == COLOURS:
            return tuple(map(tuple, self.ramp.numpy().tolist()))
        if parameter.kind == POSITIONS:
            return tuple(self.ramp.positions_numpy().tolist())
        number = first_number(value)
        return int(number) if parameter.kind == INTEGER and number.is_integer() else number

    def _check_counts(self) -> None:
        """The rules the host checks on every edit, from the arrays' widths (never a
        read): the ramp's number of colours, one position for each."""
        lo, hi = BY_NAME["ramp"].bounds
        count = dr.width(self.editable["ramp"]) if dr.is_jit_v(mi.Float) \
            else len(self.ramp.numpy())
        if not lo <= count <= hi:
            raise ParameterError(f"marble: ramp has {count} colours; it holds {lo}..{hi}")
        if "ramp_positions" in self.editable:
            positions = dr.width(self.editable["ramp_positions"]) \
                if dr.is_jit_v(mi.Float) else len(self.ramp.positions_numpy())
            problem = ramp_count_problem(range(count), range(positions))
            if problem:
                raise ParameterError(f"marble: {problem}")

    def _kernel_check(self, on_device: set):
        """The table's rules for the values on the device, as one opaque Dr.Jit Bool the
        kernel reads (True when the host checked every value: the same kernel either way,
        so that a first edit on the device compiles nothing new): scale > 0, period and
        distortion finite, 0 < gain < 1, 1 < lacunarity ≤ MAX_LACUNARITY, every ramp
        component finite, positions in [0, 1] and non-decreasing, to_world finite and
        invertible (as texture_mapping.check_invertible). Its reductions run on the
        device; nothing is read back."""
        e = {name: dr.detach(value) for name, value in self.editable.items()}
        rules = []
        if "scale" in on_device:
            rules.append((e["scale"] > 0.0) & dr.isfinite(e["scale"]))
        for name in ("period", "distortion"):
            if name in on_device:
                rules.append(dr.isfinite(e[name]))
        if "gain" in on_device:
            rules.append((e["gain"] > 0.0) & (e["gain"] < 1.0))
        if "lacunarity" in on_device:
            rules.append((e["lacunarity"] > 1.0) & (e["lacunarity"] <= MAX_LACUNARITY))
        if "ramp" in on_device:
            c = e["ramp"]
            rules.append(dr.all(dr.isfinite(c[0]) & dr.isfinite(c[1]) & dr.isfinite(c[2])))
        if "ramp_positions" in on_device:
            p = e["ramp_positions"]
            rules.append(dr.all((p >= 0.0) & (p <= 1.0)))
            if dr.width(p) > 1:
                k = dr.arange(mi.UInt32, dr.width(p) - 1)
                rules.append(dr.all(dr.gather(mi.Float, p, k + 1) >= dr.gather(mi.Float, p, k)))
        if "to_world" in on_device:
            m = e["to_world"].matrix
            finite = mi.Bool(True)
            for i in range(4):
                for j in range(4):
                    finite &= dr.isfinite(m[i][j])
            linear = mi.Matrix3f(*(m[i][j] for i in range(3) for j in range(3)))
            largest = dr.max(dr.abs(mi.Vector3f(*(dr.max(dr.abs(mi.Vector3f(
                m[i][0], m[i][1], m[i][2]))) for i in range(3)))))
            rules.append(finite & (largest > 0.0)
                         & (dr.abs(dr.det(linear)) > dr.power(1e-6 * largest, 3)))
        valid = mi.Bool(True)
        for rule in rules:
            valid = valid & rule
        dr.make_opaque(valid)
        return valid

    def check_values(self) -> None:
        """Every traversed value checked on the host with the table's rules, reading back
        those on the device (a wait): ParameterError naming the first broken rule, as an
        edit the host holds gets at ``params.update()``. Nothing is changed."""
        for name in self.editable:
            if name in BY_NAME:
                value = self._read_back(BY_NAME[name])
                checked(BY_NAME[name], value)
        self._check_counts()
        if "ramp_positions" in self.editable:
            problem = ramp_count_problem(self.ramp.numpy(), self.ramp.positions_numpy())
            if problem:
                raise ParameterError(f"marble: {problem}")
        self.mapping.check(host_matrix(self.mapping.to_world, read=True))

    def _read_back(self, parameter):
        """A traversed parameter's value as the table holds it, read back now."""
        value = self.editable[parameter.name]
        if parameter.kind == COLOURS:
            return self.ramp.numpy()
        if parameter.kind == POSITIONS:
            return tuple(self.ramp.positions_numpy().tolist())
        number = first_number(value)
        return int(number) if parameter.kind == INTEGER and number.is_integer() else number


def _literal(value) -> bool:
    """Whether every component of a JIT value is a literal: a number the host holds (a
    Python number set through ``mi.traverse`` is one), read without waiting."""
    if isinstance(value, (mi.Transform4f, mi.ScalarTransform4f)) or hasattr(value, "matrix"):
        value = value.matrix
    if dr.depth_v(value) > 1:
        return all(_literal(value[k]) for k in range(len(value)))
    return value.state == dr.VarState.Literal


def _indices(value) -> tuple:
    """The Dr.Jit variables (JIT and AD indices) a traversed value is made of."""
    return tuple(dr.detail.collect_indices(value))


def _told(value, host) -> tuple:
    """(the variables of ``value``, a copy of it holding them — so none is freed and its
    index reused by another value while this is kept —, the ``host`` value)."""
    return _indices(value), type(value)(value), host


def host_matrix(transform, read: bool = False) -> np.ndarray | None:
    """``transform``'s 4×4 matrix as float64, if its entries are literals (read without
    waiting) or ``read``; else None (on the device)."""
    if dr.is_jit_v(mi.Float) and not read and not _literal(transform):
        return None
    return transform_matrix(transform) if read or not dr.is_jit_v(mi.Float) else \
        np.array([[transform.matrix[i][j][0] for j in range(4)] for i in range(4)],
                 dtype=np.float64)


def editable_storage(parameter, value):
    """A traversed parameter's value in a container Mitsuba can write into in every
    variant: ``mi.Float`` in JIT variants; in scalar_rgb, where mi.Float is a Python
    float, a one-element ``ArrayXf``; the ramp's own (mimarble/texture/ramp.py). An integer is
    held as a float too, so that an edit to 2.5 is seen and refused, not truncated."""
    if parameter.kind == COLOURS:
        return ramp_storage(value)
    if parameter.kind == POSITIONS:
        return positions_storage(value)
    return mi.Float(value) if dr.is_jit_v(mi.Float) else dr.scalar.ArrayXf([value])

