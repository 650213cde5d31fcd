"""The CPU's cycle counter inside jitted code, for the kernel's per-phase time shares.

``cycles()`` is LLVM's ``llvm.readcyclecounter`` intrinsic (the time-stamp counter on x86-64, the
virtual counter on AArch64; 0 where a target has none): a few nanoseconds per call, so the time
loop can read it at every phase boundary without a measurable cost. Only ratios of its counts are
used (the shares of a run's time per phase), so the counter's frequency does not matter.
"""

from __future__ import annotations

from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic


@intrinsic
def cycles(typingctx):
    """Cycle counter [ticks] (int64)."""
    sig = types.int64()

    def codegen(context, builder, signature, args):
        fnty = ir.FunctionType(ir.IntType(64), [])
        fn = cgutils.get_or_insert_function(builder.module, fnty, "llvm.readcyclecounter")
        return builder.call(fn, [])

    return sig, codegen
