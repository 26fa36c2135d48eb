"""Rendering through Mitsuba: passes, replay, loaded scenes, adaptive sampling, output."""
