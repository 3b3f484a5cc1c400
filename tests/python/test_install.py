"""The package as pip installed it (scripts/test runs the suite in a fresh venv with SPECULA_TEST_INSTALLED=1):
imported from the venv's site-packages with its stubs and py.typed, known to `pip show`."""
import os
import subprocess
import sys
import sysconfig

import pytest

from conftest import BUILD, INSTALLED
import specula


@pytest.mark.skipif(not INSTALLED, reason="the suite runs against the build tree (SPECULA_TEST_INSTALLED unset)")
def test_imported_from_site_packages_with_stubs_and_py_typed():
    package = os.path.dirname(os.path.abspath(specula.__file__))
    assert package == os.path.join(sysconfig.get_paths()["platlib"], "specula")
    assert not package.startswith(os.path.join(os.path.abspath(BUILD), "python"))
    assert sys.prefix != sys.base_prefix  # a venv
    for f in ("__init__.pyi", "py.typed"):
        assert os.path.isfile(os.path.join(package, f)), f
    assert os.path.basename(specula._specula.__file__).startswith("_specula.cpython-")
    r = subprocess.run([sys.executable, "-m", "pip", "show", "-f", "specula"], capture_output=True, text=True,
                       check=True)
    assert f"Version: {specula.__version__}" in r.stdout
    assert "specula/py.typed" in r.stdout and "specula/__init__.pyi" in r.stdout


def test_signatures_and_docstrings_are_real():
    for f in (specula.Store.write_image, specula.render_sphere, specula.spc_encode, specula.compare_grids,
              specula.SpcBrdf.evaluate):
        doc = f.__doc__
        assert doc and "object" not in doc.splitlines()[0], doc.splitlines()[0]
