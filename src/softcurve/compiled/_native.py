"""Calling CasADi-generated C functions from Python through ctypes.

CasADi's own ``Function.__call__`` converts every argument to a ``DM``, which costs
tens of microseconds, far more than the compiled dynamics themselves. Here a
generated function is called with pointers to preallocated NumPy buffers: the sparsity of every
input and output, and the work-array sizes, are read from the library's own
``<name>_sparsity_in/out`` and ``<name>_work`` symbols. Buffers are kept per thread,
so one function may be called from several threads (ctypes releases the GIL during
the call). Buffers are allocated once per thread and function.
"""

from __future__ import annotations

import ctypes
import threading

import numpy as np

_int = ctypes.c_longlong  # casadi_int in generated code
_int_p = ctypes.POINTER(_int)


def _sparsity(pointer) -> tuple[int, int, np.ndarray | None]:
    """Decode CasADi's compressed-column sparsity: (rows, cols, flat dense indices or None)."""
    rows, cols = pointer[0], pointer[1]
    if pointer[2] == 1:  # compact form of a dense pattern (a column index starts with 0)
        return rows, cols, None
    colind = [pointer[2 + j] for j in range(cols + 1)]
    nnz = colind[-1]
    if nnz == rows * cols:
        return rows, cols, None
    row = [pointer[2 + cols + 1 + k] for k in range(nnz)]
    flat = np.empty(nnz, dtype=np.intp)
    for j in range(cols):
        for k in range(colind[j], colind[j + 1]):
            flat[k] = row[k] * cols + j  # row-major position in the dense result
    return rows, cols, flat


class NativeFunction:
    """A generated function ``name`` of the shared library ``library``.

    Call it with one array per input (dense, the input's number of elements);
    it returns a list of dense float64 arrays of each output's shape
    (vectors flattened).

    Parameters
    ----------
    library : ctypes.CDLL
        A library that CasADi generated, with ``name`` and its ``name_work``,
        ``name_sparsity_in`` ... symbols.
    name : str
        The function's name in the library.
    """

    def __init__(self, library: ctypes.CDLL, name: str):
        self.name = name
        self._function = getattr(library, name)
        self._function.restype = ctypes.c_int
        self._function.argtypes = [ctypes.c_void_p] * 4 + [ctypes.c_int]
        sizes = [_int() for _ in range(4)]
        work = getattr(library, f"{name}_work")
        work.argtypes = [_int_p] * 4
        if work(*(ctypes.byref(s) for s in sizes)) != 0:
            raise RuntimeError(f"{name}_work failed")
        self._sz_arg, self._sz_res, self._sz_iw, self._sz_w = (s.value for s in sizes)
        self.n_in = self._count(library, "n_in")
        self.n_out = self._count(library, "n_out")
        self._in = [self._read_sparsity(library, "in", i) for i in range(self.n_in)]
        self._out = [self._read_sparsity(library, "out", i) for i in range(self.n_out)]
        self._in_sizes = [r * c for r, c, _ in self._in]
        self._local = threading.local()
        for i, (_, _, flat) in enumerate(self._in):
            if flat is not None:
                raise RuntimeError(f"{name}: input {i} is sparse; only dense inputs are supported")

    @property
    def shapes(self) -> tuple[tuple, tuple]:
        """``(inputs, outputs)``: the ``(rows, columns)`` of each input and output."""
        return tuple(s[:2] for s in self._in), tuple(s[:2] for s in self._out)

    @property
    def address(self) -> int:
        """The generated function's address (what C calls it by: ``casadi_fn``)."""
        return ctypes.cast(self._function, ctypes.c_void_p).value

    @property
    def work_sizes(self) -> tuple[int, int, int, int]:
        """``(sz_arg, sz_res, sz_iw, sz_w)``: the sizes of its work arrays."""
        return (self._sz_arg, self._sz_res, self._sz_iw, self._sz_w)

    def _count(self, library, what: str) -> int:
        f = getattr(library, f"{self.name}_{what}")
        f.restype = _int
        return int(f())

    def _read_sparsity(self, library, what: str, i: int):
        f = getattr(library, f"{self.name}_sparsity_{what}")
        f.restype = _int_p
        f.argtypes = [_int]
        return _sparsity(f(i))

    def _buffers(self) -> _Buffers:
        buffers = getattr(self._local, "buffers", None)
        if buffers is None:
            buffers = self._local.buffers = _Buffers(self)
        return buffers

    def __call__(self, *inputs) -> list[np.ndarray]:
        if len(inputs) != self.n_in:
            raise TypeError(f"{self.name} takes {self.n_in} inputs, got {len(inputs)}")
        buffers = self._buffers()
        for i, (value, target) in enumerate(zip(inputs, buffers.inputs, strict=True)):
            a = np.asarray(value, dtype=np.float64)
            if a.size != target.size:
                raise ValueError(
                    f"{self.name}: input {i} needs {target.size} numbers, got {a.size}"
                )
            target[:] = a.reshape(-1)
        status = self._function(buffers.arg, buffers.res, buffers.iw_pointer, buffers.w_pointer, 0)
        if status != 0:
            raise RuntimeError(f"{self.name} returned status {status}")
        result = []  # fresh arrays: the buffers are overwritten by the next call
        for (rows, cols, flat), buffer in zip(self._out, buffers.outputs, strict=True):
            if flat is None:
                dense = buffer.reshape(cols, rows).T.copy()  # CasADi stores column-major
            else:
                dense = np.zeros(rows * cols)
                dense[flat] = buffer
                dense = dense.reshape(rows, cols)
            result.append(dense.ravel() if cols == 1 else dense)
        return result

    def call_rows(self, inputs, out: np.ndarray, start: int, stop: int) -> list:
        """Call the function on rows ``start:stop`` of the 2-D inputs (the 1-D ones are
        shared by every row), writing its first output into the rows of ``out`` in place:
        no copies, about a microsecond of Python per row (a call that returns holds the
        GIL only to set two pointers).

        Parameters
        ----------
        inputs : sequence of ndarray
            One per input, float64, C-contiguous: shape (N, size) per row, or (size,)
            shared.
        out : ndarray, shape (N, size of the first output)
            float64, C-contiguous; the first output must be dense.
        start, stop : int
            The rows.

        Returns
        -------
        list of (int, str)
            The rows whose call returned a non-zero status, and that status as a message
            (their rows of ``out`` are undefined).
        """
        if len(inputs) != self.n_in:
            raise TypeError(f"{self.name} takes {self.n_in} inputs, got {len(inputs)}")
        rows, cols, flat = self._out[0]
        if flat is not None or cols != 1:
            raise ValueError(f"{self.name}: the first output must be a dense column")
        arrays = [*inputs, out]
        sizes = [*self._in_sizes, rows]
        for i, (a, size) in enumerate(zip(arrays, sizes, strict=True)):
            shared = a.ndim == 1 and i < len(inputs)
            if (
                a.dtype != np.float64
                or not a.flags.c_contiguous
                or a.shape[-1] != size
                or not (shared or (a.ndim == 2 and a.shape[0] >= stop))
            ):
                raise ValueError(
                    f"{self.name}: array {i} must be C-contiguous float64 of shape ({size},) "
                    f"or (>= {stop}, {size}), got {a.dtype} {a.shape}"
                )
        if not out.flags.writeable or out.ndim != 2:
            raise ValueError(f"{self.name}: out must be a writeable 2-D array")
        if not 0 <= start <= stop:
            raise ValueError(f"{self.name}: rows {start}:{stop} must have 0 <= start <= stop")
        buffers = self._buffers()
        arg, res = buffers.arg, buffers.res
        per_row = []
        for k, a in enumerate(inputs):
            if a.ndim == 2:
                per_row.append((k, a.ctypes.data, a.strides[0]))
            else:
                arg[k] = a.ctypes.data
        out_base, out_stride = out.ctypes.data, out.strides[0]
        function, iw, w = self._function, buffers.iw_pointer, buffers.w_pointer
        failed = []
        try:
            for i in range(start, stop):
                for k, base, stride in per_row:
                    arg[k] = base + i * stride
                res[0] = out_base + i * out_stride
                status = function(arg, res, iw, w, 0)
                if status:
                    failed.append((i, f"{self.name} returned status {status}"))
        finally:  # the buffers' own arrays again, for __call__
            for k, a in enumerate(buffers.inputs):
                arg[k] = a.ctypes.data
            res[0] = buffers.outputs[0].ctypes.data
        return failed


class _Buffers:
    """Input, output and work arrays of one function for one thread, with the pointer
    arrays the generated code reads, built once."""

    def __init__(self, function: NativeFunction):
        self.inputs = [np.zeros(size) for size in function._in_sizes]
        self.outputs = [
            np.zeros(r * c if flat is None else flat.size) for r, c, flat in function._out
        ]
        self.iw = np.zeros(max(function._sz_iw, 1), dtype=np.int64)
        self.w = np.zeros(max(function._sz_w, 1))
        self.arg = (ctypes.c_void_p * max(function._sz_arg, 1))()
        self.res = (ctypes.c_void_p * max(function._sz_res, 1))()
        for i, a in enumerate(self.inputs):
            self.arg[i] = a.ctypes.data
        for i, a in enumerate(self.outputs):
            self.res[i] = a.ctypes.data
        self.iw_pointer, self.w_pointer = self.iw.ctypes.data, self.w.ctypes.data
