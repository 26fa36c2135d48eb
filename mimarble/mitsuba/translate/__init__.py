"""Scene model → Mitsuba scene dict: scene_dict.to_mitsuba, from one module per part (modes,
textures, materials, media, shapes, lights, float32_range)."""
