"""POV-Ray 3.7, the peer a user would otherwise pick, timed on a comparable marble sphere.

:func:`scene_text` writes a paper scene in POV-Ray's language (spheres only: planes,
boxes, meshes and object-space marbles are refused in one sentence): the same spheres,
camera, point lights and ambient light, each material's first marble channel as
POV-Ray's ``marble`` pattern and the ramp as its ``color_map``, the paper's Phong
channels as ``finish { ambient diffuse specular roughness }``. It is comparable,
not identical: POV-Ray's marble is a triangle wave in x with its own turbulence
(``turbulence`` = distortion/period, ``octaves``, ``omega`` = gain, ``lambda`` =
lacunarity; ``ramp_wave`` for ``sawtooth``; the pattern's transform after its scale),
not |sin(π(period·x + distortion·F))|. POV-Ray is left-handed: z is mirrored.

:func:`time_povray` runs ``povray`` (no anti-aliasing, no display, all cores) and
reports its own "Trace Time" and the whole process, medians of ``repeats`` runs;
None when POV-Ray is not installed (Debian: ``apt-get install povray``).
"""

from __future__ import annotations

import re
import shutil
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

from mimarble.scene import model
from mimarble.scene.shapes import SHAPE_KINDS


def _vec(v, mirror_z=True) -> str:
    x, y, z = v
    return f"<{x!r}, {y!r}, {-z if mirror_z else z!r}>"


def _step(kind: str, v) -> str:
    """A transform step's vector in POV-Ray's left-handed frame: a translation's z
    mirrored, a rotation's x and y angles negated, a scale as it is."""
    if kind == "translate":
        return _vec(v)
    if kind == "rotate":
        return _vec((-v[0], -v[1], v[2]), False)
    return _vec(v, False)


def _pigment(channel) -> str:
    if isinstance(channel, model.ColorChannel):
        return f"pigment {{ rgb {_vec(channel.rgb, False)} }}"
    if not isinstance(channel, model.MarbleChannel):
        raise ValueError(f"POV-Ray export takes colour and marble channels only, not "
                         f"{type(channel).__name__} (the benchmark's comparison is fig11a)")
    ramp = channel.ramp
    keys = channel.ramp_positions or [k / (len(ramp) - 1) if len(ramp) > 1 else 0.0
                                      for k in range(len(ramp))]
    entries = " ".join(f"[{key!r} rgb {_vec(c, False)}]" for key, c in zip(keys, ramp))
    period = abs(channel.period) or 1.0
    wave = " ramp_wave" if channel.function == "sawtooth" else ""   # else marble's triangle
    # The pattern's own transform, then the paper's frequency; POV-Ray is left-handed
    # (z mirrored), so a rotation's x and y angles change sign (docs/coming-from-povray.md).
    steps = " ".join(f"{kind} {_step(kind, v)}" for kind, v in channel.transform)
    return (f"pigment {{ marble{wave} turbulence {abs(channel.distortion) / period!r} "
            f"octaves {max(1, min(channel.octaves, 10))} omega {channel.gain!r} "
            f"lambda {channel.lacunarity!r} color_map {{ {entries} }} "
            f"scale {1.0 / (period * channel.scale)!r} {steps} }}")


def scene_text(scene: model.Scene, size: int) -> str:
    """The scene in POV-Ray 3.7's language (see the module docstring); a scene with planes,
    boxes or meshes, or a ``space object`` marble, is refused (ValueError, one sentence):
    the comparison is of a marble sphere in world space."""
    others = [kind.plural for kind in SHAPE_KINDS if kind.cls is not model.Sphere
              and getattr(scene, kind.plural)]
    if others:
        raise ValueError(f"POV-Ray export takes spheres only, not {' or '.join(others)} "
                         f"(the benchmark's comparison is a marble sphere, fig11a)")
    if any(model.in_object_space(channel) for material in scene.materials.values()
           for channel in material.channels().values()):
        raise ValueError("POV-Ray export takes world-space marbles only, not 'space object' "
                         "(the benchmark's comparison is a marble sphere, fig11a)")
    cam = scene.camera
    lines = ["#version 3.7;", "global_settings { assumed_gamma 1.0 "
             f"ambient_light rgb {_vec(scene.ambient, False)} }}",
             f"camera {{ perspective location {_vec(cam.eye)} look_at {_vec(cam.lookat)} "
             f"sky {_vec(cam.up)} up y right x angle {cam.fov!r} }}",
             f"background {{ rgb {_vec(scene.image.background, False)} }}"]
    lines += [f"light_source {{ {_vec(light.position)} rgb {_vec(light.color, False)} }}"
              for light in scene.lights]
    for sphere in scene.spheres:
        material = scene.materials[sphere.material]
        channels = material.channels()
        main = next((c for c in channels.values() if isinstance(c, model.MarbleChannel)),
                    channels.get("diffuse") or model.ColorChannel((0.0, 0.0, 0.0)))
        specular = material.specular
        ks = sum(specular.rgb) / 3 if isinstance(specular, model.ColorChannel) else (
            0.5 if specular is not None else 0.0)
        finish = (f"finish {{ ambient {1.0 if 'ambient' in channels else 0.0} "
                  f"diffuse {1.0 if 'diffuse' in channels else 0.0} specular {ks!r} "
                  f"roughness {1.0 / material.shininess!r} }}")
        lines.append(f"sphere {{ {_vec(sphere.center)}, {sphere.radius!r} "
                     f"texture {{ {_pigment(main)} {finish} }} }}")
    return "\n".join(lines) + "\n"


_TRACE_TIME = re.compile(r"Trace Time:.*\(([\d.]+) seconds\)")


def available() -> bool:
    """Whether ``povray`` is installed (on the PATH)."""
    return shutil.which("povray") is not None


def time_povray(scene: model.Scene, size: int = 500, repeats: int = 3) -> dict | None:
    """POV-Ray's trace time and whole-process time on ``scene`` at size², 1 sample a pixel."""
    povray = shutil.which("povray")
    if povray is None:
        return None
    trace, process = [], []
    with tempfile.TemporaryDirectory() as folder:
        source = Path(folder) / "marble.pov"
        source.write_text(scene_text(scene, size))
        for _ in range(repeats):
            start = time.perf_counter()
            run = subprocess.run([povray, "-D", "-A", f"+W{size}", f"+H{size}",
                                  f"+O{Path(folder) / 'out.png'}", str(source)],
                                 capture_output=True, text=True, timeout=600)
            process.append(time.perf_counter() - start)
            found = _TRACE_TIME.search(run.stderr + run.stdout)
            if run.returncode != 0 or not found:
                raise RuntimeError(f"povray failed: {(run.stderr or run.stdout)[-500:]}")
            trace.append(float(found.group(1)))
    found = subprocess.run([povray, "--version"], capture_output=True, text=True)
    version = found.stdout + found.stderr
    version = next((line for line in version.splitlines() if line.startswith("POV-Ray")), "")
    return {"trace_s": statistics.median(trace), "process_s": statistics.median(process),
            "version": version.strip() or "POV-Ray", "size": size}
