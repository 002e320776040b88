"""One BLAS thread inside a unit of work; the loaded libraries looked for again only after an import."""

from __future__ import annotations

import sys

import pytest
from threadpoolctl import ThreadpoolController, threadpool_info

from planner import threads


def blas_threads() -> set[int]:
    return {i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}


def test_blas_uses_one_thread_inside_and_its_own_count_after() -> None:
    before = blas_threads()
    with threads.one_blas_thread():
        assert blas_threads() == {1}
        with threads.one_blas_thread():  # nested: still one, and the outer limit kept on the way out
            assert blas_threads() == {1}
        assert blas_threads() == {1}
    assert blas_threads() == before


def test_libraries_are_looked_for_once_until_a_module_is_imported(monkeypatch: pytest.MonkeyPatch) -> None:
    made: list[ThreadpoolController] = []

    class Counted(ThreadpoolController):
        def __init__(self) -> None:
            super().__init__()
            made.append(self)

    monkeypatch.setattr(threads, "ThreadpoolController", Counted)
    monkeypatch.setattr(threads, "_FOUND", [])
    for _ in range(3):
        with threads.one_blas_thread():
            assert blas_threads() == {1}
    assert len(made) == 1
    monkeypatch.setitem(sys.modules, "tests._a_module_imported_since", sys)  # as an import adds one
    with threads.one_blas_thread():
        assert blas_threads() == {1}
    assert len(made) == 2
