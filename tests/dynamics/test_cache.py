"""The stale-cache guard of penaltyrun.dynamics (numba checks only the cached function's file)."""

from __future__ import annotations

from pathlib import Path

from penaltyrun import dynamics


def _tree(root: Path) -> tuple[Path, Path]:
    (root / "sub" / "__pycache__").mkdir(parents=True)
    (root / "__pycache__").mkdir()
    (root / "a.py").write_text("x = 1\n")
    (root / "sub" / "b.py").write_text("y = 2\n")
    nbi = root / "sub" / "__pycache__" / "b.f-1.py311.nbi"
    pyc = root / "sub" / "__pycache__" / "b.cpython-311.pyc"
    return nbi, pyc


def test_cache_kept_while_sources_unchanged_and_dropped_after_an_edit(tmp_path, monkeypatch):
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    nbi, pyc = _tree(tmp_path)
    dynamics._drop_stale_numba_cache(tmp_path)  # first run: no stamp yet → writes it
    nbi.write_text("index")
    pyc.write_text("bytecode")
    dynamics._drop_stale_numba_cache(tmp_path)
    assert nbi.exists()
    (tmp_path / "a.py").write_text("x = 3\n")  # a callee edited in another file
    dynamics._drop_stale_numba_cache(tmp_path)
    assert not nbi.exists() and pyc.exists()


def test_custom_cache_dir_is_left_alone(tmp_path, monkeypatch):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "elsewhere"))
    nbi, _ = _tree(tmp_path)
    nbi.write_text("index")
    dynamics._drop_stale_numba_cache(tmp_path)
    assert nbi.exists() and not (tmp_path / "__pycache__" / dynamics._STAMP).exists()
