"""Mesh files (PLY, OBJ): one reader, their facts for the parser and their arrays for the renderers.

limits.py (what a file may hold, MeshFileError), ply_header.py and obj_lines.py (the
formats, read alike for both), ply_body.py and facts.py (the facts, standard library only:
the scene language imports them) and arrays.py (NumPy, imported by the renderers only).
Nothing here imports mimarble.scene, which imports this.
"""
