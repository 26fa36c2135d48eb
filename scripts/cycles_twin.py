"""A translucent mimarble scene rebuilt in Blender Cycles (its random-walk subsurface), rendered
headless, its linear image and Cycles' own render time read back.

    ./go python scripts/cycles_twin.py SCENE [--spp 64] [--seed 0] [--threads 2]
        [--radius mfp|matched] [--out IMAGE.exr|.npy] [--json OUT.json]

Needs Blender 3.4 (Debian: apt-get install blender); ./go does not install it and nothing in the
test suite's normal path runs it. This file is also the script Blender runs
(``blender -b --factory-startup -P scripts/cycles_twin.py -- --build SPEC OUT``): under
Blender's own Python (no NumPy, no mimarble) only :func:`build_and_render` and what it calls run.

What the twin supports, and how each part maps (anything else is refused in one sentence,
:class:`Unsupported`):

* Spheres whose material has a ``subsurface`` (no planes, boxes or meshes; no density
  channel): a UV sphere of 256 × 128 segments, smooth-shaded (its facets are within 8e-5 of
  the radius), with a Principled BSDF: Subsurface 1 (the weight; Base Color = Subsurface Color,
  so nothing is left to the diffuse lobe), method Random Walk, Roughness 0, Specular =
  F0/0.08 with F0 = ((ior − 1)/(ior + 1))² (Principled's own scale: Specular 0.5 is F0 0.04),
  Subsurface IOR = IOR = ior, Metallic, Sheen, Clearcoat, Transmission 0.
* The colour: the subsurface's ``reflectance`` channel (the colour seen; Cycles' Subsurface
  Color means the same) or, in a scene that gives ``albedo`` (the single-scattering albedo),
  that channel's colour, and the result's ``colour_comparable`` is false. A constant colour
  is the colour; a marble (world space, no transform, ``abs_sine``/``sine``/``cosine``, no
  turbulence) is APPROXIMATED by Cycles' Wave texture (bands along its axis, sine profile, the
  same period, scale and octave count; its distortion from Blender's fractal noise, which is
  not the paper's) → a 32-stop linear ColorRamp of the marble's ramp colours: the veins run
  the same way at the same spacing, not through the same points.
* Subsurface Radius, and what Cycles makes of it. Blender 3.4's Random Walk method does not
  take the radius as the mean free path: it scales it by √(3(1 − α′)), α′ the reduced albedo
  for which the classical dipole's diffuse reflectance equals the colour at the Subsurface
  IOR (Jensen et al. 2001; Cycles kernel/closure/bssrdf.h, bssrdf_setup_radius), and its walk
  has σ_t = 1/(that product) (kernel/integrator/subsurface_random_walk.h). So the radius is
  the diffusion length 1/σ_tr, and the walk's mean free path is radius·√(3(1 − α′)).
  ``--radius mfp`` (the default, the issue's setup) sets the radius to the scene's
  mean_free_path in every channel: Cycles' medium is then denser than ours (at colour 0.8,
  ior 1.5, α′ = 0.9986: its mean free path is 0.065 of the radius). ``--radius matched``
  divides the mean free path by √(3(1 − α′)) per channel (α′ of the constant colour, or of
  the marble ramp's mean colour) so that Cycles' walk has our mean free path. (Read in the
  Cycles 3.x sources; not checked line by line against the 3.4.1 binary.)
* ``ambient`` A: the world, a Background of colour A and strength 1 (constant radiance A),
  hidden from camera rays as path mode hides emitters (``hide_emitters``).
* Point lights and spherical area lights: Cycles point lights (radius 0, or the sphere's
  radius: Blender 3.4 draws it as a disk of that radius facing the shaded point) with the
  radiance path mode gives them (mimarble/mitsuba/translate/lights.py): radiant intensity
  I·π·d² towards the look-at point (d the light's distance to it). A Cycles point light of
  power P [W] has radiant intensity P/(4π) (a disk of radius R: radiance P/(4π·πR²)), so
  P = 4π²·I·d². Rectangle lights are refused.
* Camera: perspective, the vertical fov, the scene's size; a 1-pixel box filter (path mode's).
* Rendering: CPU, ``--threads`` threads, ``--spp`` samples and seed ``--seed``; no adaptive
  sampling, no denoising, no light clamping (Blender's default clamps indirect light at 10),
  no glossy filter, no path guiding.

The render time is Cycles' own (``--debug-cycles`` logs it): ``cycles_render_s`` the "render
time (without synchronization)", ``cycles_total_s`` with the scene's sync (mesh, BVH, shaders)
added; ``blender_call_s`` is the wall time of the whole ``bpy.ops.render.render`` call and
``blender_call_cpu_s`` the CPU seconds of Blender's threads over it.
"""

from __future__ import annotations

import json
import math
import re
import sys

SEGMENTS, RINGS = 256, 128
RAMP_STOPS = 32          # Blender's ColorRamp holds at most 32 stops
MARKER = "CYCLES_TWIN_RESULT "


class Unsupported(ValueError):
    """A scene (or part of one) the Cycles twin cannot rebuild, in one sentence."""


# ---------------------------------------------------------------------------
# The scene → a plain description (project Python)

def fresnel_f0(ior: float) -> float:
    """Normal-incidence reflectance of a smooth dielectric, ((η − 1)/(η + 1))²."""
    return ((ior - 1.0) / (ior + 1.0)) ** 2


def dipole_reduced_albedo(colour: float, ior: float) -> float:
    """α′ in [0, 1) whose dipole diffuse reflectance R_d(α′) = (α′/2)(1 + e^{−(4/3)A·s})e^{−s},
    s = √(3(1 − α′)), equals ``colour`` (Jensen et al. 2001, with A = (1 + F_dr)/(1 − F_dr),
    F_dr = −1.440/η² + 0.710/η + 0.668 + 0.0636η): the quantity Blender 3.4 scales the
    Random Walk radius with. R_d rises with α′; solved by bisection to float64."""
    f_dr = -1.440 / ior ** 2 + 0.710 / ior + 0.668 + 0.0636 * ior
    big_a = (1.0 + f_dr) / (1.0 - f_dr)

    def r_d(a):
        s = math.sqrt(3.0 * (1.0 - a))
        return 0.5 * a * (1.0 + math.exp(-4.0 / 3.0 * big_a * s)) * math.exp(-s)

    if colour <= 0.0:
        return 0.0
    lo, hi = 0.0, 1.0
    if r_d(hi - 1e-12) <= colour:
        return 1.0 - 1e-12
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if r_d(mid) < colour else (lo, mid)
    return 0.5 * (lo + hi)


def cycles_radius(mean_free_path: float, colour, ior: float, rule: str) -> list[float]:
    """Subsurface Radius per channel: the mean free path (``mfp``), or the radius whose Random
    Walk mean free path is ours (``matched``): mfp/√(3(1 − α′(colour, ior)))."""
    if rule == "mfp":
        return [mean_free_path] * 3
    return [mean_free_path / math.sqrt(3.0 * (1.0 - dipole_reduced_albedo(c, ior)))
            for c in colour]


def light_power(light, lookat) -> float:
    """Cycles point-light power P with radiant intensity P/(4π) = path mode's I·π·d², per
    unit of colour: 4π²·d²."""
    return 4.0 * math.pi ** 2 * math.dist(light.position, lookat) ** 2


def marble_texture(channel) -> dict:
    """The Wave → ColorRamp approximation of a marble channel (see the module docstring).

    abs_sine: t = |sin πu|, u = period·v_axis + distortion·F(v), v = scale·p. Wave (bands,
    sine profile) gives w = ½ + ½ sin(n − π/2 + phase), n = 20·S·p_axis + D·(2·fbm − 1),
    fbm Blender's fractal noise in [0, 1] at S·detail_scale·p. w = sin²(πu) = t² when
    n = 2πu: S = 2π·period·scale/20; the noise at our frequency: detail_scale = scale/S; our
    F = Σ N(2^i v)/2^i spans about twice Blender's normalised (2·fbm − 1), so D = 4π·distortion.
    The ramp is sampled at t_j and placed at w_j = t_j². sine and cosine: w = t directly
    (phase π/2 and π)."""
    from mimarble.reference.marble import ramp
    import numpy as np
    if channel.function not in ("abs_sine", "sine", "cosine"):
        raise Unsupported(f"the Cycles twin approximates abs_sine, sine and cosine marbles, "
                          f"not {channel.function}")
    if channel.turbulence or getattr(channel, "space", "world") != "world" \
            or getattr(channel, "transform", ()) or channel.lacunarity != 2.0:
        raise Unsupported("the Cycles twin approximates world-space marbles without turbulence, "
                          "transform or a lacunarity other than 2")
    scale, period, distortion = channel.scale, channel.period, channel.distortion
    if channel.function == "abs_sine":
        wave_scale, phase, strength = 2 * math.pi * period * scale / 20, 0.0, 4 * math.pi
        t = np.linspace(0.0, 1.0, RAMP_STOPS)
        positions = t ** 2
    else:
        frequency = period * scale if channel.function == "sine" else scale
        wave_scale, strength = frequency / 20, 2.0
        phase = math.pi / 2 if channel.function == "sine" else math.pi
        t = positions = np.linspace(0.0, 1.0, RAMP_STOPS)
    colours = ramp(t, channel.ramp, getattr(channel, "ramp_positions", None))
    return {"kind": "wave", "axis": channel.axis.upper(), "scale": wave_scale, "phase": phase,
            "distortion": strength * distortion, "detail": float(min(channel.octaves - 1, 15)),
            "detail_scale": scale / wave_scale, "detail_roughness": channel.gain,
            "stops": [[float(p)] + [float(c) for c in col] for p, col in zip(positions, colours)],
            "mean_colour": [float(c) for c in np.mean(ramp(np.linspace(0, 1, 1001), channel.ramp,
                                                           getattr(channel, "ramp_positions",
                                                                   None)), axis=0)]}


def colour_spec(channel) -> dict:
    """A subsurface colour channel as the twin builds it: constant or Wave → ColorRamp."""
    from mimarble.scene import model
    if isinstance(channel, model.ColorChannel):
        return {"kind": "constant", "colour": list(channel.rgb), "mean_colour": list(channel.rgb)}
    if isinstance(channel, model.MarbleChannel):
        return marble_texture(channel)
    raise Unsupported(f"the Cycles twin takes a constant colour or a marble as the subsurface "
                      f"colour, not a {type(channel).__name__}")


def twin_spec(scene, spp: int, seed: int, threads: int = 2, radius_rule: str = "mfp") -> dict:
    """The Cycles twin of ``scene`` as plain data (what :func:`build_and_render` reads);
    :class:`Unsupported` for what the twin does not support."""
    from mimarble.scene import model
    if scene.planes or scene.boxes or scene.meshes:
        raise Unsupported("the Cycles twin builds spheres only (this scene has planes, boxes "
                          "or meshes)")
    if not scene.spheres:
        raise Unsupported("the Cycles twin needs at least one sphere")
    lookat = scene.camera.lookat
    lights = []
    for light in scene.lights:
        if isinstance(light.area, model.RectangleArea):
            raise Unsupported("the Cycles twin takes point and spherical area lights, not "
                              "rectangle lights")
        lights.append({"position": list(light.position),
                       "radius": light.area.radius if light.area is not None else 0.0,
                       "power": [c * light_power(light, lookat) for c in light.color]})
    spheres, comparable = [], True
    for sphere in scene.spheres:
        sub = scene.materials[sphere.material].subsurface
        if sub is None:
            raise Unsupported(f'the Cycles twin builds translucent spheres only: material '
                              f'"{sphere.material}" has no subsurface')
        if sub.density is not None:
            raise Unsupported("the Cycles twin cannot take a subsurface density channel "
                              "(Cycles' random walk has one extinction per closure)")
        reflectance = getattr(sub, "reflectance", None)
        comparable = comparable and reflectance is not None
        colour = colour_spec(reflectance if reflectance is not None else sub.albedo)
        spheres.append({"center": list(sphere.center), "radius": sphere.radius,
                        "ior": sub.ior, "specular": fresnel_f0(sub.ior) / 0.08,
                        "subsurface_radius": cycles_radius(sub.mean_free_path,
                                                           colour["mean_colour"], sub.ior,
                                                           radius_rule),
                        "colour": colour})
    cam, img = scene.camera, scene.image
    return {"width": img.width, "height": img.height, "spp": spp, "seed": seed,
            "threads": threads, "radius_rule": radius_rule, "colour_comparable": comparable,
            "camera": {"eye": list(cam.eye), "lookat": list(cam.lookat), "up": list(cam.up),
                       "fov": cam.fov},
            "ambient": list(scene.ambient), "lights": lights, "spheres": spheres}


def render_cycles(scene, spp: int, seed: int = 0, threads: int = 2, radius_rule: str = "mfp",
                  exr_path: str | None = None):
    """Render the twin of ``scene`` in Blender → (linear float32 (H, W, 3), info dict: the
    Cycles times, the Blender version, the spec's flags). Raises Unsupported, or
    RuntimeError when Blender fails."""
    import shutil
    import subprocess
    import tempfile
    from pathlib import Path
    if shutil.which("blender") is None:
        raise RuntimeError("blender is not installed (Debian: apt-get install blender)")
    spec = twin_spec(scene, spp, seed, threads, radius_rule)
    with tempfile.TemporaryDirectory() as folder:
        spec_path = Path(folder) / "twin.json"
        spec_path.write_text(json.dumps(spec))
        out = exr_path or str(Path(folder) / "cycles.exr")
        run = subprocess.run(["blender", "-b", "--factory-startup", "-noaudio", "--debug-cycles",
                              "-P", str(Path(__file__).resolve()), "--", "--build",
                              str(spec_path), out], capture_output=True, text=True)
        text = run.stdout + run.stderr
        found = [line for line in text.splitlines() if line.startswith(MARKER)]
        if run.returncode != 0 or not found:
            raise RuntimeError(f"blender failed (exit {run.returncode}): {text[-1500:]}")
        info = json.loads(found[-1][len(MARKER):])
        info.update(cycles_times(text))
        image = read_exr(out)
    info.update(radius_rule=radius_rule, colour_comparable=spec["colour_comparable"],
                subsurface_radius=[s["subsurface_radius"] for s in spec["spheres"]],
                colour_kinds=[s["colour"]["kind"] for s in spec["spheres"]])
    return image, info


def cycles_times(log: str) -> dict:
    """Cycles' logged times (seconds): total, and render without synchronization."""
    out = {}
    for key, pattern in (("cycles_total_s", r"Total render time: ([0-9.eE+-]+)"),
                         ("cycles_render_s",
                          r"Render time \(without synchronization\): ([0-9.eE+-]+)")):
        match = re.findall(pattern, log)
        if match:
            out[key] = float(match[-1])
    return out


def read_exr(path: str):
    """A float EXR as (H, W, 3) float32 (Mitsuba's Bitmap reads it)."""
    import numpy as np
    import mimarble
    image = np.array(mimarble.mi.Bitmap(path), dtype=np.float32)
    return np.ascontiguousarray(image[..., :3])


# ---------------------------------------------------------------------------
# Inside Blender (its own Python: bpy, mathutils, no NumPy)

def build_and_render(spec: dict, out: str) -> dict:
    """Build the described scene in an empty Blender file and render it with Cycles to the
    float EXR ``out``; returns the Blender version and the call's wall time."""
    import time
    import bpy
    from mathutils import Matrix, Vector
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    cycles = scene.cycles
    cycles.device = "CPU"
    cycles.samples = spec["spp"]
    cycles.seed = spec["seed"]
    cycles.use_animated_seed = False
    cycles.use_adaptive_sampling = False
    cycles.use_denoising = False
    cycles.sample_clamp_direct = 0.0
    cycles.sample_clamp_indirect = 0.0
    cycles.blur_glossy = 0.0
    cycles.pixel_filter_type = "BOX"
    cycles.filter_width = 1.0
    if hasattr(cycles, "use_guiding"):
        cycles.use_guiding = False
    scene.render.threads_mode = "FIXED"
    scene.render.threads = spec["threads"]
    scene.render.resolution_x, scene.render.resolution_y = spec["width"], spec["height"]
    scene.render.resolution_percentage = 100
    scene.render.use_compositing = False
    scene.render.use_sequencer = False
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    settings = scene.render.image_settings
    settings.file_format, settings.color_depth, settings.color_mode = "OPEN_EXR", "32", "RGB"

    cam = spec["camera"]
    eye, target, up = (Vector(cam[k]) for k in ("eye", "lookat", "up"))
    forward = (target - eye).normalized()
    right = forward.cross(up).normalized()
    true_up = right.cross(forward)
    camera = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    scene.collection.objects.link(camera)
    camera.matrix_world = Matrix([[right[i], true_up[i], -forward[i], eye[i]] for i in range(3)]
                                 + [[0, 0, 0, 1]])
    camera.data.sensor_fit = "VERTICAL"
    camera.data.angle_y = math.radians(cam["fov"])
    camera.data.clip_start, camera.data.clip_end = 1e-3, 1e5
    scene.camera = camera

    world = bpy.data.worlds.new("ambient")
    world.use_nodes = True
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = list(spec["ambient"]) + [1.0]
    background.inputs["Strength"].default_value = 1.0
    world.cycles_visibility.camera = False        # path mode's hide_emitters
    scene.world = world

    for k, light in enumerate(spec["lights"]):
        data = bpy.data.lights.new(f"light_{k}", "POINT")
        energy = max(light["power"])
        data.energy = energy
        data.color = [p / energy if energy > 0 else 0.0 for p in light["power"]]
        data.shadow_soft_size = light["radius"]
        obj = bpy.data.objects.new(f"light_{k}", data)
        obj.location = light["position"]
        if hasattr(obj, "visible_camera"):
            obj.visible_camera = False
        scene.collection.objects.link(obj)

    for k, sphere in enumerate(spec["spheres"]):
        bpy.ops.mesh.primitive_uv_sphere_add(segments=SEGMENTS, ring_count=RINGS,
                                             radius=sphere["radius"], location=sphere["center"])
        obj = bpy.context.active_object
        bpy.ops.object.shade_smooth()
        obj.data.materials.append(principled_material(f"sphere_{k}", sphere))

    scene.render.filepath = out
    start, used = time.perf_counter(), time.process_time()
    bpy.ops.render.render(write_still=True)
    return {"blender_call_s": time.perf_counter() - start,
            "blender_call_cpu_s": time.process_time() - used, "blender": bpy.app.version_string,
            "sampling_pattern": cycles.sampling_pattern}


def principled_material(name: str, sphere: dict):
    """The Principled BSDF of a translucent sphere (module docstring)."""
    import bpy
    material = bpy.data.materials.new(name)
    material.use_nodes = True
    nodes, links = material.node_tree.nodes, material.node_tree.links
    bsdf = nodes["Principled BSDF"]
    bsdf.subsurface_method = "RANDOM_WALK"
    values = {"Subsurface": 1.0, "Subsurface Radius": sphere["subsurface_radius"],
              "Subsurface IOR": sphere["ior"], "Subsurface Anisotropy": 0.0, "Metallic": 0.0,
              "Specular": sphere["specular"], "Specular Tint": 0.0, "Roughness": 0.0,
              "Sheen": 0.0, "Clearcoat": 0.0, "IOR": sphere["ior"], "Transmission": 0.0}
    for key, value in values.items():
        bsdf.inputs[key].default_value = value
    colour = sphere["colour"]
    if sphere.get("lambertian"):          # the units check: a Diffuse BSDF of the colour
        diffuse = nodes.new("ShaderNodeBsdfDiffuse")
        diffuse.inputs["Color"].default_value = list(colour["colour"]) + [1.0]
        links.new(diffuse.outputs["BSDF"], nodes["Material Output"].inputs["Surface"])
        return material
    if colour["kind"] == "constant":
        for key in ("Base Color", "Subsurface Color"):
            bsdf.inputs[key].default_value = list(colour["colour"]) + [1.0]
        return material
    position = nodes.new("ShaderNodeNewGeometry")
    wave = nodes.new("ShaderNodeTexWave")
    wave.wave_type, wave.bands_direction, wave.wave_profile = "BANDS", colour["axis"], "SIN"
    for key, value in (("Scale", colour["scale"]), ("Distortion", colour["distortion"]),
                       ("Detail", colour["detail"]), ("Detail Scale", colour["detail_scale"]),
                       ("Detail Roughness", colour["detail_roughness"]),
                       ("Phase Offset", colour["phase"])):
        wave.inputs[key].default_value = value
    ramp = nodes.new("ShaderNodeValToRGB")
    elements = ramp.color_ramp.elements
    stops = colour["stops"]
    elements[0].position, elements[0].color = stops[0][0], stops[0][1:] + [1.0]
    elements[1].position, elements[1].color = stops[-1][0], stops[-1][1:] + [1.0]
    for stop in stops[1:-1]:
        elements.new(stop[0]).color = stop[1:] + [1.0]
    ramp.color_ramp.interpolation = "LINEAR"
    links.new(position.outputs["Position"], wave.inputs["Vector"])
    links.new(wave.outputs["Fac"], ramp.inputs["Fac"])
    for key in ("Base Color", "Subsurface Color"):
        links.new(ramp.outputs["Color"], bsdf.inputs[key])
    return material


# ---------------------------------------------------------------------------
# Command line

def main(argv=None) -> int:
    import argparse
    from pathlib import Path
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", help="a scene file, or a packaged scene's name")
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--radius", choices=("mfp", "matched"), default="mfp")
    parser.add_argument("--out", help="the linear image: .exr (Blender's) or .npy")
    parser.add_argument("--json", help="write the times and settings here")
    args = parser.parse_args(argv)
    from mimarble import scene as scene_language
    from mimarble.runtime import packaged_scenes
    path = packaged_scenes.resolve(args.scene)    # a file, else a packaged scene's name
    scene = scene_language.load(path)
    exr = args.out if args.out and args.out.endswith(".exr") else None
    try:
        image, info = render_cycles(scene, args.spp, args.seed, args.threads, args.radius, exr)
    except Unsupported as problem:
        print(f"{path}: {problem}", file=sys.stderr)
        return 2
    if args.out and args.out.endswith(".npy"):
        import numpy as np
        np.save(args.out, image)
    info.update(scene=str(path), spp=args.spp, seed=args.seed, threads=args.threads,
                size=[image.shape[1], image.shape[0]])
    if args.json:
        Path(args.json).write_text(json.dumps(info, indent=1) + "\n")
    print(json.dumps(info, indent=1))
    return 0


def _blender_main(argv: list[str]) -> None:
    """Blender's entry: ``-- --build SPEC OUT``."""
    spec_path, out = argv[argv.index("--build") + 1:argv.index("--build") + 3]
    with open(spec_path) as handle:
        spec = json.load(handle)
    print(MARKER + json.dumps(build_and_render(spec, out)), flush=True)


if __name__ == "__main__":
    import importlib.util
    if importlib.util.find_spec("bpy") is None:        # bpy: present only inside Blender
        sys.exit(main())
    _blender_main(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else [])
