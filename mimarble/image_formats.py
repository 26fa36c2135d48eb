"""The image files mimarble writes.

Its own module, importing nothing: the command line checks an output name
before Dr.Jit and Mitsuba load (mimarble/__init__.py).
"""

#: 8-bit sRGB PNG, or linear float OpenEXR.
IMAGE_FORMATS = (".png", ".exr")
