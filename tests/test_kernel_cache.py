"""numba's cache of the loop's kernels: dropped whole when any kernel source changed
(numba checks a kernel against its own file only); `kernels.in_cache` tells a compiled
kernel from one never compiled or whose source changed, and `platoon-sumo run` says why
the first run after an install (which compiles them, about a minute on 2 cores) is
slow."""

from __future__ import annotations

import contextlib
import importlib
import io
import sys
from pathlib import Path

import pytest

from platoon_sumo import cli
from platoon_sumo.kernels import SOURCES_STAMP, drop_stale_caches, in_cache
from tests.test_results_folders import scenario, write

SOURCE = """
from numba import njit


@njit(cache=True)
def scaled(x):
    return {body}
"""
NOTE = "compiles the loop's kernels once"


def test_in_cache_tells_a_compiled_kernel_from_a_new_or_edited_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    module = tmp_path / "fresh_kernel_for_cache_test.py"
    module.write_text(SOURCE.format(body="2.0 * x"))
    monkeypatch.syspath_prepend(str(tmp_path))
    fresh = importlib.import_module(module.stem)
    try:
        assert in_cache(fresh.scaled) is False  # never compiled
        assert fresh.scaled(1.5) == 3.0
        assert in_cache(fresh.scaled) is True  # compiled and saved by that call
        module.write_text(SOURCE.format(body="3.0 * x + 0.0"))  # another size, stamp
        edited = importlib.reload(fresh)
        assert in_cache(edited.scaled) is False
        assert edited.scaled(1.5) == 4.5
        assert in_cache(edited.scaled) is True
    finally:
        sys.modules.pop(module.stem, None)


def test_in_cache_has_no_answer_for_what_is_not_a_cached_kernel() -> None:
    assert in_cache(len) is None


@pytest.mark.parametrize("compiled", [False, True])
def test_run_says_why_the_first_run_is_slow(
    compiled: bool, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(cli, "_kernels_compiled", lambda: compiled)
    path = write(tmp_path, scenario(simulation={"step_s": 0.1, "end_s": 0.5, "seed": 1}))
    stderr = io.StringIO()
    with contextlib.redirect_stderr(stderr), contextlib.redirect_stdout(io.StringIO()):
        assert cli.main(["run", str(path), "--out", str(tmp_path / "out")]) == 0
    assert (NOTE in stderr.getvalue()) is not compiled


def test_caches_are_dropped_when_any_kernel_source_changes(tmp_path: Path) -> None:
    """numba checks a kernel's cache against its own file only: a kernel calling one in
    another file would load its old compiled code after that file changed."""
    (tmp_path / "callee.py").write_text("def f(x):\n    return x\n")
    (tmp_path / "caller.py").write_text("def g(x):\n    return 2 * x\n")
    cache = tmp_path / "__pycache__"

    def compiled() -> list[Path]:  # what numba writes: an index and data per kernel
        files = [cache / "caller.g-1.py311.nbi", cache / "caller.g-1.py311.1.nbc"]
        for f in files:
            f.write_bytes(b"compiled")
        return files

    assert drop_stale_caches(tmp_path)  # no stamp yet: whatever is there is unknown
    files = compiled()
    assert not drop_stale_caches(tmp_path)  # the same sources: kept
    assert all(f.exists() for f in files)
    (tmp_path / "callee.py").write_text("def f(x):\n    return x + 1\n")  # the callee only
    assert drop_stale_caches(tmp_path)
    assert not any(f.exists() for f in files)
    files = compiled()
    assert not drop_stale_caches(tmp_path)
    assert all(f.exists() for f in files)
    assert (cache / SOURCES_STAMP).exists()
