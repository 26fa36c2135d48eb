"""How much code a render traces: what a skipped or looped computation saves."""

import mimarble

dr = mimarble.dr


def operations_traced(scene) -> int:
    """The operations of the kernels ``mimarble.render(scene)`` launched (Dr.Jit's kernel
    history). Call it with ``MIMARBLE_FREEZE=0``: a replayed recording traces nothing."""
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
        mimarble.render(scene)
        return sum(k.get("operation_count", 0) for k in dr.kernel_history())
