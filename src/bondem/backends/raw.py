"""Array access for the hottest CPU loops, without Numba's negative-index wraparound.

Numba reads ``a[i]`` with a signed ``i`` as ``a[i + n if i < 0 else i]``, and LLVM can
rarely prove ``i >= 0``: in the bond kernel's gather into its scratch and scatter out of
it that was three extra instructions per access, and the shapes it needs, with the
strides, left more values than registers (spilled and reloaded per bond). These intrinsics
address the element directly, so an index must lie in ``[0, n)``: the callers' loops
guarantee it (bond and particle numbers, scratch slots). They change no result.

``prefetch`` asks the cache for a row ahead of its use.
"""
import numba
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.core.extending import intrinsic
from numba.np.arrayobj import load_item, store_item


def _element(context, builder, array_type, array, indices, index_types):
    """Pointer to array[indices], with no wraparound and no bounds check."""
    data = context.make_array(array_type)(context, builder, array)
    shapes = cgutils.unpack_tuple(builder, data.shape, array_type.ndim)
    strides = cgutils.unpack_tuple(builder, data.strides, array_type.ndim)
    index = [context.cast(builder, value, kind, types.intp)
             for value, kind in zip(indices, index_types)]
    return cgutils.get_item_pointer2(context, builder, data.data, shapes, strides,
                                     array_type.layout, index, wraparound=False,
                                     boundscheck=False)


def _row_of_three(context, builder, array_type, array, row, column, index_types):
    """Pointer to array[row, column] of a C-contiguous (n, 3) array: 3 row + column
    elements from the start, one multiply by a constant (no shape read)."""
    data = context.make_array(array_type)(context, builder, array)
    row, column = (context.cast(builder, value, kind, types.intp)
                   for value, kind in zip((row, column), index_types))
    offset = builder.add(builder.mul(row, context.get_constant(types.intp, 3)), column)
    return builder.gep(data.data, [offset])


def _need(array, ndim, contiguous=False):
    if not isinstance(array, types.Array) or array.ndim != ndim:
        raise TypingError(f"raw access: need a {ndim}-d array, got {array}")
    if contiguous and array.layout != "C":
        raise TypingError(f"raw access: need a C-contiguous array, got {array}")


def _pointer(context, builder, signature, args, rows_of_three):
    """Pointer to the element named by args = (array, *indices[, value])."""
    array_type = signature.args[0]
    if rows_of_three:
        return _row_of_three(context, builder, array_type, args[0], args[1], args[2],
                             signature.args[1:3])
    count = array_type.ndim
    return _element(context, builder, array_type, args[0], args[1:1 + count],
                    signature.args[1:1 + count])


def _loader(rows_of_three):
    def codegen(context, builder, signature, args):
        return load_item(context, builder, signature.args[0],
                         _pointer(context, builder, signature, args, rows_of_three))
    return codegen


def _storer(rows_of_three):
    def codegen(context, builder, signature, args):
        value = context.cast(builder, args[-1], signature.args[-1], signature.args[0].dtype)
        store_item(context, builder, signature.args[0], value,
                   _pointer(context, builder, signature, args, rows_of_three))
        return context.get_dummy_value()
    return codegen


@intrinsic
def get(typingctx, array, i):
    """array[i] of a 1-d array, 0 <= i < len(array)."""
    _need(array, 1)
    return array.dtype(array, i), _loader(False)


@intrinsic
def get2(typingctx, array, i, k):
    """array[i, k] of a 2-d array, both indices in range."""
    _need(array, 2)
    return array.dtype(array, i, k), _loader(False)


@intrinsic
def put(typingctx, array, i, value):
    """array[i] = value for a 1-d array, 0 <= i < len(array)."""
    _need(array, 1)
    return types.void(array, i, value), _storer(False)


@intrinsic
def get3(typingctx, array, i, k):
    """array[i, k] of a C-contiguous (n, 3) array (the caller checks the 3),
    0 <= i < n, 0 <= k < 3."""
    _need(array, 2, contiguous=True)
    return array.dtype(array, i, k), _loader(True)


@intrinsic
def put3(typingctx, array, i, k, value):
    """array[i, k] = value for a C-contiguous (n, 3) array, as ``get3``."""
    _need(array, 2, contiguous=True)
    return types.void(array, i, k, value), _storer(True)


@intrinsic
def prefetch(typingctx, array, row):
    """Ask the cache for the first line of ``array[row]`` (a C-contiguous array), to be
    read soon: LLVM's ``llvm.prefetch`` (read, keep in all levels). Changes no result."""
    def codegen(context, builder, signature, args):
        data = context.make_array(signature.args[0])(context, builder, args[0])
        stride = cgutils.unpack_tuple(builder, data.strides, signature.args[0].ndim)[0]
        byte = ir.IntType(8).as_pointer()
        address = builder.gep(builder.bitcast(data.data, byte), [builder.mul(args[1], stride)])
        i32 = ir.IntType(32)
        # named .p0i8: this LLVM's own name on older llvmlite, upgraded to .p0 by newer
        call = builder.module.declare_intrinsic(
            "llvm.prefetch", [byte], ir.FunctionType(ir.VoidType(), [byte, i32, i32, i32]))
        builder.call(call, [address, ir.Constant(i32, 0), ir.Constant(i32, 3),
                            ir.Constant(i32, 1)])
        return context.get_dummy_value()
    return types.void(array, types.intp), codegen


@numba.njit(inline="always")
def row3(a, i):
    """Row i of a C-contiguous (n, 3) array as a 3-tuple (``loops.row3`` on the CPU)."""
    return (get3(a, i, 0), get3(a, i, 1), get3(a, i, 2))


@numba.njit(inline="always")
def store3(a, i, v):
    """a[i] = v for a C-contiguous (n, 3) array and a 3-tuple (``loops.store3`` on the
    CPU)."""
    put3(a, i, 0, v[0])
    put3(a, i, 1, v[1])
    put3(a, i, 2, v[2])


# The loop bodies the CPU compiles as these (``loops.compile_loops``' given): every row
# of three a body reads or writes through row3 and store3 goes unchecked. An array of
# another layout fails to compile (get3's typing), so a body never reads a wrong row.
ROWS = {"row3": row3, "store3": store3}
