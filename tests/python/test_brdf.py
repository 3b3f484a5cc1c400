"""BRDF grids, .spgrid/.spc/.binary files and lookup, against numpy: a MERL reader written from the format's
description, BRDFRead.cpp's index arithmetic, the .spc codec's stated error bound, and a neural BRDF against the CLI's
import and tests/codec/nbrdf_reference.py's numpy network."""
import os
import subprocess
import sys

import numpy as np
import pytest

from conftest import ROOT, cli, cli_error
import specula

CELLS = 90 * 90 * 180


@pytest.fixture(scope="module")
def spgrid(tmp_path_factory):
    path = tmp_path_factory.mktemp("grid") / "rp.spgrid"
    cli("synth-brdf", "red-plastic", "--wavelengths", "400:700:100", "-o", path)
    return path


def test_spgrid_read_write_round_trip(spgrid, tmp_path):
    g = specula.read_spgrid(spgrid)
    assert g.bands == 4 and g.values.shape == (4, 90, 90, 180) and g.values.dtype == np.float32
    np.testing.assert_array_equal(g.wavelengths, [400, 500, 600, 700])
    out = tmp_path / "copy.spgrid"
    specula.write_spgrid(out, g)
    h = specula.read_spgrid(out)
    np.testing.assert_array_equal(h.values, g.values)
    assert h.scale == g.scale
    made = specula.Grid([400, 500, 600, 700], g.values * 2, scale=0.5)
    specula.write_spgrid(out, made)
    np.testing.assert_array_equal(specula.read_spgrid(out).values, g.values * 2)


def test_spgrid_errors(spgrid, tmp_path):
    bad = tmp_path / "bad.spgrid"
    bad.write_bytes(spgrid.read_bytes()[:1000])
    with pytest.raises(specula.InputError) as e:
        specula.read_spgrid(bad)
    assert str(e.value) == cli_error("decode", bad, "-o", tmp_path / "x.spgrid") or "bad.spgrid" in str(e.value)
    with pytest.raises(specula.UsageError, match=r"\(4, 90, 90, 180\)"):
        specula.Grid([400, 500, 600, 700], np.zeros((3, 90, 90, 180)))


def test_merl_round_trip_and_layout(tmp_path):
    rng = np.random.default_rng(5)
    raw = rng.uniform(0, 2, (3, 90, 90, 180))
    raw[:, 0, 0, :10] = -1  # no data
    path = tmp_path / "m.binary"
    specula.write_merl(path, raw)
    data = path.read_bytes()
    assert len(data) == 12 + 3 * CELLS * 8
    np.testing.assert_array_equal(np.frombuffer(data[:12], "<i4"), [90, 90, 180])
    np.testing.assert_array_equal(np.frombuffer(data[12:], "<f8").reshape(3, 90, 90, 180), raw)
    np.testing.assert_array_equal(specula.read_merl(path), raw)
    scaled = specula.read_merl(path, scaled=True)
    s = np.array(specula.MERL_SCALE)[:, None, None, None]
    np.testing.assert_allclose(scaled, np.where(raw >= 0, raw * s, raw), rtol=1e-15)
    specula.write_merl(tmp_path / "s.binary", scaled, scaled=True)
    np.testing.assert_allclose(specula.read_merl(tmp_path / "s.binary"), raw, rtol=1e-14)
    (tmp_path / "short.binary").write_bytes(data[:-8])
    with pytest.raises(specula.InputError, match="short.binary") as e:
        specula.read_merl(tmp_path / "short.binary")
    assert str(e.value) == cli_error("uplift", tmp_path / "short.binary", "-o", tmp_path / "u.spgrid")


def merl_index_numpy(ti, pi, to, po):
    """BRDFRead.cpp (Matusik et al.): standard angles -> half/difference angles -> cell, in numpy."""
    def vec(t, p):
        return np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1)

    def rot(v, axis, a):
        c, s = np.cos(a)[..., None], np.sin(a)[..., None]
        return v * c + np.cross(axis, v) * s + axis * (v @ axis)[..., None] * (1 - c)

    wi, wo = vec(ti, pi), vec(to, po)
    h = (wi + wo) / np.linalg.norm(wi + wo, axis=-1, keepdims=True)
    th, ph = np.arccos(np.clip(h[..., 2], -1, 1)), np.arctan2(h[..., 1], h[..., 0])
    d = rot(rot(wi, np.array([0.0, 0, 1]), -ph), np.array([0.0, 1, 0]), -th)
    td, pd = np.arccos(np.clip(d[..., 2], -1, 1)), np.arctan2(d[..., 1], d[..., 0])
    ih = np.clip(np.floor(np.sqrt(np.maximum(th, 0) / (np.pi / 2)) * 90), 0, 89).astype(int)
    ih[th <= 0] = 0
    idd = np.clip(np.floor(td / (np.pi / 2) * 90), 0, 89).astype(int)
    pd = np.where(pd < 0, pd + np.pi, pd)
    ip = np.clip(np.floor(pd / np.pi * 180), 0, 179).astype(int)
    return ih, idd, ip


def test_lookup_is_index_arithmetic_on_the_array(spgrid):
    g = specula.read_spgrid(spgrid)
    rng = np.random.default_rng(11)
    n = 2000
    ti, to = rng.uniform(0.01, 1.5, n), rng.uniform(0.01, 1.5, n)
    pi, po = rng.uniform(-np.pi, np.pi, n), rng.uniform(-np.pi, np.pi, n)
    ih, idd, ip = merl_index_numpy(ti, pi, to, po)
    idx = specula.merl_index(ti, pi, to, po)
    expected = ip + 180 * (idd + 90 * ih)
    # Cells on a floor() boundary may differ by rounding between the two computations: allow a few.
    assert (idx != expected).sum() <= n // 200
    ok = idx == expected
    v = specula.brdf_lookup(g, ti, pi, to, po)
    assert v.shape == (n, 4)
    direct = g.values.reshape(4, -1)[:, idx].T.astype(np.float64)
    np.testing.assert_array_equal(v, np.where(direct < 0, np.nan, direct * g.scale))
    np.testing.assert_array_equal(np.isnan(v).any(axis=1), (direct < 0).any(axis=1))
    assert ok.mean() > 0.99
    two_d = specula.brdf_lookup(g, ti.reshape(40, 50), pi.reshape(40, 50), to.reshape(40, 50), po.reshape(40, 50))
    np.testing.assert_array_equal(two_d.reshape(n, 4), v)
    with pytest.raises(specula.UsageError, match="one size"):
        specula.brdf_lookup(g, ti, pi, to, po[:3])
    with pytest.raises(specula.UsageError, match="not finite"):
        specula.merl_index([np.nan], [0.0], [0.1], [0.0])


def spc_bound(x, xd, scale_s, e, residual):
    """The bound of docs/codec-format.md per valid cell and band: |x' - x| <= |m' - m| |r'| + m (E + residual)
    with |m' - m| <= E (m + s) and |r'| <= |r| + E + residual."""
    m = x.mean(axis=0)
    r = np.divide(x, m, out=np.zeros_like(x), where=m > 0)
    return e * (m + scale_s) * (np.abs(r) + e + residual) + m * (e + residual)


@pytest.mark.parametrize("k", [4, 2])
def test_spc_round_trip_within_its_stated_bound(spgrid, tmp_path, k):
    g = specula.read_spgrid(spgrid)
    data, report = specula.spc_encode(g, k=k, max_error=0.01)
    assert report["output_bytes"] == len(data) and data[:8] == b"SPECUSPC"
    path = tmp_path / "g.spc"
    specula.write_spc(path, data)
    assert path.read_bytes() == data
    d = specula.spc_decode(path)
    np.testing.assert_array_equal(d.values, specula.spc_decode(data).values)
    x = g.values.reshape(4, -1).astype(np.float64)
    xd = d.values.reshape(4, -1).astype(np.float64)
    valid = (x >= 0).all(axis=0)
    np.testing.assert_array_equal((xd >= 0).all(axis=0), valid)
    x, xd = x[:, valid], xd[:, valid]
    residual = report["max_shape_residual"]
    if k == 4:
        assert residual < 1e-6  # a full basis expresses every shape
    bound = spc_bound(x, xd, report["magnitude_scale"], 0.01, residual)
    err = np.abs(xd - x)
    assert np.all(err <= bound * (1 + 1e-5) + 1e-6 * np.abs(x))
    np.testing.assert_allclose(report["max_abs_error"], err.max() * g.scale, rtol=1e-4)


def test_spc_on_a_learned_basis_and_errors(db, spgrid):
    g = specula.read_spgrid(spgrid)
    basis = specula.Basis("nmf", [400, 500, 600, 700], np.eye(4)[:3] + 0.1)
    data, report = specula.spc_encode(g, basis=basis, k=3, extra=1)
    assert report["basis"] == "python+1"
    assert specula.spc_decode(data).bands == 4
    with pytest.raises(specula.UsageError, match="extra"):
        specula.spc_encode(g, extra=1)
    broken = bytearray(data)
    broken[len(broken) // 2] ^= 0xFF
    with pytest.raises(specula.InputError, match="^spc bytes"):
        specula.spc_decode(bytes(broken))
    wrong = specula.pca(db, collection="chips")
    with pytest.raises(specula.InputError):
        specula.spc_encode(g, basis=wrong, k=3)


NBRDF = os.path.join(os.path.dirname(ROOT), "shared", "data", "brdf", "nbrdf-merl", "gold-metallic-paint2.h5")


@pytest.mark.skipif(not os.path.exists(NBRDF), reason="../shared is absent")
def test_read_nbrdf_is_the_clis_import_and_numpys_network(tmp_path):
    rgb = specula.read_nbrdf(NBRDF)
    cli("import", NBRDF, "--format", "nbrdf", "-o", tmp_path / "g.binary")
    np.testing.assert_array_equal(rgb, specula.read_merl(tmp_path / "g.binary"))
    scaled = specula.read_nbrdf(NBRDF, scaled=True)
    cells = [(0, 45, 90), (3, 70, 90), (20, 10, 5), (60, 80, 170), (89, 89, 0)]
    out = subprocess.run([sys.executable, os.path.join(ROOT, "tests", "codec", "nbrdf_reference.py"), NBRDF,
                          *(f"{i},{j},{k}" for i, j, k in cells)], capture_output=True, text=True, check=True)
    lines = out.stdout.splitlines()
    assert len(lines) == len(cells) and sum(float(line.split()[3]) > 0 for line in lines) >= 3
    for line in lines:
        i, j, k, *v = line.split()
        want = np.array(v, float)
        got = scaled[:, int(i), int(j), int(k)]
        if want[0] < 0:
            assert np.all(got < 0), (i, j, k, got)
        else:
            np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-9, err_msg=line)
    (tmp_path / "bad.h5").write_bytes(b"not hdf5")
    with pytest.raises(specula.InputError, match="bad.h5"):
        specula.read_nbrdf(tmp_path / "bad.h5")
    with pytest.raises(specula.MissingFileError, match="absent.h5"):
        specula.read_nbrdf(tmp_path / "absent.h5")


def test_uplift_is_the_clis_uplift_and_import(tmp_path):
    rgb = specula.read_nbrdf(NBRDF)
    specula.write_merl(tmp_path / "g.binary", rgb)
    for flags, kwargs in [([], {}), (["--nonnegative", "--illuminant", "A"], {"nonnegative": True, "illuminant": "A"})]:
        cli("uplift", tmp_path / "g.binary", "--wavelengths", "400:700:20", *flags, "-o", tmp_path / "u.spgrid")
        want = specula.read_spgrid(tmp_path / "u.spgrid")
        got = specula.uplift(rgb, wavelengths="400:700:20", **kwargs)
        np.testing.assert_array_equal(got.wavelengths, want.wavelengths)
        np.testing.assert_array_equal(got.values, want.values)
    # A neural BRDF's import with --uplift is the non-negative uplift under D65; values in 1/sr give the same grid.
    cli("import", NBRDF, "--uplift", "--wavelengths", "400:700:20", "-o", tmp_path / "s.h5")
    with specula.Store(tmp_path / "s.h5") as s:
        imported = s.grid(s.grids[0])
    mine = specula.uplift(specula.read_nbrdf(NBRDF, scaled=True), True, wavelengths="400:700:20", nonnegative=True)
    valid = imported.values >= 0
    np.testing.assert_array_equal(mine.values >= 0, valid)
    np.testing.assert_allclose(mine.values[valid] * mine.scale, imported.values[valid] * imported.scale, rtol=1e-5)
    # Uplifted under its own illuminant, a flat white comes back flat.
    ones = np.where(rgb >= 0, 1 / np.array(specula.MERL_SCALE)[:, None, None, None], rgb)
    flat = specula.uplift(ones, illuminant=specula.illuminant("D65", "400:700:10"))
    np.testing.assert_allclose(flat.values[:, 45, 45, 90] * flat.scale, 1, rtol=1e-3)
    with pytest.raises(specula.UsageError, match=r"\(3, 90, 90, 180\)"):
        specula.uplift(rgb[:, :10])
    with pytest.raises(specula.UsageError, match="alpha"):
        specula.uplift(rgb, alpha=0)
