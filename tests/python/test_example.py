"""examples/python/pca_figures.py draws both figures from a store."""
import os
import subprocess
import sys

from conftest import ROOT, module_env


def test_pca_figures_writes_both_pngs(db, tmp_path):
    env = module_env()
    r = subprocess.run([sys.executable, os.path.join(ROOT, "examples", "python", "pca_figures.py"), str(db), "-o",
                        str(tmp_path / "figs")], capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr
    for name in ("components.png", "eigenvalues.png"):
        data = (tmp_path / "figs" / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10000
    r = subprocess.run([sys.executable, os.path.join(ROOT, "examples", "python", "pca_figures.py"), str(db), "-o",
                        str(tmp_path / "x"), "--collection", "nope"], capture_output=True, text=True, env=env)
    assert r.returncode == 1 and r.stderr.startswith("pca_figures: ") and "nope" in r.stderr
