"""docs/presets.md: every preset of the marble library on a sphere and a slab.

    ./go python scripts/preset_gallery.py            # renders docs/presets/NAME.png, rewrites the page's table
    ./go python scripts/preset_gallery.py --page     # rewrites the page's table only (no renders)
    ./go python scripts/preset_gallery.py --check    # exit 1 if the page's table is not what the library says

Each image is two whitted renders side by side, each SIZE² pixels at 4 samples a pixel: a
unit sphere and a 3 × 0.2 × 2 slab, both shaded by ``marble { preset "NAME" }`` (ambient
and diffuse, a grey specular), one point light. The page's table (between its markers) is
written from mimarble/presets.toml: name, title, what the stone is, where its colours come
from, and the values (``mimarble presets NAME``); tests/test_presets.py runs the check.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from module_map import with_section, write_or_check  # noqa: E402  (a script beside this one)

from mimarble import presets  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs" / "presets.md"
IMAGES = ROOT / "docs" / "presets"
BEGIN = "<!-- presets table: written by scripts/preset_gallery.py from mimarble/presets.toml; do not edit -->"
END = "<!-- end of the presets table -->"
#: Each view's side in pixels.
SIZE = 128

#: The two views: the camera and the shape, in the scene language.
VIEWS = {
    "sphere": ("camera { eye < 0 1.2 4.3 > lookat < 0 0 0 > up < 0 1 0 > fov 30 }",
               "sphere { center < 0 0 0 > radius 1 material \"stone\" }"),
    "slab": ("camera { eye < 0 3.4 3.2 > lookat < 0 -0.1 0 > up < 0 1 0 > fov 42 }",
             "box { min < -1.5 -0.1 -1 > max < 1.5 0.1 1 > material \"stone\" }"),
}


def scene_text(name: str, view: str, size: int = SIZE, samples: int = 4) -> str:
    """A small scene of preset ``name`` on the ``view`` ("sphere" or "slab")."""
    camera, shape = VIEWS[view]
    return f"""// Preset "{name}" on a {view} (scripts/preset_gallery.py).
image    {{ width {size} height {size} samples {samples} background < 0.08 0.08 0.09 > }}
{camera}
ambient  < 0.25 0.25 0.25 >
light    {{ position < -4 6 6 > color < 0.9 0.9 0.9 > }}
texture "marble" {{ marble {{ preset "{name}" }} }}
material "stone" {{
  ambient  {{ texture "marble" }}
  diffuse  {{ texture "marble" }}
  specular {{ color < 0.25 0.25 0.25 > }}
  shininess 40
}}
{shape}
"""


def page_table() -> str:
    """The page's body between its markers: one section a preset."""
    parts = []
    for name, p in presets.presets().items():
        parts.append(f"### `{name}` — {p.title}\n\n"
                     f"![{p.title} on a sphere and a slab](presets/{name}.png)\n\n"
                     f"{p.about}\n\n"
                     f"*Colours:* {p.colours}\n\n"
                     f"    marble {{ preset \"{name}\" }}   // = marble {{ "
                     f"{presets.block_text(p)} }}\n")
    return "\n".join(parts)


def render_images(names=None) -> None:
    """Render each preset's two views and write docs/presets/NAME.png (sphere | slab)."""
    import numpy as np

    import mimarble
    from mimarble.mitsuba import write_image
    IMAGES.mkdir(exist_ok=True)
    for name in names or presets.presets():
        views = [mimarble.render(mimarble.scene.parse(scene_text(name, view), f"{name}.scene"))
                 for view in VIEWS]
        write_image(IMAGES / f"{name}.png", np.concatenate(views, axis=1))
        print(f"wrote {(IMAGES / f'{name}.png').relative_to(ROOT)}")


def main(argv) -> int:
    new = with_section(DOCS.read_text(encoding="utf-8"), page_table(), BEGIN, END)
    if "--check" not in argv[1:] and "--page" not in argv[1:]:
        render_images()
    return write_or_check(DOCS, new, [a for a in argv if a != "--page"], "the presets table")


if __name__ == "__main__":
    sys.exit(main(sys.argv))
