"""Compiled calls by address (``kernels``; Numba): NumPy's inner loops, MuJoCo's step.

Defined at module level so that Numba's cache keys the kernels that use it the same in
every process (an intrinsic made anew in each would make them compile again each time).
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.extending import intrinsic


@intrinsic
def call_loop(typingctx, fn, args, dims, steps):
    """``fn(args, dims, steps, NULL)``: a NumPy loop (``PyUFuncGenericFunction``) at
    address ``fn``, its three arrays at the addresses given (integers)."""
    sig = types.void(types.intp, types.intp, types.intp, types.intp)

    def codegen(context, builder, signature, a):
        ptr = ir.IntType(8).as_pointer()
        fnty = ir.FunctionType(ir.VoidType(), [ptr, ptr, ptr, ptr])
        f = builder.inttoptr(a[0], fnty.as_pointer())
        builder.call(f, [builder.inttoptr(v, ptr) for v in a[1:]] + [ir.Constant(ptr, None)])
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def call_step(typingctx, fn, m, d):
    """``fn(m, d)``: MuJoCo's ``mj_step`` at address ``fn`` on the model and data at the
    addresses ``m`` and ``d`` (integers; ``sim.native_physics``)."""
    sig = types.void(types.intp, types.intp, types.intp)

    def codegen(context, builder, signature, a):
        ptr = ir.IntType(8).as_pointer()
        fnty = ir.FunctionType(ir.VoidType(), [ptr, ptr])
        f = builder.inttoptr(a[0], fnty.as_pointer())
        builder.call(f, [builder.inttoptr(v, ptr) for v in a[1:]])
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def call_get_state(typingctx, fn, m, d, state, spec):
    """``fn(m, d, state, spec)``: MuJoCo's ``mj_getState`` at address ``fn`` into the
    array at address ``state`` (integers), ``spec`` the state's components."""
    sig = types.void(types.intp, types.intp, types.intp, types.intp, types.intp)

    def codegen(context, builder, signature, a):
        ptr = ir.IntType(8).as_pointer()
        i32 = ir.IntType(32)
        fnty = ir.FunctionType(ir.VoidType(), [ptr, ptr, ptr, i32])
        f = builder.inttoptr(a[0], fnty.as_pointer())
        builder.call(f, [builder.inttoptr(v, ptr) for v in a[1:4]] + [builder.trunc(a[4], i32)])
        return context.get_dummy_value()

    return sig, codegen
