"""Fixtures for the specula Python module's tests: small stores made by the specula CLI of the same build.
The package is imported from $SPECULA_BUILD/python (default: build/ beside this source tree), or, with
SPECULA_TEST_INSTALLED=1 (scripts/test, in a fresh venv), from where pip installed it."""
import os
import subprocess
import sys

import h5py
import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BUILD = os.environ.get("SPECULA_BUILD", os.path.join(ROOT, "build"))
INSTALLED = os.environ.get("SPECULA_TEST_INSTALLED") == "1"
if not INSTALLED:
    sys.path.insert(0, os.path.join(BUILD, "python"))
SPECULA = os.path.join(BUILD, "apps", "specula")


def module_env():
    """The environment a child Python needs to import the same specula as these tests."""
    return dict(os.environ) if INSTALLED else dict(os.environ, PYTHONPATH=os.path.join(BUILD, "python"))


def cli(*args, check=True):
    """Runs the specula CLI; returns the completed process."""
    return subprocess.run([SPECULA, "-q", *map(str, args)], capture_output=True, text=True, check=check)


def cli_error(*args):
    """The one-line message the CLI prints for a failing command (without its 'specula: ' prefix)."""
    r = cli(*args, check=False)
    assert r.returncode == 1, (r.returncode, r.stderr)
    line = r.stderr.strip().splitlines()[-1]
    assert line.startswith("specula: ")
    return line[len("specula: "):]


@pytest.fixture(scope="session")
def db(tmp_path_factory):
    """A store with three synthetic images (masked pixels included), a collection, a set of BRDF samples, a grid, a
    PCA basis and a coefficient map, all made by the CLI."""
    d = tmp_path_factory.mktemp("db")
    path = d / "db.h5"
    cli("synth-db", "-o", path, "--images", 3, "--size", "37x53", "--seed", 7)
    rng = np.random.default_rng(3)
    nm = np.arange(420, 721, 10)
    with open(d / "chips.csv", "w") as f:
        f.write("name," + ",".join(str(w) for w in nm) + "\n")
        for i in range(40):
            f.write(f"chip{i}," + ",".join(f"{v:.6f}" for v in rng.uniform(0.05, 0.9, nm.size)) + "\n")
    cli("import", d / "chips.csv", "-o", path, "--name", "chips", "--units", "reflectance")
    cli("synth-samples", "red-plastic", "--geometry", "random", "-n", 500, "-o", f"{path}:scan")
    cli("synth-brdf", "red-plastic", "--wavelengths", "420:720:100", "-o", f"{path}:rp")
    cli("pca", path, "--name", "pca")
    cli("coefficients", path, "--basis", "pca", "-k", 4, "--images", "*0", "--name", "coef")
    return path


def valid_spectra_h5(path, names):
    """Every valid spectrum of the named images, read with h5py through the root's external links."""
    out = []
    with h5py.File(path, "r") as f:
        for n in names:
            cube = f["images"][n]["cube"][...]
            mask = f["images"][n]["mask"][...].astype(bool)
            out.append(cube[mask])
    return np.concatenate(out)
