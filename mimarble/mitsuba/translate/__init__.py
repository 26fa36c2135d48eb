"""Scene model → Mitsuba scene dict."""
