"""The process around the renderers: libLLVM and variant, kernel cache, machine, files, progress."""
