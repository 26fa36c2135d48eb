"""Mesh files (PLY, OBJ): their facts for the parser and their arrays for the renderers."""
