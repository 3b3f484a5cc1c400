"""RGL .bsdf from Python: write_bsdf then read_bsdf against the grid (cosine-weighted relative error, the CLI's
export as a peer byte for byte), the real RGB files of ../shared as arrays, and errors as specula.InputError."""
import json
import os

import numpy as np
import pytest

from conftest import ROOT, cli
import specula

RGL = os.path.join(os.path.dirname(ROOT), "shared", "data", "brdf", "rgl")


@pytest.fixture(scope="module")
def spgrid(tmp_path_factory):
    path = tmp_path_factory.mktemp("bsdf") / "bp.spgrid"
    cli("synth-brdf", "blue-paint", "--wavelengths", "400:700:100", "-o", path)
    return path


@pytest.fixture(scope="module")
def cli_bsdf(spgrid):
    path = spgrid.parent / "cli.bsdf"
    cli("export", spgrid, "-o", path)
    return path


def test_write_then_read_reproduces_the_grid(spgrid, cli_bsdf, tmp_path):
    g = specula.read_spgrid(spgrid)
    out = tmp_path / "bp.bsdf"
    specula.write_bsdf(out, g, description="specula export of " + str(spgrid))
    assert out.read_bytes() == cli_bsdf.read_bytes()
    back = specula.read_bsdf(out)
    np.testing.assert_array_equal(back.wavelengths, g.wavelengths)
    a, b = g.values * g.scale, back.values * back.scale
    valid = (a >= 0).all(axis=0) & (b >= 0).all(axis=0)
    # Weights cos(theta_i) cos(theta_o) at the cell centres (docs/brdf.md), as brdf-diff's rel_rms_cos.
    th = (((np.arange(90) + 0.5) / 90) ** 2 * np.pi / 2)[:, None, None]
    td = ((np.arange(90) + 0.5) * np.pi / 180)[None, :, None]
    pd = ((np.arange(180) + 0.5) * np.pi / 180)[None, None, :]
    dx, dz = np.sin(td) * np.cos(pd), np.cos(td)
    ci, co = -np.sin(th) * dx + np.cos(th) * dz, np.sin(th) * dx + np.cos(th) * dz
    w = np.clip(ci, 0, None) * np.clip(co, 0, None) * valid
    rel = np.sqrt((w * (a - b) ** 2).sum() / (w * a ** 2).sum())
    assert rel < 0.3


@pytest.mark.skipif(not os.path.isdir(RGL), reason="../shared is absent")
def test_real_rgb_files_read_as_arrays():
    v = specula.read_bsdf(os.path.join(RGL, "vch_silk_blue_rgb.bsdf"))
    assert v.shape == (3, 90, 90, 180) and v.dtype == np.float32
    ok = v[0] >= 0
    assert ok.mean() > 0.4 and np.isfinite(v).all()
    assert np.median(v[2][ok]) > np.median(v[0][ok])  # a blue silk


def test_store_info_names_an_imported_grids_parameterisation_as_the_cli_does(cli_bsdf, tmp_path):
    db = tmp_path / "s.h5"
    cli("import", cli_bsdf, "-o", db, "--name", "back")
    cli("synth-brdf", "blue-paint", "--wavelengths", "400:700:100", "-o", f"{db}:plain")
    s = specula.Store(db)
    p = s.info("back")["parameterisation"]
    assert p == json.loads(cli("info", db, "back", "--json").stdout)["parameterisation"]
    # The defaults of the export that made the file (docs/brdf.md): 8 incident elevations on a 32^2 sample square.
    assert p["source"] == "rgl" and len(p["theta_i"]) == 8 and p["resolution"] == 32
    assert s.info("plain")["parameterisation"] is None


def test_errors_are_input_errors(tmp_path):
    bad = tmp_path / "bad.bsdf"
    bad.write_bytes(b"tensor_filX" + bytes(20))
    with pytest.raises(specula.InputError, match="bad.bsdf"):
        specula.read_bsdf(bad)


def test_read_bsdf_missing_file_is_file_not_found(tmp_path):
    with pytest.raises(FileNotFoundError, match=str(tmp_path / "nope.bsdf")):
        specula.read_bsdf(tmp_path / "nope.bsdf")


def test_write_to_a_target_is_the_cli_export_and_reports_its_trials(spgrid, cli_bsdf, tmp_path):
    g = specula.read_spgrid(spgrid)
    out = tmp_path / "t.bsdf"
    desc = "specula export of " + str(spgrid)
    report = specula.write_bsdf(out, g, theta_i=4, resolution=16, description=desc, target_de00=0.5)
    # The ladder starts at its first size not smaller than 4 x 16^2 (8 x 32^2), which an analytic paint meets.
    assert report["reached"] is True and len(report["trials"]) == 1
    t = report["trials"][0]
    assert (t["theta_i"], t["resolution"], t["met"]) == (8, 32, True)
    assert t["de00_mean"] <= 0.5 and t["de00_p95"] <= 1.5 and t["bytes"] == out.stat().st_size
    # The CLI's export at that size (its --target-de00 search is tested in tests/apps/bsdf_test.cpp).
    assert out.read_bytes() == cli_bsdf.read_bytes()
    assert specula.write_bsdf(tmp_path / "plain.bsdf", g, theta_i=2, resolution=2) is None


def test_write_to_a_target_refuses_what_the_cli_refuses(spgrid, tmp_path):
    g = specula.read_spgrid(spgrid)
    with pytest.raises(specula.UsageError, match="target_p95 goes with target_de00"):
        specula.write_bsdf(tmp_path / "a.bsdf", g, target_p95=1.0)
    with pytest.raises(specula.UsageError, match="drop rgb"):
        specula.write_bsdf(tmp_path / "b.bsdf", g, rgb=True, target_de00=0.5)
    with pytest.raises(specula.UsageError, match="must be positive"):
        specula.write_bsdf(tmp_path / "c.bsdf", g, target_de00=-1.0)
    assert not any(tmp_path.iterdir())
