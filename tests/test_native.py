"""guardid.native: host C fast paths built once into the cache, None without a compiler."""

from __future__ import annotations

import ctypes

import pytest

from guardid.native import NativeBuildError, cached_library, find_compiler

pytestmark = pytest.mark.skipif(find_compiler() is None, reason="needs a C compiler")


def test_a_source_is_built_once_and_runs(tmp_path, monkeypatch):
    monkeypatch.setenv("GUARDID_CACHE_DIR", str(tmp_path / "cache"))
    src = tmp_path / "add.c"
    src.write_text("double add3(double a, double b) { return a + b + 3.0; }\n")
    lib = cached_library("add", [src])
    assert lib is not None and lib.parent == tmp_path / "cache"
    f = ctypes.CDLL(str(lib)).add3
    f.restype, f.argtypes = ctypes.c_double, [ctypes.c_double, ctypes.c_double]
    assert f(1.5, 2.0) == 6.5
    assert cached_library("add", [src]) == lib  # the same sources: the cached file
    src.write_text("double add3(double a, double b) { return a + b + 4.0; }\n")
    assert cached_library("add", [src]) != lib  # a changed source: a new library


def test_no_compiler_or_switched_off_means_no_library(tmp_path, monkeypatch):
    monkeypatch.setenv("GUARDID_CACHE_DIR", str(tmp_path / "cache"))
    src = tmp_path / "x.c"
    src.write_text("int x(void) { return 1; }\n")
    monkeypatch.setenv("GUARDID_NATIVE", "0")
    assert cached_library("x", [src]) is None
    monkeypatch.delenv("GUARDID_NATIVE")
    assert cached_library("x", [src]) is not None
    monkeypatch.setenv("CC", "/nonexistent/cc")
    assert cached_library("x", [src]) is None


def test_a_compiler_error_names_the_library(tmp_path, monkeypatch):
    monkeypatch.setenv("GUARDID_CACHE_DIR", str(tmp_path / "cache"))
    src = tmp_path / "bad.c"
    src.write_text("int bad(void) { int unused; return 1; }\n")  # -Werror: unused variable
    with pytest.raises(NativeBuildError, match="^building bad failed: "):
        cached_library("bad", [src])
    assert list((tmp_path / "cache").iterdir()) == []  # no half-written library left
