"""Host C code compiled at first use: the compiler, the cache directory, atomic builds.

Used by the C firmware core in the loop (:mod:`guardid.firmware.c_core`), the AVR port's
simulator shim and any host-side fast path written in C. Libraries go to a cache directory
outside the repository (``$GUARDID_CACHE_DIR``, else ``$XDG_CACHE_HOME/guardid`` or
``~/.cache/guardid``) under a name that carries a hash of the sources, flags and compiler,
so that a changed source builds anew and concurrent builders agree.

A fast path must keep working without a compiler: :func:`cached_library` returns None
there, or when the environment has ``GUARDID_NATIVE=0`` (every fast path off, for a
comparison or a suspected fast-path bug), and the caller takes its numpy path.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import tempfile
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path

from guardid.errors import GuardidError

HOST_CFLAGS = ("-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-O2", "-shared", "-fPIC")
"""Flags of a host-side fast path: the project's C rules, optimised, a shared library."""


class NativeBuildError(GuardidError):
    """C code cannot be built or loaded (no compiler, sources missing, compiler error)."""


def find_compiler() -> str | None:
    """``$CC`` if set, else the first of gcc, cc, clang on PATH."""
    env = os.environ.get("CC")
    if env:
        return shutil.which(env) or None
    return next((shutil.which(c) for c in ("gcc", "cc", "clang") if shutil.which(c)), None)


def cache_dir() -> Path:
    """Where built libraries are kept (outside the repository)."""
    if os.environ.get("GUARDID_CACHE_DIR"):
        return Path(os.environ["GUARDID_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "guardid"


def build_cached(
    lib: Path,
    command: Callable[[str], list[str]],
    what: str,
    error: type[GuardidError] = NativeBuildError,
) -> Path:
    """``lib`` [a cached shared library], built once by ``command(out)`` (the compiler's
    argv writing to ``out``) into a temporary file renamed into place: atomic, so that
    concurrent builders agree. A failed build raises ``error`` "``what`` failed: <the
    compiler's first line>"."""
    if lib.is_file():
        return lib
    lib.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(suffix=".so", dir=lib.parent)
    os.close(fd)
    try:
        res = subprocess.run(command(tmp), capture_output=True, text=True)
        if res.returncode != 0:
            first = ((res.stderr or res.stdout).strip().splitlines() or ["(no output)"])[0]
            raise error(f"{what} failed: {first}")
        os.replace(tmp, lib)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return lib


def cached_library(
    name: str, sources: Sequence[Path], cflags: Sequence[str] = HOST_CFLAGS
) -> Path | None:
    """The shared library ``lib<name>-<hash>.so`` built from ``sources`` (C files, headers
    included in the hash when listed) with ``cflags``; None when no compiler is found or
    ``GUARDID_NATIVE=0``, so that the caller falls back to its Python path. A compiler error raises
    :class:`NativeBuildError` (a source bug, not a machine's lack)."""
    if os.environ.get("GUARDID_NATIVE", "1") == "0":
        return None
    cc = find_compiler()
    if cc is None:
        return None
    digest = hashlib.sha256()
    for path in sources:
        digest.update(path.name.encode() + b"\0" + Path(path).read_bytes())
    digest.update(" ".join((os.path.realpath(cc), *cflags)).encode())
    lib = cache_dir() / f"lib{name}-{digest.hexdigest()[:16]}.so"
    c_files = [str(p) for p in sources if str(p).endswith(".c")]
    return build_cached(lib, lambda out: [cc, *cflags, *c_files, "-o", out], f"building {name}")


def load_cached(name: str, sources: Sequence[Path], signatures: dict) -> ctypes.CDLL | None:
    """The library of :func:`cached_library` loaded through ctypes, each function of
    ``signatures`` ({C name: (argtypes, restype)}) declared; None without a compiler, with
    ``GUARDID_NATIVE=0``, with a cache directory that cannot be written or a library that
    does not load (the caller takes its Python path). A build that fails (a compiler that
    errs, is killed or lacks its headers) is a speed-up lost, not a wrong result: one
    warning naming it, and None (the tests that need the kernel assert it is there)."""
    try:
        path = cached_library(name, sources)
        lib = None if path is None else ctypes.CDLL(str(path))
    except OSError:
        return None
    except NativeBuildError as exc:
        warnings.warn(f"guardid: the C fast path {name} is off: {exc}", stacklevel=2)
        return None
    if lib is None:
        return None
    for fn, (argtypes, restype) in signatures.items():
        getattr(lib, fn).argtypes = argtypes
        getattr(lib, fn).restype = restype
    return lib
