"""The compiled reader of guardid's log body: csvrows.c through ctypes.

:func:`parse_rows` reads the leading rows of a block of text that are plain decimals
(``-?[0-9]+(.[0-9]+)?``, ``,`` between fields, ``\\n`` after each row, integers below 2^53
once the point is dropped, at most 22 decimals) straight into the caller's float64 columns,
each value bit for bit ``float(text)`` (the digits as an integer divided by 10^decimals:
both exact, the quotient correctly rounded). It stops at the first row it does not recognise
(a NaN, an empty field, a short line, a comment, ...) and says how far it got, so that the
caller reads the rest on its Python path (:mod:`guardid.log.numeric`), with its one-line
errors. The C is built once into guardid's cache (:func:`guardid.native.cached_library`) on
first use; without a compiler, or when the build fails or the cache cannot be written
(logged as a warning), :func:`library` is None and the Python path reads everything, to the
same values.
"""

from __future__ import annotations

import functools
import logging
from pathlib import Path

import numpy as np

SOURCE = Path(__file__).with_name("csvrows.c")
_LOG = logging.getLogger("guardid.log")


@functools.cache
def library():
    """The C function ``guardid_csv_rows`` (ctypes), or None without a working compiler."""
    import ctypes

    from guardid.native import NativeBuildError, cached_library

    try:
        lib = cached_library("csvrows", [SOURCE])
        fn = None if lib is None else ctypes.CDLL(str(lib)).guardid_csv_rows
    except (NativeBuildError, OSError) as exc:  # a failed build, a cache it cannot write
        _LOG.warning("compiled log reader unavailable (%s): reading logs in numpy", exc)
        return None
    if fn is None:
        return None
    long, ptr = ctypes.c_long, ctypes.c_void_p
    fn.restype = long
    fn.argtypes = [ctypes.c_char_p, long, long, long, ptr, ptr, long, ctypes.POINTER(long)]
    return fn


def parse_rows(
    fn, block: bytes, start: int, addresses: np.ndarray, strides: np.ndarray, max_rows: int
) -> tuple[int, int]:
    """(rows, end): the rows read from ``block[start:]`` by ``fn`` (:func:`library`), at
    most ``max_rows``, and the offset in ``block`` after them; field c of row r written to
    the float64 at ``addresses[c] + 8 * r * strides[c]`` (the caller keeps room for
    ``max_rows`` rows there, and the arrays alive)."""
    import ctypes

    addresses = np.ascontiguousarray(addresses, dtype=np.uintp)
    strides = np.ascontiguousarray(strides, dtype=np.dtype(ctypes.c_long))
    end = ctypes.c_long(0)
    rows = fn(
        block, start, len(block), len(addresses), addresses.ctypes.data, strides.ctypes.data,
        max_rows, ctypes.byref(end),
    )  # fmt: skip
    return int(rows), end.value
