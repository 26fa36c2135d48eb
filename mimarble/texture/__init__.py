"""The marble's mathematics in Dr.Jit: noise, stripes, ramp, mapping, filters, error budget."""
