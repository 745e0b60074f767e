"""Eight float32 lanes as one numba value, for :mod:`lstm_lockstep`'s kernels.

Why: numba arrays carry no aliasing information, so LLVM vectorizes a loop over 8 or 16 lanes
only behind run-time overlap checks, or not at all once it has unrolled the loop; and it keeps
no accumulator of such a loop in a register. An epoch of 32 models written as plain loops over
the lanes ran at 0.57-0.76x the speed of training them one after another. :data:`f32x8` is an
LLVM ``<8 x float>`` value: loads, stores and arithmetic on it are vector instructions by
construction, and values held across a loop stay in registers.

Every operation carries the training kernels' float flags (nnan, ninf, nsz: no reordering, no
fused multiply-adds), so each lane rounds exactly as the scalar code of one model does.
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.extending import intrinsic, models, register_model

WIDTH = 8  # lanes of a vector: one AVX2 register of float32
_VECTOR = ir.VectorType(ir.FloatType(), WIDTH)
_FLAGS = ("nnan", "ninf", "nsz")  # lstm_kernels._TRAIN_MATH


class F32x8(types.Type):
    def __init__(self):
        super().__init__(name="f32x8")


f32x8 = F32x8()


@register_model(F32x8)
class _F32x8Model(models.PrimitiveModel):
    def __init__(self, dmm, fe_type):
        super().__init__(dmm, fe_type, _VECTOR)


def _pointer(context, builder, array_type, array, index):
    data = context.make_array(array_type)(context, builder, value=array).data
    return builder.bitcast(builder.gep(data, [index]), _VECTOR.as_pointer())


@intrinsic
def load(typingctx, array, index):
    """The 8 float32 of a C-contiguous array from flat element ``index`` on."""

    def codegen(context, builder, sig, args):
        return builder.load(_pointer(context, builder, sig.args[0], *args), align=4)

    return f32x8(array, types.intp), codegen


@intrinsic
def store(typingctx, array, index, value):
    """Write ``value`` to the 8 float32 of a C-contiguous array from flat ``index`` on."""

    def codegen(context, builder, sig, args):
        builder.store(args[2], _pointer(context, builder, sig.args[0], args[0], args[1]), align=4)
        return context.get_dummy_value()

    return types.none(array, types.intp, f32x8), codegen


@intrinsic
def splat(typingctx, x):
    """The float32 ``x`` in every lane."""

    def codegen(context, builder, sig, args):
        scalar = context.cast(builder, args[0], sig.args[0], types.float32)
        v = builder.insert_element(
            ir.Constant(_VECTOR, ir.Undefined), scalar, ir.Constant(ir.IntType(32), 0)
        )
        zeros = ir.Constant(ir.VectorType(ir.IntType(32), WIDTH), [0] * WIDTH)
        return builder.shuffle_vector(v, ir.Constant(_VECTOR, ir.Undefined), zeros)

    return f32x8(x), codegen


def _arithmetic(operation):
    @intrinsic
    def apply(typingctx, a, b):
        def codegen(context, builder, sig, args):
            return getattr(builder, operation)(args[0], args[1], flags=_FLAGS)

        return f32x8(f32x8, f32x8), codegen

    return apply


add, sub, mul, div = (_arithmetic(op) for op in ("fadd", "fsub", "fmul", "fdiv"))


def _choice(predicate):
    @intrinsic
    def apply(typingctx, a, b):
        def codegen(context, builder, sig, args):
            keep = builder.fcmp_ordered(predicate, args[0], args[1], flags=_FLAGS)
            return builder.select(keep, args[0], args[1])

        return f32x8(f32x8, f32x8), codegen

    return apply


minimum, maximum = _choice("<"), _choice(">")


@intrinsic
def where(typingctx, mask, a, b):
    """``a`` in the lanes where ``mask`` is positive, ``b`` elsewhere."""

    def codegen(context, builder, sig, args):
        zero = ir.Constant(_VECTOR, [0.0] * WIDTH)
        return builder.select(builder.fcmp_ordered(">", args[0], zero), args[1], args[2])

    return f32x8(f32x8, f32x8, f32x8), codegen
