"""``mimarble bench``: run time against error, and what skipping saves."""
