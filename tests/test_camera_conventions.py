"""The camera conventions docs/scene-language.md states for a POV-Ray user ("Coming from
POV-Ray"): right-handed axes, so POV-Ray's location copied unchanged mirrors the image;
``fov`` vertical, POV-Ray's ``angle`` horizontal, fov = 2·atan(tan(angle/2)·H/W)."""

import math

import numpy as np

from mimarble import reference
from mimarble import scene as S
from mimarble.reference.tracer import camera_rays

RED = 'material "red" { ambient { color < 1 0 0 > } }\nambient < 1 1 1 >\n'


def columns_of_the_red_sphere(eye):
    scene = S.parse(f"image {{ width 40 height 20 }} camera {{ eye {eye} fov 40 }}\n{RED}"
                    "sphere { center < 2 0 0 > radius 1 material \"red\" }")
    image = reference.render(scene)
    return np.nonzero(image[..., 0].max(axis=0) > 0.5)[0]


def test_plus_x_is_on_the_right_seen_from_plus_z():
    assert columns_of_the_red_sphere("< 0 0 9 >").min() > 20


def test_povray_location_copied_unchanged_mirrors_the_image():
    # POV-Ray's location <0,0,-9> (left-handed) shows +x on the right; here it is on the left.
    assert columns_of_the_red_sphere("< 0 0 -9 >").max() < 20
    assert (np.sort(39 - columns_of_the_red_sphere("< 0 0 -9 >")) ==
            columns_of_the_red_sphere("< 0 0 9 >")).all()


def horizontal_fov(scene):
    """The angle between the rays through the film's left and right edges, at mid-height."""
    _, d = camera_rays(scene, np.array([0.0, 1.0]), np.array([0.5, 0.5]))
    return math.degrees(math.acos(float(d[0] @ d[1])))


def test_fov_is_vertical_and_povrays_horizontal_angle_follows_from_the_aspect():
    angle = 46.0
    fov = math.degrees(2 * math.atan(math.tan(math.radians(angle / 2)) * 3 / 4))
    assert round(fov) == 35
    scene = S.Scene(image=S.Image(640, 480), camera=S.Camera(eye=(0, 0, 9), fov=fov))
    assert math.isclose(horizontal_fov(scene), angle, rel_tol=1e-12)
    _, d = camera_rays(scene, np.array([0.5, 0.5]), np.array([0.0, 1.0]))
    assert math.isclose(math.degrees(math.acos(float(d[0] @ d[1]))), fov, rel_tol=1e-12)
