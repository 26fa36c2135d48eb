"""``mimarble export``: a scene as a Mitsuba 3 XML file, or as a Python file that builds the
dict, either of which Mitsuba loads into the scene ``mi.load_dict(to_mitsuba(scene))`` makes.

Both writers work on the Mitsuba scene dict (:func:`mimarble.mitsuba.translate.scene_dict.to_mitsuba`),
not on the scene model: whatever the translator puts in the dict (new shapes included) is
written, value by value, as what ``mi.load_dict`` makes of it.

Why not Mitsuba's own writer (``mi.parser.parse_dict`` then ``mi.parser.write_string``, in
Mitsuba 3.9's src/core/parser.cpp): it names each element by the plugin's registered type,
which Mitsuba knows only for its C++ plugins (``PluginManager::plugin_type`` answers
``Unknown`` for Python ones, and the writer stops: "Cannot determine XML tag name for node
with unknown object type and plugin name "whitted""); and it rewrites every transform
as scale/rotate/translate or, for a sensor, as a ``lookat`` recomputed from the matrix,
which changes its float32 entries (by 1.2e-7 for a camera, measured). So this module
writes the XML itself:

* **Elements.** A nested dict ``{"type": T, …}`` is an element whose tag is the kind of
  plugin T: mimarble's own plugins by their declared kind (mimarble/mitsuba/plugins/registration.py: texture,
  bsdf, integrator, emitter), Mitsuba's by ``mi.PluginManager.plugin_type``. Top-level
  entries carry ``id`` = their key (so ``{"type": "ref", "id": "texture_0"}``, written
  ``<ref name=… id="texture_0"/>``, finds the shared texture, and the shapes keep their
  ids, as ``load_dict`` gives them) and ``name`` = their key; nested ones ``name`` only.
  The dict's order is kept: a scene's emitters are summed in that order, and a texture is
  declared before what refers to it.
* **Values**, each as the XML element that makes the property type ``load_dict`` makes
  (Mitsuba's ``Properties.__setitem__``): bool ``<boolean>``, int ``<integer>``, float
  ``<float>`` written as ``repr`` (the shortest decimal that reads back as the same double;
  Mitsuba parses with fast_float, correctly rounded), str ``<string>``, a sequence of three
  numbers ``<vector>``, ``{"type": "rgb"}`` ``<rgb>``, ``{"type": "spectrum"}``
  ``<spectrum>``, a transform ``<transform><matrix value="16 numbers"/></transform>`` (its
  float32 entries, exactly).
* **Strings** are data: ``& < > "`` and tab, newline, carriage return are written as
  character references, and every ``$`` as ``\\$`` (Mitsuba substitutes ``$name``
  parameters in every attribute and removes the backslash of ``\\$``). A character XML 1.0
  cannot hold at all (U+0000–U+001F but those three, U+FFFE, U+FFFF, a lone surrogate) is
  refused.
* **File names** (a ``filename`` value): ``mi.load_file`` looks a relative name up in the
  XML file's own folder first (src/core/python/parser.cpp, ``load_file``). A file in the
  XML's folder or below it is written relative to it, so the folder moves as a whole; any
  other, absolute. The Python file writes them as ``os.path.join(HERE, …)`` and absolute
  names alike, ``HERE`` being its own folder.

What XML cannot say: a transform's inverse. ``mi.ScalarTransform4f`` carries the inverse it
was made with; an XML ``<matrix>`` is inverted in double precision, then rounded to float32
when the plugin reads it. The translator gives the transforms that are read through their
inverse (a ``disk``'s, a mesh's, an object-space marble's: mimarble/mitsuba/translate/shapes.py,
``_transform``) exactly that inverse, and the sensor, the sphere and the marble read none,
so every shipped scene renders from its XML as from its dict, bit for bit (tested); a dict
made elsewhere may differ in the last bit (:func:`xml_transform` makes what XML would). The
Python file writes both, ``mi.ScalarTransform4f(matrix, inverse_transpose)``, and renders as the dict, bit for bit.

Neither file holds a Mitsuba object given by value (a loaded ``mi.Bitmap``, a mesh built
in memory): the translator writes file names, and such a value is refused
(:class:`ExportError`, one sentence).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

#: The version attribute of the XML's ``<scene>``: Mitsuba 3's scene format.
XML_VERSION = "3.0.0"

#: The suffixes ``mimarble export`` writes: Mitsuba XML, or (``--python``) a Python file.
XML_SUFFIXES = (".xml",)
PYTHON_SUFFIXES = (".py",)

#: The modules an exported Python file imports by name (``mimarble``, ``mitsuba``) and the
#: packages ``import mimarble`` loads before Mitsuba (``drjit``, ``numpy``). Python puts a
#: script's own folder first on its path, so a file ``NAME.py`` there is imported in
#: their place — by that script and by every other one in the folder:
#: ``export --python`` refuses to write one (:func:`script_name_problem`).
SCRIPT_IMPORTS = ("mimarble", "mitsuba", "drjit", "numpy")

#: Mitsuba's object types (``mi.ObjectType``) by their XML tags (src/core/parser.cpp,
#: ``interpret_tag``).
_TAGS = {"Scene": "scene", "Sensor": "sensor", "Film": "film", "Emitter": "emitter",
         "Sampler": "sampler", "Shape": "shape", "Texture": "texture", "Volume": "volume",
         "Medium": "medium", "BSDF": "bsdf", "Integrator": "integrator",
         "PhaseFunction": "phase", "ReconstructionFilter": "rfilter"}

#: Dicts that are property values, not plugins (``load_dict`` reads them so).
_VALUE_TYPES = ("ref", "rgb", "spectrum")


class ExportError(ValueError):
    """A value of the scene dict that neither file can hold, in one sentence."""


def script_name_problem(path) -> str | None:
    """Why a Python file may not be written at ``path`` (None: it may): its name would
    shadow one of :data:`SCRIPT_IMPORTS` for every script in its folder."""
    stem = Path(path).stem
    if Path(path).suffix in PYTHON_SUFFIXES and stem in SCRIPT_IMPORTS:
        return (f"a Python file named {stem}.py would be imported in place of the {stem} "
                f"module by every script in its folder (this one too: it imports "
                f"{' and '.join(SCRIPT_IMPORTS[:2])}); name it otherwise")
    return None


def plugin_tag(plugin_name: str) -> str:
    """The XML tag of plugin ``plugin_name``: a mimarble plugin's declared kind (whose
    names are the tags), else Mitsuba's registered type of it; ExportError for neither."""
    from mimarble.mitsuba.plugins import registration as plugins
    for kind, name, _ in plugins.declared_plugins:      # (kind, name, class) of every declared one
        if name == plugin_name:
            return kind
    import mitsuba as mi
    kind = mi.PluginManager.instance().plugin_type(plugin_name)
    tag = _TAGS.get(kind.name)
    if tag is None:
        raise ExportError(f"cannot export plugin {plugin_name!r:.60}: neither mimarble nor "
                         f"Mitsuba knows it")
    return tag


# ---------------------------------------------------------------------------
# Values


def _number(value) -> float | int | bool | None:
    """``value`` as a Python bool, int or float if it is a number (NumPy's too), else None."""
    if isinstance(value, (bool, int, float)):
        return value
    kind = getattr(getattr(value, "dtype", None), "kind", None)
    if kind is not None and getattr(value, "shape", None) == ():
        return value.item() if kind in "biuf" else None
    return None


def _float_text(x: float) -> str:
    """The shortest decimal that reads back as the same double (``inf``, ``nan`` too:
    fast_float reads them)."""
    return repr(float(x))


def _transform_matrices(value):
    """(matrix, inverse transpose) of a Mitsuba transform, as 4×4 lists of Python floats
    (each float32 entry exactly), or None if ``value`` is not one."""
    if not (hasattr(value, "matrix") and hasattr(value, "inverse_transpose")):
        return None

    def rows(m):
        return [[float(m[i][j]) for j in range(4)] for i in range(4)]
    return rows(value.matrix), rows(value.inverse_transpose)


def xml_transform(matrix):
    """The float32 transform Mitsuba's XML parser makes of ``<matrix value="…"/>`` with the
    float32 entries of ``matrix`` (4×4 rows, or a transform): the entries, and the inverse
    of them computed in double precision (``ScalarAffineTransform4d``, src/core/parser.cpp)
    and rounded to float32 (``Properties`` converting it for the plugin). A dict holding
    such transforms renders from its XML bit for bit (module docstring)."""
    import mitsuba as mi
    matrices = _transform_matrices(matrix)
    rows = matrices[0] if matrices is not None else [list(map(float, row)) for row in matrix]
    single = mi.ScalarMatrix4f(rows)
    double = mi.ScalarTransform4d(mi.ScalarMatrix4d(single))
    return mi.ScalarTransform4f(single, mi.ScalarMatrix4f(double.inverse_transpose))


def _triple(value, what: str) -> list | None:
    """A sequence of three numbers as a list of floats (ints stay ints), else None."""
    if isinstance(value, (str, bytes, dict)) or not hasattr(value, "__len__"):
        return None
    try:
        items = [_number(v) for v in value]
    except TypeError:
        return None
    if len(items) != 3 or any(v is None or isinstance(v, bool) for v in items):
        return None
    return items


def _refuse(key: str, value) -> ExportError:
    return ExportError(f"cannot export {key!r:.60}: a {type(value).__name__} value has no "
                     f"XML or Python literal form (give the dict a file name instead)")


# ---------------------------------------------------------------------------
# File names

def _file_name(value: str, folder: Path) -> tuple[bool, str]:
    """(relative?, name) for a file the dict names: relative to ``folder`` when the file
    lies in it or below it, else absolute. A relative name in the dict is the working
    directory's (where ``mi.load_dict`` looks it up)."""
    absolute = os.path.abspath(value)
    base = os.path.abspath(folder)
    try:
        inside = os.path.commonpath([absolute, base]) == base
    except ValueError:              # another drive (Windows)
        inside = False
    if inside and absolute != base:
        return True, os.path.relpath(absolute, base)
    return False, absolute


# ---------------------------------------------------------------------------
# XML

_XML_REFERENCES = {"&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;",
                   "\t": "&#9;", "\n": "&#10;", "\r": "&#13;", "$": "\\$"}


def _xml_text(text: str, key: str) -> str:
    """``text`` as the inside of a double-quoted XML attribute that Mitsuba reads back as
    ``text`` (module docstring, "Strings")."""
    for c in text:
        code = ord(c)
        if (code < 0x20 and c not in "\t\n\r") or 0xD800 <= code <= 0xDFFF \
                or code in (0xFFFE, 0xFFFF):
            raise ExportError(f"cannot export {key!r:.60}: its value holds the character "
                             f"U+{code:04X}, which XML cannot hold")
    return "".join(_XML_REFERENCES.get(c, c) for c in text)


class _XML:
    def __init__(self, folder: Path):
        self.folder = folder
        self.lines: list[str] = []

    def attributes(self, pairs, key) -> str:
        return "".join(f' {name}="{_xml_text(str(value), key)}"' for name, value in pairs)

    def element(self, depth: int, tag: str, pairs, key: str, children=None) -> None:
        indent = "    " * depth
        head = f"{indent}<{tag}{self.attributes(pairs, key)}"
        if children is None:
            self.lines.append(head + "/>")
            return
        start = len(self.lines)
        children()
        if len(self.lines) == start:             # no properties: <rfilter type="box"/>
            self.lines.append(head + "/>")
            return
        self.lines.insert(start, head + ">")
        self.lines.append(f"{indent}</{tag}>")

    def plugin(self, depth: int, key: str | None, value: dict, top: bool) -> None:
        plugin_name = value["type"]
        pairs = [("type", plugin_name)]
        if top:
            pairs.append(("id", value.get("id", key)))
        elif "id" in value:
            pairs.append(("id", value["id"]))
        if key is not None:
            pairs.append(("name", key))
        self.element(depth, plugin_tag(plugin_name), pairs, key or plugin_name,
                     lambda: self.properties(depth + 1, value, top=plugin_name == "scene"))

    def properties(self, depth: int, values: dict, top: bool) -> None:
        for key, value in values.items():
            if key in ("type", "id"):
                continue
            if not isinstance(key, str):
                raise ExportError(f"cannot export the key {key!r:.60}: keys are strings")
            self.value(depth, key, value, top)

    def value(self, depth: int, key: str, value, top: bool) -> None:
        number = _number(value)
        if isinstance(number, bool):
            self.element(depth, "boolean", [("name", key), ("value", str(number).lower())], key)
        elif isinstance(number, int):
            self.element(depth, "integer", [("name", key), ("value", str(number))], key)
        elif isinstance(number, float):
            self.element(depth, "float", [("name", key), ("value", _float_text(number))], key)
        elif isinstance(value, (str, os.PathLike)):
            text = os.fspath(value)
            if key == "filename":
                text = _file_name(text, self.folder)[1]
            self.element(depth, "string", [("name", key), ("value", text)], key)
        elif isinstance(value, dict):
            self.dict_value(depth, key, value, top)
        elif (matrices := _transform_matrices(value)) is not None:
            numbers = " ".join(_float_text(x) for row in matrices[0] for x in row)
            self.element(depth, "transform", [("name", key)], key, lambda: self.element(
                depth + 1, "matrix", [("value", numbers)], key))
        elif (triple := _triple(value, key)) is not None:
            self.element(depth, "vector", [("name", key)] + [
                (axis, _float_text(v)) for axis, v in zip("xyz", triple)], key)
        else:
            raise _refuse(key, value)

    def dict_value(self, depth: int, key: str, value: dict, top: bool) -> None:
        kind = value.get("type")
        if not isinstance(kind, str):
            raise ExportError(f"cannot export {key!r:.60}: a nested dict needs a 'type'")
        if kind == "ref":
            self.element(depth, "ref", [("name", key), ("id", value["id"])], key)
        elif kind == "rgb":
            rgb = value["value"]
            rgb = [rgb] if _number(rgb) is not None else _triple(rgb, key)
            if rgb is None:
                raise _refuse(key, value["value"])
            self.element(depth, "rgb", [("name", key), ("value", " ".join(
                _float_text(v) for v in rgb))], key)
        elif kind == "spectrum":
            self.element(depth, "spectrum", [("name", key)] + _spectrum_pairs(value, key, self),
                         key)
        else:
            self.plugin(depth, key, value, top)


def _spectrum_pairs(value: dict, key: str, xml: _XML) -> list:
    if "filename" in value:
        return [("filename", _file_name(os.fspath(value["filename"]), xml.folder)[1])]
    data = value["value"]
    if _number(data) is not None:
        return [("value", _float_text(data))]
    return [("value", ", ".join(f"{_float_text(w)}:{_float_text(v)}" for w, v in data))]


def _check_own_keys(scene_dict: dict) -> None:
    """Refuse a plugin under a key ``load_dict`` reads as the dict's own (``type``,
    ``id``: translate.LOAD_DICT_KEYS): Mitsuba would take it for the scene's id ("std::
    bad_cast"), and neither file could say it."""
    from mimarble.mitsuba.translate.scene_dict import LOAD_DICT_KEYS
    for key in LOAD_DICT_KEYS:
        if isinstance(scene_dict.get(key), dict):
            raise ExportError(f"cannot export the plugin under the key {key!r}: mi.load_dict "
                              f"reads a dict's {key!r} as its own, not as a child; give the "
                              f"plugin another key")


def to_xml(scene_dict: dict, folder=".") -> str:
    """The Mitsuba XML of a scene dict (module docstring), for a file in ``folder``
    (where its relative file names start)."""
    if not isinstance(scene_dict, dict) or scene_dict.get("type", "scene") != "scene":
        raise TypeError("to_xml: expected a Mitsuba scene dict ({'type': 'scene', …})")
    _check_own_keys(scene_dict)
    xml = _XML(Path(folder))
    xml.lines.append(f'<scene version="{XML_VERSION}">')
    for key, value in scene_dict.items():
        if key in ("type", "id"):
            continue
        if isinstance(value, dict) and value.get("type") not in _VALUE_TYPES:
            xml.plugin(1, key, value, top=True)
        else:
            xml.value(1, key, value, top=True)
    xml.lines.append("</scene>")
    return "\n".join(xml.lines) + "\n"


# ---------------------------------------------------------------------------
# Python

def _py_float(x: float) -> str:
    x = float(x)
    return repr(x) if math.isfinite(x) else f"float({repr(x)!r})"


def _py_rows(rows) -> str:
    return "[" + ", ".join("[" + ", ".join(_py_float(x) for x in row) + "]" for row in rows) + "]"


class _Python:
    def __init__(self, folder: Path):
        self.folder = folder

    def literal(self, key: str, value, depth: int) -> str:
        number = _number(value)
        if number is not None:
            return _py_float(number) if isinstance(number, float) else repr(number)
        if isinstance(value, (str, os.PathLike)):
            text = os.fspath(value)
            if key == "filename":
                relative, text = _file_name(text, self.folder)
                if relative:
                    return f"os.path.join(HERE, {text!r})"
            return repr(text)
        if isinstance(value, dict):
            indent = "    " * (depth + 1)
            items = []
            for k, v in value.items():
                if not isinstance(k, str):
                    raise ExportError(f"cannot export the key {k!r:.60}: keys are strings")
                items.append(f"{indent}{k!r}: {self.literal(k, v, depth + 1)},")
            return "{\n" + "\n".join(items) + "\n" + "    " * depth + "}"
        if (matrices := _transform_matrices(value)) is not None:
            matrix, inverse_transpose = matrices
            return (f"mi.ScalarTransform4f(mi.ScalarMatrix4f({_py_rows(matrix)}),\n"
                    f"{'    ' * (depth + 1)}mi.ScalarMatrix4f({_py_rows(inverse_transpose)}))")
        if isinstance(value, (list, tuple)):
            items = [self.literal(key, v, depth + 1) for v in value]
            return "[" + ", ".join(items) + "]"
        raise _refuse(key, value)


def to_python(scene_dict: dict, variant: str, folder=".", command: str | None = None) -> str:
    """A Python file that builds ``scene_dict`` as ``scene`` (module docstring) in
    ``variant``, for a file in ``folder``; run as a script it renders the scene to the
    EXR named by its argument (default: its own name with .exr). ``command``, the command
    line that wrote it, is kept as a string constant (any characters are safe there)."""
    if not isinstance(scene_dict, dict):
        raise TypeError("to_python: expected a Mitsuba scene dict")
    _check_own_keys(scene_dict)
    body = _Python(Path(folder)).literal("scene", scene_dict, 0)
    return (f'"""A mimarble scene as a Mitsuba 3 scene dict, written by ``mimarble export``\n'
            f"(the command: ``COMMAND``).\n\n"
            f"``scene`` is what ``mimarble.to_mitsuba`` made of it: ``mi.load_dict(scene)``\n"
            f"loads it (mimarble must be importable: ``import mimarble`` registers its\n"
            f"plugins).\n"
            f"Run as a script, it renders the scene to the linear EXR named by its argument\n"
            f'(default: this file\'s name with .exr).\n"""\n\n'
            f"import os\nimport sys\n\n"
            f"import mimarble  # first: it picks a libLLVM, then registers its plugins\n"
            f"import mitsuba as mi\n\n"
            f"mi.set_variant({variant!r})\n\n"
            f"COMMAND = {command or 'mimarble export'!r}\n"
            f"HERE = os.path.dirname(os.path.abspath(__file__))\n\n"
            f"scene = {body}\n\n\n"
            f'if __name__ == "__main__":\n'
            f"    out = sys.argv[1] if len(sys.argv) > 1 else \\\n"
            f"        os.path.splitext(__file__)[0] + '.exr'\n"
            f"    mi.Bitmap(mi.render(mi.load_dict(scene))).write(out)\n"
            f"    print(out)\n")


# ---------------------------------------------------------------------------
# The command's work

def export(scene, path, mode: str = "whitted", spp: int | None = None, python: bool = False,
           command: str | None = None) -> str:
    """Write ``to_mitsuba(scene, mode, spp)`` to ``path`` as XML (or ``python``: a Python
    file), whole or not at all (mimarble/runtime/files.py); returns the text written. ``command``:
    the command line, kept in the Python file (``COMMAND``). ExportError, before anything
    is written, for a name no writer takes (``files.output_name_problem``) or a Python
    file that would shadow a module it imports (:func:`script_name_problem`)."""
    import mitsuba as mi

    from mimarble.runtime.files import output_name_problem, write_atomically
    from mimarble.mitsuba.translate.scene_dict import to_mitsuba
    problem = output_name_problem(path) or (script_name_problem(path) if python else None)
    if problem:
        raise ExportError(f"{os.fspath(path)!r}: {problem}")
    path = Path(path)
    scene_dict = to_mitsuba(scene, mode, spp)
    folder = path.parent
    text = to_python(scene_dict, mi.variant(), folder, command) if python \
        else to_xml(scene_dict, folder)
    write_atomically(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))
    return text
