"""Workflows on top of the renderers: compare, bake, export, POV-Ray, gallery, stress."""
